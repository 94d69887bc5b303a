//! The structure a closed form needs: the leading prismatic joints and six revolute ones, the
//! robot base frame, and the checks of the MDH rows' structural angles (shared with
//! `crate::parallel_arm`).

use nalgebra::{Matrix3, Vector3};
use vatcal_core::frame::{rot_x, rot_y, rot_z};
use vatcal_core::{Frame, JointVector};
use vatcal_kinematics::Model;

use super::common::wrap_angle;
use crate::error::PlanError;

/// Tolerance on the structural angles (alpha) for the closed form to be used as a seed (rad).
pub(crate) const STRUCTURE_ANGLE_TOL_RAD: f64 = 0.05;
/// Tolerance on the structural lengths that must be zero (mm).
pub(crate) const STRUCTURE_LENGTH_TOL_MM: f64 = 5.0;

/// Number of prismatic joints before the first revolute joint of `model` (the external axes
/// in front of the arm; 1 on the canonical cell, 0 for an arm on a table).
pub fn leading_prismatic_joints(model: &Model) -> usize {
    model.joint_kinds().iter().take_while(|k| !k.is_revolute()).count()
}

/// The cell row of the first arm joint of a chain that is six revolute joints after its
/// prismatic external axes (if any) — what every closed-form IK needs.
///
/// # Errors
/// [`PlanError::UnsupportedArm`] describing the chain otherwise.
pub fn six_revolute_arm(model: &Model) -> Result<usize, PlanError> {
    let n = model.joint_count();
    let k = leading_prismatic_joints(model);
    if n != k + 6 || !model.joint_kinds()[k..].iter().all(|j| j.is_revolute()) {
        return Err(PlanError::UnsupportedArm(format!(
            "the closed-form IK needs six revolute joints after the prismatic external axes (if any); this chain has {}",
            model.describe_chain()
        )));
    }
    Ok(k + 1)
}

/// World pose of the robot base frame `B` (parent of the arm's first MDH frame) at guide
/// position `q1_mm`: the frame after the prismatic joints in front of the arm (the first at
/// `q1_mm`, any others at 0; `q1_mm` is ignored without one), followed by the fixed part
/// `Rx(alpha) Tx(a) Ry(beta)` of the arm's first row. Includes the model's base pose and the
/// guide effects. See [`robot_base_frame_at`] to give every external axis.
pub fn robot_base_frame(model: &Model, q1_mm: f64) -> Frame {
    let mut q = JointVector::zeros(model.joint_count());
    if leading_prismatic_joints(model) > 0 {
        q[0] = q1_mm;
    }
    robot_base_frame_at(model, &q)
}

/// World pose of the robot base frame `B` with the prismatic joints in front of the arm at
/// their values in `q` (the arm's values in `q` are not used). On a chain without a revolute
/// joint this is the last frame.
pub fn robot_base_frame_at(model: &Model, q: &JointVector) -> Frame {
    let k = leading_prismatic_joints(model);
    let chain = model.chain(q);
    if k >= model.joint_count() {
        return chain.frames[k];
    }
    let row = model.row(k + 1);
    let fixed = Frame { r: rot_x(row.alpha) * rot_y(row.beta), p: Vector3::new(row.a, 0.0, 0.0) };
    chain.frames[k].compose(&fixed)
}

/// Why a chain does not qualify for the closed form: in joint row `row` (1-based), the value
/// of `field` (its cell-file name) is `value`, the closed form needs `want` (`why`).
pub(crate) fn structure_error(row: usize, field: &str, value: String, want: &str, why: &str) -> PlanError {
    PlanError::UnsupportedArm(format!(
        "joint row {row}: {field} = {value}, the closed form needs {want} ({why})"
    ))
}

/// `Ok(±pi/2)` when `alpha` is within the tolerance of ±90 deg.
pub(crate) fn quarter_turn(row: usize, alpha: f64, why: &str) -> Result<f64, PlanError> {
    use std::f64::consts::FRAC_PI_2;
    let sign = if wrap_angle(alpha - FRAC_PI_2).abs() <= STRUCTURE_ANGLE_TOL_RAD {
        1.0
    } else if wrap_angle(alpha + FRAC_PI_2).abs() <= STRUCTURE_ANGLE_TOL_RAD {
        -1.0
    } else {
        return Err(structure_error(
            row,
            "alpha_deg",
            format!("{:.3}", alpha.to_degrees()),
            &format!("±90 ± {:.1} deg", STRUCTURE_ANGLE_TOL_RAD.to_degrees()),
            why,
        ));
    };
    Ok(sign * FRAC_PI_2)
}

/// `Ok(0)` or `Ok(pi)` when `alpha` (a structure angle of joint row `row`) is within the
/// tolerance of 0 or 180 deg (parallel axes).
pub(crate) fn zero_or_half_turn(row: usize, alpha: f64, why: &str) -> Result<f64, PlanError> {
    use std::f64::consts::PI;
    if wrap_angle(alpha).abs() <= STRUCTURE_ANGLE_TOL_RAD {
        Ok(0.0)
    } else if wrap_angle(alpha - PI).abs() <= STRUCTURE_ANGLE_TOL_RAD {
        Ok(PI)
    } else {
        Err(structure_error(
            row,
            "alpha_deg",
            format!("{:.3}", alpha.to_degrees()),
            &format!("0 or 180 ± {:.1} deg", STRUCTURE_ANGLE_TOL_RAD.to_degrees()),
            why,
        ))
    }
}

/// `cos` of an exact structure angle 0 or pi: +1 or -1.
pub(crate) fn sign_of_cos(alpha: f64) -> f64 {
    if alpha == 0.0 { 1.0 } else { -1.0 }
}

/// One MDH link `Rx(alpha) Tx(a) Rz(theta) Tz(d)` with `Rx(alpha)` given.
pub(crate) fn mdh_link(rx: &Matrix3<f64>, a: f64, theta: f64, d: f64) -> Frame {
    let r = rx * rot_z(theta);
    Frame { r, p: Vector3::new(a, 0.0, 0.0) + r.column(2) * d }
}
