//! Nominal Meca500 R3 kinematics for the simulator only (joints ↔ flange pose), so that the
//! fake robot can execute Cartesian moves (`MoveLinRel*`, `MovePose`, `MoveLin`) and answer
//! pose queries. This is the controller's *own* (nominal) model, like the real controller's;
//! the calibration crates model the real, imperfect robot separately.
//!
//! Modified DH (Craig), the same rows as the J1..J6 rows of `fixtures/meca500-zaber.toml`
//! with the robot standing upright (α₀ = 0):
//!
//! | i | α_{i-1} | a_{i-1} \[mm\] | θ offset | d_i \[mm\] |
//! |---|---|---|---|---|
//! | 1 | 0 | 0 | 0 | 135 |
//! | 2 | −90° | 0 | −90° | 0 |
//! | 3 | 0 | 135 | 0 | 0 |
//! | 4 | −90° | 38 | 0 | 120 |
//! | 5 | 90° | 0 | 0 | 0 |
//! | 6 | −90° | 0 | −180° | 70 |
//!
//! At zero joints the flange is at (190, 0, 308) mm, tool z along base +x — the pose
//! (190, 0, 308, 0, 90, 0) Mecademic documents for the zero position.

use nalgebra::{Isometry3, Matrix6, Rotation3, SVD, Translation3, UnitQuaternion, Vector3, Vector6};

use crate::codec::Six;

/// (α_{i-1} \[deg\], a_{i-1} \[mm\], θ offset \[deg\], d_i \[mm\]) per joint.
const MDH: [(f64, f64, f64, f64); 6] = [
    (0.0, 0.0, 0.0, 135.0),
    (-90.0, 0.0, -90.0, 0.0),
    (0.0, 135.0, 0.0, 0.0),
    (-90.0, 38.0, 0.0, 120.0),
    (90.0, 0.0, 0.0, 0.0),
    (-90.0, 0.0, -180.0, 70.0),
];

/// Why a Cartesian target has no joint solution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IkFailure {
    /// Newton iterations did not converge (target out of reach) → `[1016]`.
    OutOfReach,
    /// The Jacobian became singular on the way → `[1012]`.
    Singular,
}

/// Flange pose in the base frame for joints in degrees.
pub fn forward(joints_deg: &Six) -> Isometry3<f64> {
    let mut pose = Isometry3::identity();
    for ((alpha, a, offset, d), q) in MDH.iter().zip(joints_deg) {
        let rx = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), alpha.to_radians());
        let rz = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), (q + offset).to_radians());
        pose = pose
            * Isometry3::from_parts(Translation3::identity(), rx)
            * Isometry3::from_parts(Translation3::new(*a, 0.0, 0.0), UnitQuaternion::identity())
            * Isometry3::from_parts(Translation3::identity(), rz)
            * Isometry3::from_parts(Translation3::new(0.0, 0.0, *d), UnitQuaternion::identity());
    }
    pose
}

/// Mecademic pose `x, y, z \[mm\], α, β, γ \[deg\]` (intrinsic X-Y-Z Euler angles) of `pose`.
pub fn to_xyzabc(pose: &Isometry3<f64>) -> Six {
    let r = pose.rotation.to_rotation_matrix();
    let m = r.matrix();
    let sb = m[(0, 2)].clamp(-1.0, 1.0);
    let beta = sb.asin();
    let (alpha, gamma) = if sb.abs() < 1.0 - 1e-12 {
        ((-m[(1, 2)]).atan2(m[(2, 2)]), (-m[(0, 1)]).atan2(m[(0, 0)]))
    } else {
        // gimbal lock: put everything into gamma (alpha = 0)
        (0.0, m[(1, 0)].atan2(m[(1, 1)]))
    };
    let t = pose.translation.vector;
    [t.x, t.y, t.z, alpha.to_degrees(), beta.to_degrees(), gamma.to_degrees()]
}

/// Inverse of [`to_xyzabc`]: R = Rx(α)·Ry(β)·Rz(γ).
pub fn from_xyzabc(p: &Six) -> Isometry3<f64> {
    let r = Rotation3::from_axis_angle(&Vector3::x_axis(), p[3].to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), p[4].to_radians())
        * Rotation3::from_axis_angle(&Vector3::z_axis(), p[5].to_radians());
    Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), UnitQuaternion::from_rotation_matrix(&r))
}

/// Pose error (target − current): translation \[mm\] and rotation vector \[rad\], both in the
/// base frame.
fn pose_error(target: &Isometry3<f64>, current: &Isometry3<f64>) -> Vector6<f64> {
    let dp = target.translation.vector - current.translation.vector;
    let dr = (target.rotation * current.rotation.inverse()).scaled_axis();
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// Joints \[deg\] reaching `target` (flange pose in the base frame), by Newton iterations on
/// a central-difference Jacobian starting from `seed_deg`.
pub fn inverse(target: &Isometry3<f64>, seed_deg: &Six) -> Result<Six, IkFailure> {
    const MAX_ITER: usize = 100;
    const TOL: f64 = 1e-10;
    const H_DEG: f64 = 1e-6;
    const SINGULAR_SIGMA: f64 = 1e-5;
    let mut q = *seed_deg;
    for _ in 0..MAX_ITER {
        let err = pose_error(target, &forward(&q));
        if err.norm() < TOL {
            return Ok(q);
        }
        let mut jac = Matrix6::zeros();
        for j in 0..6 {
            let (mut plus, mut minus) = (q, q);
            plus[j] += H_DEG;
            minus[j] -= H_DEG;
            // d(pose)/dq_j per degree
            let col = pose_error(&forward(&plus), &forward(&minus)) / (2.0 * H_DEG);
            jac.set_column(j, &col);
        }
        let svd = SVD::new(jac, true, true);
        if svd.singular_values.min() < SINGULAR_SIGMA {
            return Err(IkFailure::Singular);
        }
        let step = svd.solve(&err, 0.0).map_err(|_| IkFailure::Singular)?;
        // limit the step to keep Newton in its basin
        let max = step.amax();
        let scale = if max > 10.0 { 10.0 / max } else { 1.0 };
        for (qi, s) in q.iter_mut().zip(step.iter()) {
            *qi += scale * s;
        }
    }
    Err(IkFailure::OutOfReach)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn zero_pose_is_the_documented_one() {
        let p = to_xyzabc(&forward(&[0.0; 6]));
        let expected = [190.0, 0.0, 308.0, 0.0, 90.0, 0.0];
        for (a, b) in p.iter().zip(expected) {
            assert!((a - b).abs() < 1e-9, "{p:?}");
        }
    }

    proptest! {
        #[test]
        fn euler_round_trip(p in proptest::array::uniform6(-80.0f64..80.0)) {
            let back = to_xyzabc(&from_xyzabc(&p));
            for (a, b) in p.iter().zip(back) {
                prop_assert!((a - b).abs() < 1e-9, "{:?} {:?}", p, back);
            }
        }

        #[test]
        fn ik_recovers_a_nearby_configuration(
            q in proptest::array::uniform6(-40.0f64..40.0),
            dq in proptest::array::uniform6(-3.0f64..3.0),
        ) {
            // keep away from the shoulder (wrist centre on the J1 axis), elbow (arm stretched)
            // and wrist (q5 = 0) singularities
            let mut q = q;
            q[1] = q[1].abs();
            q[2] = q[2] / 40.0 * 30.0 - 10.0;
            q[4] = 30.0 + q[4].abs();
            let target = forward(&q);
            let mut seed = q;
            for (s, d) in seed.iter_mut().zip(dq) { *s += d; }
            let sol = inverse(&target, &seed);
            prop_assert!(sol.is_ok());
            let sol = sol.unwrap_or(seed);
            let err = pose_error(&target, &forward(&sol)).norm();
            prop_assert!(err < 1e-8, "{}", err);
        }
    }

    #[test]
    fn unreachable_and_singular_targets_fail() {
        let far = Isometry3::translation(2000.0, 0.0, 0.0);
        assert!(inverse(&far, &[0.0, 0.0, 0.0, 0.0, 30.0, 0.0]).is_err());
        // q5 = 0 aligns joints 4 and 6: singular Jacobian
        assert_eq!(inverse(&Isometry3::translation(180.0, 0.0, 300.0), &[0.0; 6]), Err(IkFailure::Singular));
    }
}
