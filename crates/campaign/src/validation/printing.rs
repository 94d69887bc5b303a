//! A six-dimensional printing path (paper §5, Figs. 9–10) and the joints that command it on a
//! given model.
//!
//! # The path
//! Bottom-up vat printing with a robot-held part: the build plate, held face down by the robot,
//! starts one layer above the tank bottom; after each cured slice it **rises by one layer**, so
//! the part grows downward from the plate and its end — where the next slice is cured, the
//! point whose accuracy matters — stays on the tank bottom, ever farther from the robot (the
//! *lever effect*: an orientation error of the plate is multiplied by the part height).
//!
//! Slice `k = 0..slices` (`s = k / (slices − 1)` from 0 to 1):
//!
//! * part height `h_k = (k + 1) · layer_mm`;
//! * printing point (the part's end) on the tank bottom, following a half circle of radius
//!   `lateral_radius_mm` (a part printed while the robot moves it sideways):
//!   `tip_k = start + r (1 − cos πs, sin πs, 0)`;
//! * plate orientation `R_k = Rz(heading + spin · s) · Ry(tilt_max · sin πs) · Rx(180°)`: the
//!   tool z axis points down, tilts by up to `tilt_max_deg` in the middle of the print and the
//!   part turns by `spin_deg` about the vertical over the print;
//! * the part's end in the tool-changer frame: `(0, 0, plate_offset_mm + h_k)` (the part axis
//!   is the tool z axis, the build-plate face `plate_offset_mm` from the flange);
//! * intended tool-changer pose: `R_k`, `p_k = tip_k − R_k (0, 0, plate_offset_mm + h_k)`.
//!
//! # Commanding it
//! The guide does what a printer's z axis does: `q1_k = q1_0 + (h_k − h_0)`. The arm joints
//! come from the IK of the **model being evaluated** (closed-form seeds refined on the full
//! model, `vatcal_planning::ik`): with the nominal model the cell goes where the nominal model
//! believes the pose is; with a calibrated model it goes (nearly) where it should.
//! [`plan_printing_joints`] chooses the guide start and the IK branch on the reference model
//! (all slices inside the joint limits with a margin, clear of singularities and collisions, no
//! joint jump between slices); [`command_printing_joints`] solves every slice on another model
//! from the reference joints, so that every model commands the same branch and guide schedule.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use vatcal_core::frame::{rot_x, rot_y, rot_z};
use vatcal_core::{Frame, JointVector, deg_to_rad};
use vatcal_kinematics::Model;
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::ik::{RefineOptions, ToolPoseIk, refine_tool_pose};
use vatcal_planning::motion::{JointBounds, SingularityMargins};

use vatcal_planning::collision::Contact;

use super::ValidationError;

/// Why the printing path cannot be commanded (the `source` of
/// [`ValidationError::PrintingPath`]; every message starts with `printing path:`).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PrintingPathError {
    /// The path has no slices.
    #[error("printing path: the path has no slices")]
    NoSlices,
    /// The guide's stroke is shorter than the part's height.
    #[error("printing path: the guide stroke cannot lift the part by {rise_mm:.1} mm")]
    GuideStroke {
        /// how far the guide must lift the part over the print \[mm\]
        rise_mm: f64,
    },
    /// No guide start and IK branch of the first slice commands the whole path.
    #[error(
        "printing path: no guide start and IK branch commands all {slices} slices ({tried} feasible first-slice solutions tried)"
    )]
    NoStart {
        /// number of slices
        slices: usize,
        /// feasible first-slice solutions tried
        tried: usize,
    },
    /// The reference joints do not have one joint vector per slice.
    #[error("printing path: {slices} slices but {reference} reference joint vectors")]
    ReferenceLength {
        /// number of slices
        slices: usize,
        /// number of reference joint vectors
        reference: usize,
    },
    /// The IK refinement of a slice failed (the planning error is the source).
    #[error("printing path: slice {slice}")]
    SliceIk {
        /// 0-based slice index
        slice: usize,
        /// why
        #[source]
        source: vatcal_planning::PlanError,
    },
    /// A slice's solution leaves the joint limits.
    #[error("printing path: slice {slice}: joint q{joint} = {value:.4} leaves its limits")]
    SliceLimits {
        /// 0-based slice index
        slice: usize,
        /// cell joint 1..=N
        joint: usize,
        /// value (mm for prismatic, rad for revolute joints)
        value: f64,
    },
    /// A model commands a slice into a collision.
    #[error("printing path: `{label}` commands slice {slice} into a collision ({contact})")]
    Collision {
        /// label of the commanding model
        label: String,
        /// 0-based slice index
        slice: usize,
        /// the bodies in contact
        contact: Contact,
    },
}

/// Definition of the printing path (see the module docs). Lengths in mm, angles in degrees.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PrintingPathOptions {
    /// number of slices (paper: 300)
    pub slices: usize,
    /// layer thickness \[mm\]
    pub layer_mm: f64,
    /// distance from the tool-changer frame origin to the build-plate face, along tool z \[mm\]
    pub plate_offset_mm: f64,
    /// first printing point on the tank bottom, world frame \[mm\]
    pub start_mm: [f64; 3],
    /// radius of the half circle the printing point follows \[mm\]
    pub lateral_radius_mm: f64,
    /// largest tilt of the plate from horizontal, reached mid-print \[deg\]
    pub tilt_max_deg: f64,
    /// rotation of the part about the vertical over the whole print \[deg\]
    pub spin_deg: f64,
    /// heading of the tool about the vertical at the first slice \[deg\]
    pub heading_deg: f64,
}

impl Default for PrintingPathOptions {
    /// 300 slices of 0.1 mm (a 30 mm part), build plate 160 mm from the flange, printing
    /// point starting at (−15, −40, 20) mm — the tank bottom is taken as the world plane
    /// z = 20 mm, the validation being a dry run just above the tank (the SMRs must be seen by
    /// the tracker), and 40 mm off the tank's y = 0 plane, which holds the horizontal J1 axis
    /// (a shoulder singularity) — moving 30 mm along a half circle of radius 15 mm, 8° of tilt
    /// mid-print, 30° of spin, heading 0°.
    fn default() -> Self {
        Self {
            slices: 300,
            layer_mm: 0.1,
            plate_offset_mm: 160.0,
            start_mm: [-15.0, -40.0, 20.0],
            lateral_radius_mm: 15.0,
            tilt_max_deg: 8.0,
            spin_deg: 30.0,
            heading_deg: 0.0,
        }
    }
}

impl PrintingPathOptions {
    /// Checks the options; errors name the field.
    pub fn check(&self) -> Result<(), ValidationError> {
        let bad = |field: &str, reason: String| Err(ValidationError::Option { option: field.into(), reason });
        if self.slices < 2 {
            return bad("printing.slices", format!("needs at least 2 slices, got {}", self.slices));
        }
        for (name, v) in
            [("printing.layer_mm", self.layer_mm), ("printing.plate_offset_mm", self.plate_offset_mm)]
        {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, format!("must be a positive length, got {v}"));
            }
        }
        let finite = [
            ("printing.start_mm", self.start_mm.iter().all(|v| v.is_finite())),
            ("printing.lateral_radius_mm", self.lateral_radius_mm.is_finite()),
            ("printing.tilt_max_deg", self.tilt_max_deg.is_finite() && self.tilt_max_deg.abs() < 90.0),
            ("printing.spin_deg", self.spin_deg.is_finite()),
            ("printing.heading_deg", self.heading_deg.is_finite()),
        ];
        for (name, ok) in finite {
            if !ok {
                return bad(name, "must be finite (tilt below 90 deg)".into());
            }
        }
        Ok(())
    }
}

/// One slice of the printing path: what the part should look like when that slice is cured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PrintingSlice {
    /// 0-based slice index
    pub index: usize,
    /// part height: build-plate face to the part's end \[mm\]
    pub part_height_mm: f64,
    /// intended printing point (the part's end) on the tank bottom, world \[mm\]
    pub tip_world_mm: Vector3<f64>,
    /// the part's end in the tool-changer frame \[mm\]
    pub tip_in_tool_mm: Vector3<f64>,
    /// centre of the build-plate face in the tool-changer frame \[mm\]
    pub plate_in_tool_mm: Vector3<f64>,
    /// intended world pose of the tool-changer frame (rotation + translation in mm)
    #[serde(with = "frame_serde")]
    pub tool_pose: Frame,
}

impl PrintingSlice {
    /// Intended world position of the build-plate face centre \[mm\].
    pub fn plate_world_mm(&self) -> Vector3<f64> {
        self.tool_pose.transform_point(&self.plate_in_tool_mm)
    }
}

/// The slices of the path defined by `opts` (see the module docs).
pub fn printing_path(opts: &PrintingPathOptions) -> Result<Vec<PrintingSlice>, ValidationError> {
    opts.check()?;
    let start = Vector3::from(opts.start_mm);
    let last = (opts.slices - 1) as f64;
    let down = rot_x(std::f64::consts::PI);
    let slices = (0..opts.slices)
        .map(|index| {
            let s = index as f64 / last;
            let phase = std::f64::consts::PI * s;
            let part_height_mm = (index + 1) as f64 * opts.layer_mm;
            let r = opts.lateral_radius_mm;
            let tip_world_mm = start + Vector3::new(r * (1.0 - phase.cos()), r * phase.sin(), 0.0);
            let heading = deg_to_rad(opts.heading_deg + opts.spin_deg * s);
            let tilt = deg_to_rad(opts.tilt_max_deg) * phase.sin();
            let rotation = rot_z(heading) * rot_y(tilt) * down;
            let plate_in_tool_mm = Vector3::new(0.0, 0.0, opts.plate_offset_mm);
            let tip_in_tool_mm = Vector3::new(0.0, 0.0, opts.plate_offset_mm + part_height_mm);
            let tool_pose = Frame { r: rotation, p: tip_world_mm - rotation * tip_in_tool_mm };
            PrintingSlice { index, part_height_mm, tip_world_mm, tip_in_tool_mm, plate_in_tool_mm, tool_pose }
        })
        .collect();
    Ok(slices)
}

/// Feasibility rules of the commanded printing path.
#[derive(Debug, Clone, Copy)]
pub struct PrintingJointRules<'a> {
    /// joint limits shrunk by the planning margins
    pub bounds: &'a JointBounds,
    /// singularity margins (on the reference model)
    pub singularity: SingularityMargins,
    /// collision checker (its model places the bodies)
    pub checker: &'a CollisionChecker<'a>,
    /// largest change of any arm joint between consecutive slices \[rad\] (no branch flips)
    pub max_joint_step_rad: f64,
    /// guide start positions tried, evenly spaced over the usable stroke
    pub guide_candidates: usize,
}

/// Guide position of every slice for a guide start `q1_0`: the guide lifts by one layer per
/// slice, like a printer's z axis.
pub fn guide_schedule(slices: &[PrintingSlice], q1_start_mm: f64) -> Vec<f64> {
    let h0 = slices.first().map_or(0.0, |s| s.part_height_mm);
    slices.iter().map(|s| q1_start_mm + (s.part_height_mm - h0)).collect()
}

/// The arm joints of the printing path on the reference `model`: tries every guide start of
/// the grid and every IK branch of the first slice (best joint-limit clearance first), follows
/// each slice by refining from the previous one, and returns the first whole path that obeys
/// `rules`.
///
/// # Errors
/// [`ValidationError::PrintingPath`] when no guide start and branch command the whole path.
pub fn plan_printing_joints(
    model: &Model,
    slices: &[PrintingSlice],
    rules: &PrintingJointRules<'_>,
) -> Result<Vec<JointVector>, ValidationError> {
    let first = slices.first().ok_or(ValidationError::PrintingPath(PrintingPathError::NoSlices))?;
    let rise = slices.last().map_or(0.0, |s| s.part_height_mm) - first.part_height_mm;
    let (lo, hi) = rules.bounds.bounds[0];
    if hi - rise < lo {
        return Err(PrintingPathError::GuideStroke { rise_mm: rise }.into());
    }
    let ik = ToolPoseIk::new(model, RefineOptions::default())?;
    let n = rules.guide_candidates.max(1);
    let mut starts: Vec<(f64, JointVector)> = Vec::new();
    for g in 0..n {
        let q1 =
            if n == 1 { 0.5 * (lo + hi - rise) } else { lo + (hi - rise - lo) * g as f64 / (n - 1) as f64 };
        for q in ik.solve_at_guide(q1, &first.tool_pose) {
            if slice_is_feasible(model, &q, rules) {
                starts.push((limit_clearance(rules.bounds, &q), q));
            }
        }
    }
    starts.sort_by(|a, b| b.0.total_cmp(&a.0));
    let tried = starts.len();
    for (_, q0) in starts {
        if let Some(path) = follow_path(model, slices, q0, rules) {
            return Ok(path);
        }
    }
    Err(PrintingPathError::NoStart { slices: slices.len(), tried }.into())
}

/// Follows the path from the first-slice joints `q0`, refining every slice from the previous
/// one; `None` at the first slice that breaks a rule.
fn follow_path(
    model: &Model,
    slices: &[PrintingSlice],
    q0: JointVector,
    rules: &PrintingJointRules<'_>,
) -> Option<Vec<JointVector>> {
    let guide = guide_schedule(slices, q0[0]);
    let mut out = Vec::with_capacity(slices.len());
    out.push(q0);
    let mut prev = q0;
    for (slice, q1) in slices.iter().zip(&guide).skip(1) {
        let mut seed = prev;
        seed[0] = *q1;
        let q = refine_tool_pose(model, &seed, &slice.tool_pose, &RefineOptions::default()).ok()?.q;
        let step = (1..7).map(|k| (q[k] - prev[k]).abs()).fold(0.0, f64::max);
        if step > rules.max_joint_step_rad || !slice_is_feasible(model, &q, rules) {
            return None;
        }
        out.push(q);
        prev = q;
    }
    Some(out)
}

fn slice_is_feasible(model: &Model, q: &JointVector, rules: &PrintingJointRules<'_>) -> bool {
    rules.bounds.contains(q)
        && rules.singularity.clear(model, &model.chain(q))
        && rules.checker.is_free(q, ProbeState::Absent)
}

/// Smallest distance of an arm joint to its (shrunk) limits \[rad\].
fn limit_clearance(bounds: &JointBounds, q: &JointVector) -> f64 {
    (1..7).map(|k| (q[k] - bounds.bounds[k].0).min(bounds.bounds[k].1 - q[k])).fold(f64::INFINITY, f64::min)
}

/// The joints that command the printing path on `model`: every slice is solved by the full-pose
/// IK refinement on `model`, seeded with the `reference` joints of the same slice (same guide
/// position, same branch). Every solution must lie inside the model's joint limits.
///
/// # Errors
/// [`ValidationError::PrintingPath`] when a slice does not converge or leaves the limits; a
/// length mismatch.
pub fn command_printing_joints(
    model: &Model,
    slices: &[PrintingSlice],
    reference: &[JointVector],
) -> Result<Vec<JointVector>, ValidationError> {
    if slices.len() != reference.len() {
        return Err(
            PrintingPathError::ReferenceLength { slices: slices.len(), reference: reference.len() }.into()
        );
    }
    slices
        .iter()
        .zip(reference)
        .map(|(slice, seed)| {
            let refined = refine_tool_pose(model, seed, &slice.tool_pose, &RefineOptions::default())
                .map_err(|source| PrintingPathError::SliceIk { slice: slice.index, source })?;
            if let Some((joint, value, ..)) = model.limit_violation(&refined.q) {
                return Err(PrintingPathError::SliceLimits { slice: slice.index, joint, value }.into());
            }
            Ok(refined.q)
        })
        .collect()
}

/// Serde of a [`Frame`] as `{ "rotation": [[row]; 3], "translation_mm": [x, y, z] }`.
mod frame_serde {
    use nalgebra::{Matrix3, Vector3};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    use vatcal_core::Frame;

    #[derive(Serialize, Deserialize)]
    struct Repr {
        rotation: [[f64; 3]; 3],
        translation_mm: [f64; 3],
    }

    pub fn serialize<S: Serializer>(f: &Frame, s: S) -> Result<S::Ok, S::Error> {
        let rotation = [0, 1, 2].map(|i| [0, 1, 2].map(|j| f.r[(i, j)]));
        Repr { rotation, translation_mm: [f.p.x, f.p.y, f.p.z] }.serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Frame, D::Error> {
        let r = Repr::deserialize(d)?;
        let m = Matrix3::from_fn(|i, j| r.rotation[i][j]);
        Ok(Frame { r: m, p: Vector3::from(r.translation_mm) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tip_stays_on_the_tank_bottom_and_the_plate_rises() {
        let opts = PrintingPathOptions::default();
        let path = printing_path(&opts).expect("path");
        assert_eq!(path.len(), 300);
        for s in &path {
            // the intended tool pose puts the part's end on the printing point
            let tip = s.tool_pose.transform_point(&s.tip_in_tool_mm);
            assert!((tip - s.tip_world_mm).norm() < 1e-9);
            assert!((s.tip_world_mm.z - 20.0).abs() < 1e-12);
            assert!((s.tool_pose.r.determinant() - 1.0).abs() < 1e-12);
            // the tool z axis points down (at most the tilt away from vertical)
            let down = -s.tool_pose.z_axis().z;
            assert!(down >= deg_to_rad(opts.tilt_max_deg).cos() - 1e-12, "{down}");
            // the plate face is the part height above the tip, along the part axis
            assert!(((s.plate_world_mm() - tip).norm() - s.part_height_mm).abs() < 1e-9);
        }
        assert!((path[299].part_height_mm - 30.0).abs() < 1e-9);
        assert!((path[299].tip_world_mm - path[0].tip_world_mm - Vector3::new(30.0, 0.0, 0.0)).norm() < 1e-9);
        let mid = &path[150];
        let tilt = (-mid.tool_pose.z_axis().z).acos().to_degrees();
        assert!((tilt - 8.0).abs() < 0.01, "{tilt}");
        assert_eq!(guide_schedule(&path, 100.0)[299], 100.0 + 29.9);
    }

    /// Every way the path cannot be commanded is a typed [`PrintingPathError`] whose message
    /// starts with `printing path:`; an IK failure keeps the planning error as the source.
    #[test]
    fn printing_path_errors_are_typed_and_keep_the_ik_error() {
        let cell = vatcal_core::CellFile::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/meca500-zaber.toml"
        ))
        .expect("fixture");
        let model = Model::from_cell(&cell).expect("model");
        let mut slices =
            printing_path(&PrintingPathOptions { slices: 2, ..Default::default() }).expect("path");
        let seed = JointVector::from_mm_deg(150.0, [0.0, 20.0, 20.0, 0.0, 40.0, 0.0]);
        let e = command_printing_joints(&model, &slices, &[seed]).expect_err("one seed for two slices");
        assert!(
            matches!(
                e,
                ValidationError::PrintingPath(PrintingPathError::ReferenceLength { slices: 2, reference: 1 })
            ),
            "{e:?}"
        );
        assert_eq!(e.to_string(), "printing path: 2 slices but 1 reference joint vectors");
        // from this seed the refinement of slice 0 converges outside the joint limits
        let e = command_printing_joints(&model, &slices, &[seed, seed]).expect_err("outside the limits");
        assert!(
            matches!(e, ValidationError::PrintingPath(PrintingPathError::SliceLimits { slice: 0, .. })),
            "{e:?}"
        );
        assert!(
            e.to_string().starts_with("printing path: slice 0: joint q")
                && e.to_string().ends_with("leaves its limits"),
            "{e}"
        );
        // slice 0 five metres above the cell: the IK refinement fails
        slices[0].tool_pose.p.z += 5000.0;
        let e = command_printing_joints(&model, &slices, &[seed, seed]).expect_err("out of reach");
        let ValidationError::PrintingPath(PrintingPathError::SliceIk { slice: 0, source }) = &e else {
            panic!("{e:?}");
        };
        assert_eq!(e.to_string(), "printing path: slice 0");
        let source_text = std::error::Error::source(&e).map(ToString::to_string);
        assert_eq!(source_text, Some(source.to_string()));
        assert!(source.to_string().contains("did not converge"), "{source}");
    }

    #[test]
    fn bad_options_name_the_field() {
        let e = printing_path(&PrintingPathOptions { slices: 1, ..Default::default() }).expect_err("bad");
        assert!(e.to_string().contains("printing.slices"), "{e}");
        let e =
            printing_path(&PrintingPathOptions { layer_mm: -0.1, ..Default::default() }).expect_err("bad");
        assert!(e.to_string().contains("printing.layer_mm"), "{e}");
    }
}
