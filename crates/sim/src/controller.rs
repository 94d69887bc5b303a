//! The simulated robot controller: it believes the **nominal** geometry.
//!
//! A relative linear move asks for a pure translation of the flange (hence of every tool
//! point) with the orientation unchanged. The controller solves that with its own model — the
//! nominal one — by Newton iterations on the 6×n geometric Jacobian of the flange pose with
//! respect to the n arm joints (guide fixed; any chain, [`JointLayout`]): the 6×6 solve of a
//! six-axis arm, the minimum-norm step of a redundant one (an arm with fewer than six joints
//! cannot hold the orientation in general and is refused where it cannot). Physically the arm
//! then moves by whatever the *true* geometry makes of those joints: the difference is what
//! calibration identifies.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Matrix6xX, Vector3, Vector6};
use vatcal_core::JointVector;
use vatcal_hardware_traits::{JointLayout, LinearFrame};
use vatcal_kinematics::Model;

/// Why the controller refuses a linear move (Meca500 codes: 1012 singularity, 1007 limit).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum LinearMoveError {
    /// The Jacobian is singular or Newton did not converge.
    Singular,
    /// The solution puts cell joint `.0` outside its limits.
    Limit(usize),
}

/// Orientation error vector taking `r` to `r_target` (small-angle, exact zero iff equal).
fn orientation_error(r: &Matrix3<f64>, r_target: &Matrix3<f64>) -> Vector3<f64> {
    0.5 * (0..3).map(|k| r.column(k).cross(&r_target.column(k))).fold(Vector3::zeros(), |a, b| a + b)
}

/// World displacement of the flange that the controller aims at, for `displacement_mm` in
/// `frame` at joints `q` (World = the axes of the frame the arm is mounted on: MDH frame 1, the
/// carriage, on a cell with a guide; frame 0, the robot base, otherwise).
pub(crate) fn world_displacement(
    nominal: &Model,
    q: &JointVector,
    displacement_mm: &Vector3<f64>,
    frame: LinearFrame,
) -> Vector3<f64> {
    let chain = nominal.chain(q);
    let mount = JointLayout::of(nominal.joint_kinds()).guide_joint().unwrap_or(0);
    match frame {
        LinearFrame::Tool => chain.flange().r * displacement_mm,
        LinearFrame::World => chain.frames[mount].r * displacement_mm,
    }
}

/// Geometric Jacobian (6×n) of the flange (MDH frame N) with respect to the n arm joints of
/// the model's [`JointLayout`] (the six Meca500 joints on the canonical cell): rows 0..3 the
/// linear velocity \[mm/rad\] (mm/mm for a prismatic joint), rows 3..6 the angular velocity.
/// Near a singularity a small translation needs large joint motions (the simulated controller
/// refuses linear moves there, like the real one); see [`translation_joint_gain`].
pub fn flange_jacobian(model: &Model, q: &JointVector) -> Matrix6xX<f64> {
    let layout = JointLayout::of(model.joint_kinds());
    let chain = model.chain(q);
    let flange = chain.flange();
    let mut jac = Matrix6xX::zeros(layout.arm_joint_count());
    for j in 0..layout.arm_joint_count() {
        let joint = layout.cell_joint(j);
        let axis_frame = chain.frames[joint];
        let z = axis_frame.z_axis();
        let (v, w) = if model.is_revolute(joint) {
            (z.cross(&(flange.p - axis_frame.p)), z)
        } else {
            (z, Vector3::zeros())
        };
        jac.fixed_view_mut::<3, 1>(0, j).copy_from(&v);
        jac.fixed_view_mut::<3, 1>(3, j).copy_from(&w);
    }
    jac
}

/// The joint motion that realises the flange twist `rhs` (6×n Jacobian `jac`): the exact
/// solve of a six-joint arm (`None` near a singularity, |det| < 1e-3), the minimum-norm
/// solution of a redundant arm (`None` when `J Jᵀ` is near-singular), the least-squares
/// solution of an arm with fewer joints (`None` when `Jᵀ J` is).
fn joint_step(jac: &Matrix6xX<f64>, rhs: &Vector6<f64>) -> Option<DVector<f64>> {
    let n = jac.ncols();
    if n == 6 {
        let lu = Matrix6::from_iterator(jac.iter().copied()).lu();
        if lu.determinant().abs() < 1e-3 {
            return None;
        }
        return lu.solve(rhs).map(|v| DVector::from_column_slice(v.as_slice()));
    }
    let j = DMatrix::from_column_slice(6, n, jac.as_slice());
    let r = DVector::from_column_slice(rhs.as_slice());
    if n > 6 {
        let jjt = &j * j.transpose();
        if jjt.determinant().abs() < 1e-3 {
            return None;
        }
        Some(j.transpose() * jjt.lu().solve(&r)?)
    } else {
        let jtj = j.transpose() * &j;
        if jtj.determinant().abs() < 1e-9 {
            return None;
        }
        jtj.lu().solve(&(j.transpose() * r))
    }
}

/// Largest joint motion per millimetre of pure flange translation at `q` [rad/mm] (orientation
/// held): about 0.01 in the middle of the workspace, growing without bound toward a
/// singularity; `None` at an exact singularity (or when the arm cannot translate its flange
/// with the orientation held).
pub fn translation_joint_gain(model: &Model, q: &JointVector) -> Option<f64> {
    let jac = flange_jacobian(model, q);
    if jac.ncols() == 6 {
        let inv = Matrix6::from_iterator(jac.iter().copied()).try_inverse()?;
        return Some(inv.columns(0, 3).amax());
    }
    (0..3)
        .map(|axis| joint_step(&jac, &Vector6::ith(axis, 1.0)).map(|dq| dq.amax()))
        .try_fold(0.0, |m: f64, g| g.map(|g| m.max(g)))
}

/// Joints (guide unchanged) that translate the nominal flange by `delta_world_mm` with the
/// orientation kept, starting from `q`.
pub(crate) fn translate_flange(
    nominal: &Model,
    q: &JointVector,
    delta_world_mm: &Vector3<f64>,
) -> Result<JointVector, LinearMoveError> {
    let layout = JointLayout::of(nominal.joint_kinds());
    let start = nominal.chain(q).flange();
    let p_target = start.p + delta_world_mm;
    let r_target = start.r;
    let mut x = *q;
    for _ in 0..30 {
        let flange = nominal.chain(&x).flange();
        let e_p = p_target - flange.p;
        let e_r = orientation_error(&flange.r, &r_target);
        if e_p.norm() < 1e-9 && e_r.norm() < 1e-12 {
            return match nominal.limit_violation(&x) {
                Some((joint, ..)) => Err(LinearMoveError::Limit(joint)),
                None => Ok(x),
            };
        }
        let jac = flange_jacobian(nominal, &x);
        let mut rhs = Vector6::zeros();
        rhs.fixed_rows_mut::<3>(0).copy_from(&e_p);
        rhs.fixed_rows_mut::<3>(3).copy_from(&e_r);
        // a near-singular arm (e.g. wrist singularity) is refused like the real controller does
        let Some(dq) = joint_step(&jac, &rhs) else { return Err(LinearMoveError::Singular) };
        if dq.amax() > 0.5 || !dq.iter().all(|v| v.is_finite()) {
            return Err(LinearMoveError::Singular);
        }
        for (k, d) in dq.iter().enumerate() {
            x[layout.cell_joint(k) - 1] += d;
        }
    }
    Err(LinearMoveError::Singular)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::CellFile;

    fn nominal() -> Model {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("fixture");
        Model::from_cell(&cell).expect("model")
    }

    #[test]
    fn flange_translates_exactly_on_the_nominal_model() {
        let m = nominal();
        let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 15.0, 40.0, -25.0]);
        for frame in [LinearFrame::Tool, LinearFrame::World] {
            let d = Vector3::new(0.8, -1.5, 2.0);
            let delta = world_displacement(&m, &q, &d, frame);
            assert!((delta.norm() - d.norm()).abs() < 1e-12);
            let q2 = translate_flange(&m, &q, &delta).expect("ik");
            assert_eq!(q2[0], q[0], "guide untouched");
            let (a, b) = (m.chain(&q), m.chain(&q2));
            assert!((b.frames[7].p - a.frames[7].p - delta).norm() < 1e-9);
            assert!((b.frames[7].r - a.frames[7].r).norm() < 1e-12);
            // every TCP moves by the same vector
            for t in m.tcp_ids() {
                let dp = m.tcp_position(&q2, t).expect("fk") - m.tcp_position(&q, t).expect("fk");
                assert!((dp - delta).norm() < 1e-9);
            }
        }
    }

    #[test]
    fn translation_gain_grows_toward_singularities() {
        let m = nominal();
        let good = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 15.0, 40.0, -25.0]);
        let g = translation_joint_gain(&m, &good).expect("regular");
        assert!(g > 0.001 && g < 0.05, "{g}");
        let near = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 15.0, 0.5, -25.0]);
        assert!(translation_joint_gain(&m, &near).expect("near") > 10.0 * g);
    }

    #[test]
    fn singular_wrist_is_refused() {
        let m = nominal();
        // J5 = 0: wrist singularity (J4 and J6 aligned)
        let q = JointVector::from_mm_deg(150.0, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let r = translate_flange(&m, &q, &Vector3::new(0.5, 0.0, 0.0));
        assert_eq!(r, Err(LinearMoveError::Singular));
    }
}
