//! The pose solver: Newton's method on the analytic tool-frame Jacobian, and IK branches.
//!
//! The error of the tool-changer frame at `q` is `e = [p* − p; log(R* Rᵀ)]` (world position
//! \[mm\] and world rotation vector \[rad\]). Its derivative with respect to a solved revolute
//! joint `i` ([`JointSplit`]) is `[z_i × (p − o_i); z_i]` (a prismatic one: `[z_i; 0]`) with
//! `z_i`, `o_i` the world axis and origin of MDH frame `i` of the model's own chain
//! ([`vatcal_kinematics::Chain::frames`]), exactly the columns of `vatcal_planning::ik`'s
//! refinement. The step solves `J Δq = e` (6×6 LU, on the stack).
//! The forward kinematics include compliance and every enabled effect with the request's
//! context; the Jacobian holds gravity torques and the joint effects' `dθ/dq` fixed, so with
//! them the iteration is quasi-Newton — still converging to rounding level because those
//! terms are tiny (`c_i ∂τ_i/∂q ~ 1e-4`). A step is shortened (halved, up to 6 times) when it
//! does not reduce the error (weighted `|Δp|² + (100 mm · |Δr|)²`), and capped at
//! [`SolveOptions::max_step_rad`] per joint so that a warm start stays in its basin. Nothing
//! is allocated.

use std::fmt;

use nalgebra::Vector6;
use vatcal_core::{Frame, JointVector};
use vatcal_kinematics::{Chain, Model};
use vatcal_planning::ik::rotation_vector;

use crate::ToolTarget;
pub use crate::branch::Branch;
pub use crate::split::JointSplit;

/// Weight of the orientation error against the position error in the step acceptance
/// (mm per rad).
const ORIENTATION_SCALE_MM: f64 = 100.0;
/// Step halvings tried before giving up.
const MAX_HALVINGS: usize = 6;

/// Tolerances and limits of the solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveOptions {
    /// iteration cap per pose
    pub max_iterations: usize,
    /// iterate until the position error is below this \[mm\] ...
    pub tol_position_mm: f64,
    /// ... and the orientation error below this \[rad\]
    pub tol_rotation_rad: f64,
    /// a pose whose iteration stalls is still accepted below this position error \[mm\] ...
    pub accept_position_mm: f64,
    /// ... and this orientation error \[rad\] (the requirement: 1e-6 mm, 1e-9 rad)
    pub accept_rotation_rad: f64,
    /// largest change of one joint in one Newton step \[rad\]
    pub max_step_rad: f64,
}

impl Default for SolveOptions {
    /// Iterate to 1e-9 mm / 1e-12 rad (a thousand times below the requirement), accept down
    /// to the requirement 1e-6 mm / 1e-9 rad; 30 iterations; steps of at most 0.3 rad.
    fn default() -> Self {
        Self {
            max_iterations: 30,
            tol_position_mm: 1e-9,
            tol_rotation_rad: 1e-12,
            accept_position_mm: 1e-6,
            accept_rotation_rad: 1e-9,
            max_step_rad: 0.3,
        }
    }
}

/// A converged solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solved {
    /// joints (q1 as requested)
    pub q: JointVector,
    /// Newton iterations used
    pub iterations: usize,
    /// final tool-frame position error \[mm\]
    pub position_error_mm: f64,
    /// final tool-frame orientation error \[rad\]
    pub rotation_error_rad: f64,
}

/// A failed solve: the error reached.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NotConverged {
    /// position error \[mm\]
    pub position_error_mm: f64,
    /// orientation error \[rad\]
    pub rotation_error_rad: f64,
}

impl fmt::Display for NotConverged {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "no convergence: tool error {:.3e} mm, {:.3e} rad",
            self.position_error_mm, self.rotation_error_rad
        )
    }
}

/// `[p* − p; log(R* Rᵀ)]` of the tool frame of `chain`.
#[inline]
pub fn tool_error(chain: &Chain, target: &Frame) -> Vector6<f64> {
    let dp = target.p - chain.tool.p;
    let dr = rotation_vector(&(target.r * chain.tool.r.transpose()));
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

pub use vatcal_planning::ik::tool_jacobian;

#[inline]
fn norms(e: &Vector6<f64>) -> (f64, f64) {
    (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm())
}

#[inline]
fn cost(e: &Vector6<f64>) -> f64 {
    let (p, r) = norms(e);
    p * p + (ORIENTATION_SCALE_MM * r) * (ORIENTATION_SCALE_MM * r)
}

/// Newton iterations from `seed` (its given joints are replaced by the target's) until the
/// model's tool-changer frame, with the target's context, is at `target.tool`. `split` is
/// [`JointSplit::of`] the model.
pub fn newton(
    model: &Model,
    split: &JointSplit,
    target: &ToolTarget,
    seed: &JointVector,
    opts: &SolveOptions,
) -> Result<Solved, NotConverged> {
    let mut q = *seed;
    split.apply_given(&mut q, &target.given);
    let fk = |q: &JointVector| model.chain_full(q, &target.context, false, None);
    let mut chain = fk(&q);
    let mut e = tool_error(&chain, &target.tool);
    let mut c = cost(&e);
    let mut iterations = 0;
    loop {
        let (pe, re) = norms(&e);
        if pe <= opts.tol_position_mm && re <= opts.tol_rotation_rad {
            break;
        }
        if iterations == opts.max_iterations || !c.is_finite() {
            break;
        }
        let Some(step) = split.jacobian(&chain).lu().solve(&e) else {
            break;
        };
        let largest = step.amax();
        if !largest.is_finite() {
            break;
        }
        let mut scale = if largest > opts.max_step_rad { opts.max_step_rad / largest } else { 1.0 };
        let mut accepted = false;
        for _ in 0..=MAX_HALVINGS {
            let mut trial = q;
            for (k, &i) in split.free().iter().enumerate() {
                trial[i] += scale * step[k];
            }
            let trial_chain = fk(&trial);
            let trial_e = tool_error(&trial_chain, &target.tool);
            let trial_c = cost(&trial_e);
            if trial_c < c {
                q = trial;
                chain = trial_chain;
                e = trial_e;
                c = trial_c;
                accepted = true;
                break;
            }
            // at rounding level a full step no longer helps: stop without halving
            if pe <= opts.accept_position_mm && re <= opts.accept_rotation_rad {
                break;
            }
            scale *= 0.5;
        }
        iterations += 1;
        if !accepted {
            break;
        }
    }
    let (position_error_mm, rotation_error_rad) = norms(&e);
    if position_error_mm <= opts.accept_position_mm && rotation_error_rad <= opts.accept_rotation_rad {
        Ok(Solved { q, iterations, position_error_mm, rotation_error_rad })
    } else {
        Err(NotConverged { position_error_mm, rotation_error_rad })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::CellFile;
    use vatcal_planning::ik::ArmGeometry;

    fn nominal() -> Model {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("cell");
        Model::from_cell(&cell).expect("model")
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let m = nominal();
        let q = JointVector::from_mm_deg(120.0, [20.0, 10.0, -30.0, 40.0, 50.0, -60.0]);
        let c = m.chain(&q);
        assert_matches_central_differences(&m, &q, &tool_jacobian(&c), 1, 1e-5);
    }

    /// Column `k` of the 6 × 6 tool Jacobian `j` against central differences of joint
    /// `first + k` (0-based): position rows within `position_tol`, rotation rows within 1e-8.
    fn assert_matches_central_differences(
        m: &Model,
        q: &JointVector,
        j: &nalgebra::Matrix6<f64>,
        first: usize,
        position_tol: f64,
    ) {
        let h = 1e-6;
        for k in 0..6 {
            let (mut qp, mut qm) = (*q, *q);
            qp[k + first] += h;
            qm[k + first] -= h;
            let (cp, cm) = (m.chain(&qp), m.chain(&qm));
            let dp = (cp.tool.p - cm.tool.p) / (2.0 * h);
            let dr = rotation_vector(&(cp.tool.r * cm.tool.r.transpose())) / (2.0 * h);
            for r in 0..3 {
                assert!(
                    (j[(r, k)] - dp[r]).abs() < position_tol,
                    "col {k} row {r}: {} vs {}",
                    j[(r, k)],
                    dp[r]
                );
                assert!((j[(r + 3, k)] - dr[r]).abs() < 1e-8, "col {k} rot {r}");
            }
        }
    }

    /// The split's Jacobian is planning's tool Jacobian on the canonical cell (bit for bit),
    /// and matches central differences on the UR5e (all six joints solved).
    #[test]
    fn split_jacobian_is_the_tool_jacobian_and_matches_finite_differences() {
        let m = nominal();
        let q = JointVector::from_mm_deg(120.0, [20.0, 10.0, -30.0, 40.0, 50.0, -60.0]);
        let split = JointSplit::of(&m).expect("split");
        assert_eq!(split.jacobian(&m.chain(&q)), tool_jacobian(&m.chain(&q)));
        let cell =
            CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml")).expect("cell");
        let ur = Model::from_cell(&cell).expect("model");
        let split = JointSplit::of(&ur).expect("split");
        let q = JointVector::new([0.3, -1.2, 1.1, -1.4, 1.2, 0.2]);
        assert_matches_central_differences(&ur, &q, &split.jacobian(&ur.chain(&q)), 0, 1e-4);
    }

    #[test]
    fn branches_of_the_closed_form_solutions_are_their_own() {
        let m = nominal();
        let arm = ArmGeometry::from_model(&m).expect("arm");
        let q = JointVector::from_mm_deg(100.0, [15.0, 20.0, -25.0, 30.0, 45.0, 10.0]);
        let base = vatcal_planning::ik::robot_base_frame(&m, 100.0);
        let target = base.inverse().compose(&m.chain(&q).tool);
        let sols = arm.solve(&target);
        assert_eq!(sols.len(), 8);
        for (s, b) in sols.as_slice().iter().zip(sols.branches()) {
            let mut qq = [0.0; 7];
            qq[0] = 100.0;
            qq[1..].copy_from_slice(s);
            assert_eq!(Branch::of(&arm, &JointVector::new(qq)), Branch(*b), "{s:?}");
        }
    }
}
