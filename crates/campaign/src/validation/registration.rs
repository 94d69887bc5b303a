//! The pose of a rigid body from three or more of its points measured in the world: the
//! least-squares rigid registration (Kabsch; Umeyama without scale).
//!
//! With the points `l_k` known in the body frame (the SMR nests of the end-effector, inspected
//! on a CMM in the tool-changer frame) and measured in the world as `w_k`, the pose `(R, p)`
//! minimises `Σ ‖R l_k + p − w_k‖²`:
//!
//! 1. centroids `l̄`, `w̄`; cross-covariance `H = Σ (l_k − l̄)(w_k − w̄)ᵀ`;
//! 2. SVD `H = U S Vᵀ`; `R = V diag(1, 1, d) Uᵀ` with `d = sign det(V Uᵀ)` applied to the
//!    direction of the smallest singular value (a proper rotation, never a reflection);
//! 3. `p = w̄ − R l̄`.

use nalgebra::{Matrix3, Vector3};
use vatcal_core::Frame;

/// Why no pose can be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegistrationError {
    /// The two point lists differ in length.
    #[error("{local} body points but {world} measured points")]
    LengthMismatch {
        /// body points
        local: usize,
        /// measured points
        world: usize,
    },
    /// Fewer than three points.
    #[error("a pose needs at least 3 points, got {0}")]
    TooFewPoints(usize),
    /// The body points are (nearly) collinear: the rotation about their line is free.
    #[error("the body points are collinear: the pose is undetermined")]
    Collinear,
    /// A coordinate is NaN or infinite.
    #[error("point {0} is not finite")]
    NonFinite(usize),
}

/// The rigid transform `world ← body` that best maps `local[k]` onto `world[k]` (least
/// squares, see the module docs) \[mm\].
///
/// # Errors
/// Different lengths, fewer than 3 points, collinear body points, non-finite coordinates.
pub fn fit_rigid_transform(
    local: &[Vector3<f64>],
    world: &[Vector3<f64>],
) -> Result<Frame, RegistrationError> {
    if local.len() != world.len() {
        return Err(RegistrationError::LengthMismatch { local: local.len(), world: world.len() });
    }
    let n = local.len();
    if n < 3 {
        return Err(RegistrationError::TooFewPoints(n));
    }
    if let Some(k) = (0..n).find(|&k| !(local[k].iter().chain(world[k].iter()).all(|v| v.is_finite()))) {
        return Err(RegistrationError::NonFinite(k));
    }
    let nf = n as f64;
    let l_mean = local.iter().sum::<Vector3<f64>>() / nf;
    let w_mean = world.iter().sum::<Vector3<f64>>() / nf;
    let mut h = Matrix3::zeros();
    let mut spread = Matrix3::zeros();
    for (l, w) in local.iter().zip(world) {
        let dl = l - l_mean;
        h += dl * (w - w_mean).transpose();
        spread += dl * dl.transpose();
    }
    if is_collinear(&spread) {
        return Err(RegistrationError::Collinear);
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(RegistrationError::Collinear);
    };
    let v = v_t.transpose();
    let mut d = Matrix3::identity();
    if (v * u.transpose()).determinant() < 0.0 {
        let smallest = svd.singular_values.imin();
        d[(smallest, smallest)] = -1.0;
    }
    let r = v * d * u.transpose();
    Ok(Frame { r, p: w_mean - r * l_mean })
}

/// True when the second-largest principal spread of the body points is negligible next to the
/// largest one.
fn is_collinear(spread: &Matrix3<f64>) -> bool {
    let mut eig: Vec<f64> = spread.symmetric_eigen().eigenvalues.iter().copied().collect();
    eig.sort_by(|a, b| b.total_cmp(a));
    !(eig[0] > 0.0 && eig[1] > 1e-12 * eig[0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Unit};
    use proptest::prelude::*;

    fn smrs() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(-56.78, 30.515, 67.113),
            Vector3::new(0.214, 30.189, 124.59),
            Vector3::new(56.855, 30.647, 66.726),
        ]
    }

    proptest! {
        /// Exact points give back the pose to rounding, for any rotation and translation.
        #[test]
        fn exact_points_give_the_pose(
            ax in -1.0f64..1.0, ay in -1.0f64..1.0, az in -1.0f64..1.0, angle in 0.0f64..3.1,
            px in -500.0f64..500.0, py in -500.0f64..500.0, pz in -500.0f64..500.0,
        ) {
            let axis = Unit::try_new(Vector3::new(ax, ay, az), 1e-3).unwrap_or(Vector3::z_axis());
            let truth = Frame { r: *Rotation3::from_axis_angle(&axis, angle).matrix(), p: Vector3::new(px, py, pz) };
            let world: Vec<_> = smrs().iter().map(|l| truth.transform_point(l)).collect();
            let fit = fit_rigid_transform(&smrs(), &world).expect("fit");
            prop_assert!((fit.r - truth.r).norm() < 1e-12, "{} vs {}", fit.r, truth.r);
            prop_assert!((fit.p - truth.p).norm() < 1e-9);
            prop_assert!((fit.r.determinant() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn noisy_points_give_the_least_squares_pose() {
        // four SMRs (over-determined), fixed pseudo-random noise of ~10 µm
        let mut l = smrs();
        l.push(Vector3::new(10.0, -20.0, 90.0));
        let axis = Unit::new_normalize(Vector3::new(0.3, -1.0, 0.4));
        let truth = Frame {
            r: *Rotation3::from_axis_angle(&axis, 2.0).matrix(),
            p: Vector3::new(-40.0, 25.0, 300.0),
        };
        let noise = [[7.0, -3.0, 5.0], [-9.0, 4.0, 1.0], [2.0, 8.0, -6.0], [-1.0, -7.0, 3.0]];
        let world: Vec<_> =
            l.iter().zip(noise).map(|(p, n)| truth.transform_point(p) + Vector3::from(n) * 1e-3).collect();
        let fit = fit_rigid_transform(&l, &world).expect("fit");
        let cost = |f: &Frame| {
            l.iter().zip(&world).map(|(a, b)| (f.transform_point(a) - b).norm_squared()).sum::<f64>()
        };
        // close to the truth (noise-sized) ...
        assert!((fit.p - truth.p).norm() < 0.05 && (fit.r - truth.r).norm() < 1e-3);
        // ... and a minimum: every small rotation or translation away from it costs more
        let c0 = cost(&fit);
        assert!(c0 < cost(&truth));
        for k in 0..6 {
            for sign in [-1.0, 1.0] {
                let mut v = [0.0; 6];
                v[k] = sign * 1e-4;
                let rot = Rotation3::new(Vector3::new(v[0], v[1], v[2]));
                let moved = Frame {
                    r: rot.matrix() * fit.r,
                    p: rot.matrix() * fit.p + Vector3::new(v[3], v[4], v[5]),
                };
                assert!(cost(&moved) > c0, "direction {k} {sign}");
            }
        }
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let l = smrs();
        assert_eq!(fit_rigid_transform(&l[..2], &l[..2]), Err(RegistrationError::TooFewPoints(2)));
        assert!(matches!(fit_rigid_transform(&l, &l[..2]), Err(RegistrationError::LengthMismatch { .. })));
        let line = vec![Vector3::zeros(), Vector3::x(), Vector3::x() * 2.0];
        assert_eq!(fit_rigid_transform(&line, &line), Err(RegistrationError::Collinear));
        let mut bad = l.clone();
        bad[1].y = f64::NAN;
        assert_eq!(fit_rigid_transform(&l, &bad), Err(RegistrationError::NonFinite(1)));
    }
}
