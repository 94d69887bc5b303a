//! The printing path of the validation through `vatcal-compensation` (issue 13, item 4).
//!
//! The validation commands the printing path twice: by the nominal model (what the robot
//! controller alone does) and by the calibrated model. Both joint lists are exactly what
//! [`vatcal_compensation::Compensator::compensate_path`] turns the slices' requested tool
//! poses into — under the nominal model (**uncompensated targets**) and under the calibrated
//! model (**compensated targets**, what `vatcal compensate` writes). [`check_printing_path`]
//! solves both with the compensation library before any validation motion and stops the run
//! when the commanded joints differ from them by more than [`JOINT_AGREEMENT`], so the
//! tracker's measurements of the two runs on the (true) cell are measurements of the two kinds
//! of targets. [`CompensationSummary`] (`report.json` → `compensation`) holds the agreement,
//! the solver residuals, the correction the compensation applies, and the measured errors of
//! the part's end.

use serde::Serialize;
use vatcal_campaign::validation::{ModelValidation, ValidationPlan};
use vatcal_compensation::{Compensator, PathOptions, PathResult, ToolTarget};
use vatcal_core::{JointVector, rad_to_deg};
use vatcal_kinematics::Model;

use crate::{CALIBRATED, NOMINAL, PipelineError};

pub use crate::error::{JOINT_AGREEMENT, PrintingPathCheckError};

/// Mean and largest of a set of distances \[mm\].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeanMax {
    /// mean \[mm\]
    pub mean_mm: f64,
    /// largest \[mm\]
    pub max_mm: f64,
}

impl MeanMax {
    fn of(values: &[f64]) -> Self {
        let n = values.len().max(1) as f64;
        Self { mean_mm: values.iter().sum::<f64>() / n, max_mm: values.iter().copied().fold(0.0, f64::max) }
    }
}

/// The compensation's targets of the printing path, checked against the commanded runs.
#[derive(Debug, Clone, PartialEq)]
pub struct PrintingPathTargets {
    /// compensated targets (calibrated model), one per slice
    pub compensated: Vec<JointVector>,
    /// uncompensated targets (nominal model), one per slice
    pub uncompensated: Vec<JointVector>,
    /// IK branch of the compensated path (`vatcal_compensation::Branch` bits)
    pub branch: u8,
    /// largest solver residual of the compensated targets: tool position \[mm\]
    pub max_residual_mm: f64,
    /// ... and tool orientation \[deg\]
    pub max_residual_deg: f64,
    /// largest |commanded − compensated| joint difference of the calibrated run \[rad / mm\]
    pub calibrated_run_difference: f64,
    /// largest |commanded − uncompensated| joint difference of the nominal run \[rad / mm\]
    pub nominal_run_difference: f64,
    /// distance, per slice, between where the nominal model puts the part's end at the
    /// compensated joints and the request: the correction the compensation applies \[mm\]
    pub correction_mm: Vec<f64>,
}

/// `report.json` → `compensation`: the printing path commanded with uncompensated and
/// compensated targets, measured on the cell by the tracker.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompensationSummary {
    /// where the commanded joints come from
    pub source: String,
    /// slices of the printing path
    pub slices: usize,
    /// IK branch of the compensated path
    pub branch: u8,
    /// largest solver residual of the compensated targets \[mm\]
    pub max_residual_mm: f64,
    /// largest solver residual of the compensated targets \[deg\]
    pub max_residual_deg: f64,
    /// largest |commanded − compensated| joint difference, calibrated run \[rad, mm for q1\]
    pub calibrated_run_difference: f64,
    /// largest |commanded − uncompensated| joint difference, nominal run \[rad, mm for q1\]
    pub nominal_run_difference: f64,
    /// the correction the compensation applies to the part's end (the nominal model's
    /// prediction at the compensated joints, from the request)
    pub correction: MeanMax,
    /// measured error of the part's end, commanded with uncompensated (nominal) targets
    pub uncompensated: Option<MeanMax>,
    /// measured error of the part's end, commanded with compensated targets
    pub compensated: Option<MeanMax>,
}

impl CompensationSummary {
    /// The summary of `targets` with the measured path errors of `results` (labels
    /// [`NOMINAL`] and [`CALIBRATED`]).
    pub fn new(targets: &PrintingPathTargets, results: &[ModelValidation]) -> Self {
        let measured = |label: &str| {
            results
                .iter()
                .find(|m| m.label == label)
                .and_then(|m| m.path.as_ref())
                .map(|p| MeanMax::of(&p.tip_magnitudes()))
        };
        Self {
            source: "vatcal_compensation::Compensator::compensate_path (the library of `vatcal compensate`)"
                .into(),
            slices: targets.compensated.len(),
            branch: targets.branch,
            max_residual_mm: targets.max_residual_mm,
            max_residual_deg: targets.max_residual_deg,
            calibrated_run_difference: targets.calibrated_run_difference,
            nominal_run_difference: targets.nominal_run_difference,
            correction: MeanMax::of(&targets.correction_mm),
            uncompensated: measured(NOMINAL),
            compensated: measured(CALIBRATED),
        }
    }
}

fn joints(result: &PathResult) -> Vec<JointVector> {
    result.solved().map(|(_, c)| c.q).collect()
}

fn largest_difference(a: &[JointVector], b: &[JointVector]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| x.as_slice().iter().zip(y.as_slice()).map(|(u, v)| (u - v).abs()))
        .fold(0.0, f64::max)
}

/// Solves the printing path of `plan` with `vatcal-compensation` — the slices' tool poses at
/// the guide schedule of the plan, the branch of the first commanded slice — under
/// `calibrated` (compensated targets) and `nominal` (uncompensated targets), and checks that
/// the plan's runs labelled [`CALIBRATED`] and [`NOMINAL`] command exactly these joints.
///
/// # Errors
/// A run is missing or has the wrong length, the compensation cannot solve a slice, or a
/// commanded joint differs from its target by more than [`JOINT_AGREEMENT`].
pub fn check_printing_path(
    nominal: &Model,
    calibrated: &Model,
    plan: &ValidationPlan,
) -> Result<PrintingPathTargets, PipelineError> {
    let run = |label: &str| {
        plan.path_runs
            .iter()
            .find(|r| r.label == label && r.joints.len() == plan.slices.len())
            .map(|r| r.joints.as_slice())
            .ok_or_else(|| PrintingPathCheckError::MissingRun { label: label.to_string() })
    };
    let (commanded_nominal, commanded_calibrated) = (run(NOMINAL)?, run(CALIBRATED)?);
    let targets: Vec<ToolTarget> = plan
        .slices
        .iter()
        .zip(commanded_nominal)
        .map(|(s, q)| ToolTarget::new(q.guide_mm(), s.tool_pose))
        .collect();
    let opts = PathOptions { start: commanded_nominal.first().copied(), ..PathOptions::default() };
    let fail = |targets: &'static str, source| PrintingPathCheckError::Solve { targets, source };
    let comp = Compensator::new(calibrated, nominal)
        .and_then(|c| c.compensate_path(&targets, &opts))
        .map_err(|e| fail("compensated", e))?;
    let uncomp = Compensator::new(nominal, nominal)
        .and_then(|c| c.compensate_path(&targets, &opts))
        .map_err(|e| fail("uncompensated", e))?;
    let (compensated, uncompensated) = (joints(&comp), joints(&uncomp));
    let calibrated_run_difference = largest_difference(commanded_calibrated, &compensated);
    let nominal_run_difference = largest_difference(commanded_nominal, &uncompensated);
    for (label, d) in [(CALIBRATED, calibrated_run_difference), (NOMINAL, nominal_run_difference)] {
        if d.is_nan() || d > JOINT_AGREEMENT {
            return Err(PrintingPathCheckError::Differs { label: label.to_string(), difference: d }.into());
        }
    }
    let (mut max_residual_mm, mut max_residual_rad) = (0.0_f64, 0.0_f64);
    for (_, c) in comp.solved() {
        max_residual_mm = max_residual_mm.max(c.position_residual_mm);
        max_residual_rad = max_residual_rad.max(c.rotation_residual_rad);
    }
    let correction_mm = plan
        .slices
        .iter()
        .zip(&compensated)
        .map(|(s, q)| {
            let context = vatcal_core::MeasurementContext::default();
            let tip = nominal.chain_full(q, &context, false, None).tool.transform_point(&s.tip_in_tool_mm);
            (tip - s.tip_world_mm).norm()
        })
        .collect();
    Ok(PrintingPathTargets {
        branch: comp.branch.map_or(0, |b| b.0),
        compensated,
        uncompensated,
        max_residual_mm,
        max_residual_deg: rad_to_deg(max_residual_rad),
        calibrated_run_difference,
        nominal_run_difference,
        correction_mm,
    })
}

/// The `summary.md` section of the compensation: the printing path, part-end error measured
/// on the cell, commanded with uncompensated and with compensated targets.
pub fn summary_markdown(c: &CompensationSummary) -> String {
    use std::fmt::Write as _;
    let mut m = String::new();
    let f = |v: Option<MeanMax>| {
        v.map_or(("-".to_string(), "-".to_string()), |v| {
            (format!("{:.4}", v.mean_mm), format!("{:.4}", v.max_mm))
        })
    };
    let (un_mean, un_max) = f(c.uncompensated);
    let (co_mean, co_max) = f(c.compensated);
    let _ = writeln!(m, "\n### Printing by `vatcal compensate`'s targets\n");
    let _ = writeln!(
        m,
        "Both printing-path runs command the joint targets of `vatcal-compensation` (the library of \
         `vatcal compensate`) for the {} requested slices: under the nominal model (uncompensated, \
         what the controller alone does) and under the calibrated model (compensated; branch {}, \
         solver residual at most {:.1e} mm / {:.1e} deg). The commanded joints equal these targets \
         to {:.1e} (calibrated run) and {:.1e} (nominal run) rad. The compensation moves the part's \
         end, as the nominal controller sees it, by {:.3} mm on average (at most {:.3} mm).\n",
        c.slices,
        c.branch,
        c.max_residual_mm,
        c.max_residual_deg,
        c.calibrated_run_difference,
        c.nominal_run_difference,
        c.correction.mean_mm,
        c.correction.max_mm
    );
    let _ = writeln!(m, "| part-end error measured on the cell [mm] | mean | max |\n|---|---:|---:|");
    let _ = writeln!(m, "| printing path, uncompensated (nominal) targets | {un_mean} | {un_max} |");
    let _ =
        writeln!(m, "| printing path, compensated targets (`vatcal compensate`) | {co_mean} | {co_max} |");
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_campaign::validation::{
        PrintingPathOptions, RandomPoseOptions, ValidationPlanOptions, build_validation_plan,
    };
    use vatcal_core::CellFile;
    use vatcal_planning::geometry::CellGeometry;

    fn plan() -> (Model, ValidationPlan) {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("canonical cell");
        let nominal = Model::from_cell(&cell).expect("model");
        let geometry = CellGeometry::from_cell(&cell).expect("geometry");
        let opts = ValidationPlanOptions {
            random: RandomPoseOptions { count: 2, ..RandomPoseOptions::default() },
            printing: PrintingPathOptions { slices: 20, ..PrintingPathOptions::default() },
            ..ValidationPlanOptions::default()
        };
        let models: [(&str, &Model); 2] = [(NOMINAL, &nominal), (CALIBRATED, &nominal)];
        let plan = build_validation_plan(&nominal, &geometry, &models, &opts).expect("plan");
        (nominal, plan)
    }

    #[test]
    fn the_commanded_runs_must_be_the_compensation_targets() {
        let (nominal, plan) = plan();
        let t = check_printing_path(&nominal, &nominal, &plan).expect("the plan's runs are the targets");
        assert_eq!(t.compensated.len(), 20);
        assert!(
            t.calibrated_run_difference <= JOINT_AGREEMENT && t.nominal_run_difference <= JOINT_AGREEMENT
        );
        // the nominal model compensating itself applies no correction
        assert!(t.correction_mm.iter().all(|d| *d < 1e-6), "{:?}", t.correction_mm);
        // a commanded joint off by 1e-4 rad is caught, naming the run
        let mut bad = plan.clone();
        bad.path_runs[1].joints[7][3] += 1e-4;
        let e = check_printing_path(&nominal, &nominal, &bad).expect_err("mismatch");
        assert!(matches!(e, PipelineError::Compensation(PrintingPathCheckError::Differs { .. })), "{e:?}");
        let text = chain(&e);
        assert!(
            text.starts_with("compensation of the printing path: the `calibrated` printing-path run differs")
                && text.contains("1.000e-4"),
            "{text}"
        );
        // a missing run is an error, not a silent skip
        let mut missing = plan.clone();
        missing.path_runs.retain(|r| r.label != NOMINAL);
        let e = check_printing_path(&nominal, &nominal, &missing).expect_err("missing");
        assert!(chain(&e).contains("no `nominal` printing-path run of every slice"), "{e:?}");
        // a compensation that cannot solve keeps the compensation library's error as the source
        let mut unreachable = plan;
        for s in &mut unreachable.slices {
            s.tool_pose.p.z += 5000.0;
        }
        let e = check_printing_path(&nominal, &nominal, &unreachable).expect_err("out of reach");
        let PipelineError::Compensation(PrintingPathCheckError::Solve { targets, source }) = &e else {
            panic!("{e:?}");
        };
        assert_eq!(*targets, "compensated");
        assert!(
            chain(&e).starts_with(&format!(
                "compensation of the printing path: compensated targets of the printing path: {source}"
            )),
            "{}",
            chain(&e)
        );
    }

    /// The error and its sources, `: `-separated (what `vatcal`'s `{:#}` prints).
    fn chain(e: &dyn std::error::Error) -> String {
        let mut text = e.to_string();
        let mut next = e.source();
        while let Some(s) = next {
            text = format!("{text}: {s}");
            next = s.source();
        }
        text
    }
}
