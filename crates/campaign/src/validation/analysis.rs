//! Errors of each model on the validation measurements.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use vatcal_identification::{ErrorStats, ValidationReport, validate};
use vatcal_kinematics::Model;
use vatcal_planning::ik::rotation_angle_between;

use super::{PathRecords, PrintingSlice, ValidationError, ValidationRecords, fit_rigid_transform};

/// Errors along one printing-path run, measured at the end of the theoretical part.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PathValidation {
    /// label of the commanding model
    pub label: String,
    /// `measured − intended` position of the part's end (tank bottom), per slice, world \[mm\]
    pub tip_errors_mm: Vec<Vector3<f64>>,
    /// `measured − intended` position of the build-plate face centre, per slice, world \[mm\]
    pub plate_errors_mm: Vec<Vector3<f64>>,
    /// angle between the measured and the intended plate orientation, per slice \[rad\]
    pub orientation_errors_rad: Vec<f64>,
    /// statistics of the part-end errors (the paper's Fig. 10)
    pub tip_stats: ErrorStats,
    /// statistics of the plate errors (without the lever effect)
    pub plate_stats: ErrorStats,
    /// slices left out because fewer than three of their SMRs were measured (points the
    /// campaign skipped after losing the line of sight)
    #[serde(default, skip_serializing_if = "is_zero")]
    pub skipped_slices: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl PathValidation {
    /// Part-end error magnitudes \[mm\], slice by slice.
    pub fn tip_magnitudes(&self) -> Vec<f64> {
        self.tip_errors_mm.iter().map(|e| e.norm()).collect()
    }
}

/// The errors of one path run: at every slice, the end-effector pose fitted to the measured
/// SMRs (their CMM coordinates `smrs_in_tool` in the tool-changer frame) is carried to the
/// part's end and to the plate face and compared with the intended points.
///
/// # Errors
/// A slice count mismatch; a slice whose SMRs do not determine a pose (unknown id, fewer than
/// three, collinear).
pub fn evaluate_path(
    slices: &[PrintingSlice],
    records: &PathRecords,
    smrs_in_tool: &[(u32, Vector3<f64>)],
) -> Result<PathValidation, ValidationError> {
    if slices.len() != records.slices.len() {
        return Err(ValidationError::Incomplete(format!(
            "`{}`: {} slices planned, {} measured",
            records.label,
            slices.len(),
            records.slices.len()
        )));
    }
    let mut tip_errors_mm = Vec::with_capacity(slices.len());
    let mut plate_errors_mm = Vec::with_capacity(slices.len());
    let mut orientation_errors_rad = Vec::with_capacity(slices.len());
    let mut skipped_slices = 0;
    for (slice, record) in slices.iter().zip(&records.slices) {
        if record.measurements.len() < 3 && record.measurements.len() < smrs_in_tool.len() {
            skipped_slices += 1; // SMRs skipped by the campaign: no pose without three
            continue;
        }
        let registration_error =
            |reason| ValidationError::Registration { run: records.label.clone(), slice: slice.index, reason };
        let (mut local, mut world) = (Vec::new(), Vec::new());
        for (tcp, p) in record.smr_positions() {
            let Some((_, l)) = smrs_in_tool.iter().find(|(id, _)| *id == tcp) else {
                return Err(ValidationError::Incomplete(format!(
                    "`{}` slice {}: SMR {tcp} has no tool-frame coordinates",
                    records.label, slice.index
                )));
            };
            local.push(*l);
            world.push(p);
        }
        let measured = fit_rigid_transform(&local, &world).map_err(registration_error)?;
        tip_errors_mm.push(measured.transform_point(&slice.tip_in_tool_mm) - slice.tip_world_mm);
        plate_errors_mm.push(measured.transform_point(&slice.plate_in_tool_mm) - slice.plate_world_mm());
        orientation_errors_rad.push(rotation_angle_between(&slice.tool_pose.r, &measured.r));
    }
    if tip_errors_mm.is_empty() && skipped_slices > 0 {
        return Err(ValidationError::Incomplete(format!(
            "`{}`: every slice lost SMRs ({skipped_slices} skipped): no pose measured",
            records.label
        )));
    }
    Ok(PathValidation {
        label: records.label.clone(),
        skipped_slices,
        tip_stats: ErrorStats::from_errors(&tip_errors_mm),
        plate_stats: ErrorStats::from_errors(&plate_errors_mm),
        tip_errors_mm,
        plate_errors_mm,
        orientation_errors_rad,
    })
}

/// The validation of one model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelValidation {
    /// label of the model (e.g. `nominal`, `calibrated`)
    pub label: String,
    /// errors `measured − FK_model(q)` at the random poses (the paper's Fig. 8)
    pub random: ValidationReport,
    /// errors along the printing path this model commanded, if it commanded one
    pub path: Option<PathValidation>,
}

/// The validation of every labelled model: random-pose errors of each, and the path run it
/// commanded (matched by label). `smrs_in_tool` are the SMR centres in the tool-changer frame
/// (CMM values; the same for every model).
///
/// # Errors
/// A model that rejects a measurement; a path run that cannot be evaluated.
pub fn evaluate(
    records: &ValidationRecords,
    slices: &[PrintingSlice],
    models: &[(&str, &Model)],
    smrs_in_tool: &[(u32, Vector3<f64>)],
) -> Result<Vec<ModelValidation>, ValidationError> {
    models
        .iter()
        .map(|(label, model)| {
            let random = validate(model, &records.random)?;
            let path = records
                .paths
                .iter()
                .find(|p| p.label == *label)
                .map(|p| evaluate_path(slices, p, smrs_in_tool))
                .transpose()?;
            Ok(ModelValidation { label: (*label).to_string(), random, path })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validation::{PrintingPathOptions, SliceRecord, printing_path};
    use vatcal_core::{JointVector, Measurement};

    fn smrs() -> Vec<(u32, Vector3<f64>)> {
        vec![
            (1, Vector3::new(-56.78, 30.515, 67.113)),
            (2, Vector3::new(0.214, 30.189, 124.59)),
            (3, Vector3::new(56.855, 30.647, 66.726)),
        ]
    }

    /// SMRs measured where a given tool pose puts them.
    fn record(pose: &vatcal_core::Frame) -> SliceRecord {
        let measurements = smrs()
            .iter()
            .map(|(id, l)| Measurement::tracker(*id, JointVector::default(), pose.transform_point(l)))
            .collect();
        SliceRecord { measurements }
    }

    #[test]
    fn a_rotated_plate_shows_the_lever_effect() {
        let opts = PrintingPathOptions { slices: 20, layer_mm: 2.0, ..Default::default() };
        let slices = printing_path(&opts).expect("path");
        // perfect run: zero errors
        let perfect = PathRecords {
            label: "ideal".into(),
            slices: slices.iter().map(|s| record(&s.tool_pose)).collect(),
        };
        let v = evaluate_path(&slices, &perfect, &smrs()).expect("evaluate");
        assert!(v.tip_stats.max < 1e-9 && v.plate_stats.max < 1e-9);
        // a plate rotated by 1 mrad about an axis through the plate face, perpendicular to the
        // part: the plate error stays zero, the tip error grows with the part height (lever
        // effect)
        let tilted = slices
            .iter()
            .map(|s| {
                let plate = s.plate_world_mm();
                let axis = nalgebra::Unit::new_normalize(s.tool_pose.x_axis());
                let rot = nalgebra::Rotation3::from_axis_angle(&axis, 1e-3);
                let r = rot.matrix() * s.tool_pose.r;
                let p = plate - r * s.plate_in_tool_mm;
                record(&vatcal_core::Frame { r, p })
            })
            .collect();
        let v = evaluate_path(&slices, &PathRecords { label: "tilted".into(), slices: tilted }, &smrs())
            .expect("eval");
        assert!(v.plate_stats.max < 1e-9, "{}", v.plate_stats.max);
        for (s, e) in slices.iter().zip(&v.tip_errors_mm) {
            // chord of the 1 mrad arc of radius h
            let lever = 2.0 * s.part_height_mm * (0.5e-3f64).sin();
            assert!((e.norm() - lever).abs() < 1e-12 * (1.0 + lever), "{} vs {lever}", e.norm());
        }
        assert!(v.orientation_errors_rad.iter().all(|a| (a - 1e-3).abs() < 1e-12));
    }
}
