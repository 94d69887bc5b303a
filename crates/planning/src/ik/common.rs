//! What both IKs share: angle wrapping, rotation vectors and the refinement's options (the
//! closed-form IK of this module and the multi-start numerical IK of `crate::numeric_ik` both
//! build on these).

use nalgebra::{Matrix3, Vector3};
use vatcal_core::JointVector;

/// Wraps an angle into (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut w = a % two_pi;
    if w <= -std::f64::consts::PI {
        w += two_pi;
    } else if w > std::f64::consts::PI {
        w -= two_pi;
    }
    w
}

/// Rotation vector (axis × angle) of a rotation matrix, accurate for small angles
/// (unlike `acos`-based formulas, whose error near 0 is ~1e-8 rad).
pub fn rotation_vector(r: &Matrix3<f64>) -> Vector3<f64> {
    let v = 0.5 * Vector3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)]);
    let s = v.norm();
    let c = 0.5 * (r.trace() - 1.0);
    let angle = s.atan2(c);
    if s > 1e-6 {
        return v * (angle / s);
    }
    if c > 0.0 {
        // tiny angle: sin(angle) = angle to second order
        return v;
    }
    // angle close to pi: axis from the symmetric part (R + I) / 2 = a a^T (approximately)
    let b = 0.5 * (r + Matrix3::identity());
    let k = (0..3).max_by(|&i, &j| b[(i, i)].total_cmp(&b[(j, j)])).unwrap_or(0);
    let mut axis: Vector3<f64> = b.column(k).into_owned();
    let n = axis.norm();
    if n > 0.0 {
        axis /= n;
    }
    if axis.dot(&v) < 0.0 {
        axis = -axis;
    }
    axis * angle
}

/// Angle (rad) of the rotation taking `a` to `b` (both rotation matrices).
pub fn rotation_angle_between(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    rotation_vector(&(b * a.transpose())).norm()
}

/// Options of the numerical refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineOptions {
    /// maximum number of iterations
    pub max_iterations: usize,
    /// stop when the tool position error is below this (mm) ...
    pub tol_position_mm: f64,
    /// ... and the tool orientation error below this (rad)
    pub tol_rotation_rad: f64,
    /// length that weighs orientation against position in the damped step (mm/rad)
    pub orientation_scale_mm: f64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            tol_position_mm: 1e-10,
            tol_rotation_rad: 1e-13,
            orientation_scale_mm: 100.0,
        }
    }
}

/// Largest absolute componentwise difference of two joint vectors (internal units).
pub(crate) fn max_abs_diff(a: &JointVector, b: &JointVector) -> f64 {
    a.as_slice().iter().zip(b.as_slice()).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_angle_range() {
        use std::f64::consts::{PI, TAU};
        for a in [-10.0, -PI, 0.0, 3.0, PI, 7.0, 100.0] {
            let w = wrap_angle(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            let turns = (a - w) / TAU;
            assert!((turns - turns.round()).abs() < 1e-12, "{a} -> {w} is not a whole number of turns away");
        }
    }

    #[test]
    fn rotation_vector_small_and_large_angles() {
        for (axis, angle) in [
            (Vector3::new(1.0, 2.0, 3.0).normalize(), 1e-9),
            (Vector3::new(0.0, 0.0, 1.0), 0.7),
            (Vector3::new(1.0, -1.0, 0.5).normalize(), std::f64::consts::PI - 1e-9),
        ] {
            let r =
                *nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle).matrix();
            let v = rotation_vector(&r);
            assert!((v - axis * angle).norm() < 1e-8 * angle.max(1e-6), "{v} vs {}", axis * angle);
        }
    }
}
