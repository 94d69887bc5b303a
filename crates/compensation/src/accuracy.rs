//! Proof on a virtual cell: how accurately a path lands when commanded with compensated
//! targets and with uncompensated (nominal) ones.

use nalgebra::Vector3;
use vatcal_core::JointVector;
use vatcal_kinematics::Model;

use crate::{CompensationError, Compensator, PathOptions, PathResult, RowOutcome, ToolTarget};

/// Mean, RMS and largest of a set of distances \[mm\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorSummary {
    /// mean \[mm\]
    pub mean_mm: f64,
    /// root mean square \[mm\]
    pub rms_mm: f64,
    /// largest \[mm\]
    pub max_mm: f64,
}

impl ErrorSummary {
    /// Summary of `errors` (zeros when empty).
    pub fn of(errors: &[f64]) -> Self {
        if errors.is_empty() {
            return Self { mean_mm: 0.0, rms_mm: 0.0, max_mm: 0.0 };
        }
        let n = errors.len() as f64;
        Self {
            mean_mm: errors.iter().sum::<f64>() / n,
            rms_mm: (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
            max_mm: errors.iter().copied().fold(0.0, f64::max),
        }
    }
}

/// True errors along one path, commanded two ways.
#[derive(Debug, Clone, PartialEq)]
pub struct PathAccuracy {
    /// true error per row when commanded with compensated targets (IK of the calibrated
    /// model) \[mm\]
    pub compensated_mm: Vec<f64>,
    /// true error per row when commanded with uncompensated targets (IK of the nominal model,
    /// what the controller alone would do) \[mm\]
    pub uncompensated_mm: Vec<f64>,
    /// the calibrated model's own error per row at the compensated joints:
    /// `|FK_truth(q) − FK_calibrated(q)|` at the evaluated point \[mm\]
    pub calibrated_model_mm: Vec<f64>,
    /// largest distance of the calibrated model's prediction at the compensated joints from
    /// the request (the solver residual at the evaluated point) \[mm\]
    pub max_prediction_residual_mm: f64,
    /// joints commanded with compensation
    pub compensated_joints: Vec<JointVector>,
    /// joints commanded without compensation
    pub uncompensated_joints: Vec<JointVector>,
}

impl PathAccuracy {
    /// Summary of [`PathAccuracy::compensated_mm`].
    pub fn compensated(&self) -> ErrorSummary {
        ErrorSummary::of(&self.compensated_mm)
    }

    /// Summary of [`PathAccuracy::uncompensated_mm`].
    pub fn uncompensated(&self) -> ErrorSummary {
        ErrorSummary::of(&self.uncompensated_mm)
    }

    /// Summary of [`PathAccuracy::calibrated_model_mm`].
    pub fn calibrated_model(&self) -> ErrorSummary {
        ErrorSummary::of(&self.calibrated_model_mm)
    }
}

fn joints(result: &PathResult) -> Vec<JointVector> {
    result
        .rows
        .iter()
        .filter_map(|r| match r {
            RowOutcome::Solved(c) => Some(c.q),
            RowOutcome::Skipped(_) => None,
        })
        .collect()
}

/// Commands the path `targets` on the virtual cell `truth` twice — with joint targets
/// compensated under `calibrated`, and with the uncompensated targets of `nominal` (the
/// controller's own IK) — and measures, per row, the true world distance of the point
/// `points_in_tool[k]` (tool-changer frame, e.g. the part's end of a printing slice) from
/// where the request puts it. `opts.start` (e.g. a reference joint vector of the first row)
/// fixes the branch of both runs; skip mode is not allowed (every row must be commanded).
///
/// # Errors
/// A row that either model cannot command; `points_in_tool` of the wrong length; skip mode.
pub fn path_accuracy(
    truth: &Model,
    calibrated: &Model,
    nominal: &Model,
    targets: &[ToolTarget],
    points_in_tool: &[Vector3<f64>],
    opts: &PathOptions,
) -> Result<PathAccuracy, CompensationError> {
    if points_in_tool.len() != targets.len() {
        return Err(CompensationError::Option {
            option: "points_in_tool",
            reason: format!("{} points for {} targets", points_in_tool.len(), targets.len()),
        });
    }
    if opts.skip_unreachable {
        return Err(CompensationError::Option {
            option: "skip_unreachable",
            reason: "every row must be commanded to compare the two runs".into(),
        });
    }
    let compensated = Compensator::new(calibrated, nominal)?.compensate_path(targets, opts)?;
    let uncompensated = Compensator::new(nominal, nominal)?.compensate_path(targets, opts)?;
    let (qc, qn) = (joints(&compensated), joints(&uncompensated));
    let mut out = PathAccuracy {
        compensated_mm: Vec::with_capacity(targets.len()),
        uncompensated_mm: Vec::with_capacity(targets.len()),
        calibrated_model_mm: Vec::with_capacity(targets.len()),
        max_prediction_residual_mm: 0.0,
        compensated_joints: qc.clone(),
        uncompensated_joints: qn.clone(),
    };
    for (((t, pt), c), n) in targets.iter().zip(points_in_tool).zip(&qc).zip(&qn) {
        let wanted = t.tool.transform_point(pt);
        let true_c = truth.chain_full(c, &t.context, false, None).tool.transform_point(pt);
        let true_n = truth.chain_full(n, &t.context, false, None).tool.transform_point(pt);
        let model_c = calibrated.chain_full(c, &t.context, false, None).tool.transform_point(pt);
        out.compensated_mm.push((true_c - wanted).norm());
        out.uncompensated_mm.push((true_n - wanted).norm());
        out.calibrated_model_mm.push((true_c - model_c).norm());
        out.max_prediction_residual_mm = out.max_prediction_residual_mm.max((model_c - wanted).norm());
    }
    Ok(out)
}
