//! The wrist-band search of [`ToolPoseIk::add_wrist_band_solutions`]: the further solutions
//! of a calibrated wrist near its singularity.

use vatcal_core::{Frame, JointVector, deg_to_rad};

use super::closed_form::ClosedFormArm;
use super::common::{rotation_vector, wrap_angle};
use super::refine::arm_tool_jacobian;
use super::tool_pose::ToolPoseIk;

/// Band around the wrist singularity (`|sin theta_5| < sin(band)`) in which the soft wrist
/// direction of a refined solution on a calibrated model is scanned
/// ([`ToolPoseIk::add_wrist_band_solutions`]) (deg).
pub const WRIST_SCAN_BAND_DEG: f64 = 15.0;

/// Steps per turn of `theta_4` of the scan of the soft wrist direction
/// ([`ToolPoseIk::add_wrist_band_solutions`]; every 5 deg: further solutions were seen 8 deg
/// apart in `theta_4`).
pub const WRIST_SCAN_STEPS: usize = 72;

/// Re-seeds per turn of `theta_4` of a solution in the wrist band, besides the scan (every
/// 30 deg; [`ToolPoseIk::add_wrist_band_solutions`]).
pub const WRIST_RESEEDS: usize = 12;

/// At most this many distinct solutions has the inverse kinematics of a 6R arm (a general 6R
/// arm has up to 16); the wrist band search stops there.
const MAX_6R_SOLUTIONS: usize = 16;

/// Gauss–Newton steps of each fit of that scan (continued from the previous step's fit).
const WRIST_FIT_ITERATIONS: usize = 8;

/// Regula falsi steps on `theta_4` for each solution bracketed by that scan.
const WRIST_ROOT_ITERATIONS: usize = 40;

impl<'a, A: ClosedFormArm> ToolPoseIk<'a, A> {
    /// Completes `solutions` (refined solutions for the world tool pose `target`, arm joints
    /// wrapped) near the wrist singularity of a calibrated model; does nothing on a model the
    /// closed form solves exactly (a spherical wrist has no further solutions), and on an arm
    /// without a spherical wrist ([`ParallelArm`](crate::ik::ParallelArm): its wrist singularity
    /// is another one, not searched; see `docs/planning.md`).
    ///
    /// Why: the closed form's eight branches are those of the spherical wrist. Within a few
    /// degrees of the wrist singularity (`sin theta_5 = 0`, axes 4 and 6 aligned) the tool
    /// orientation fixes `theta_4 + k theta_6` well and the difference badly (`k = ±1`); a
    /// calibrated wrist, whose axes no longer meet exactly, couples that soft direction to the
    /// arm joints, and where the wrist centre is also close to the axis of arm joint 1 (the
    /// shoulder singularity) one spherical-wrist branch can become three solutions of the model
    /// (a fold), or two seeds can refine to the same solution so that a branch is lost. Each
    /// refined branch is the continuation of a nominal one and correct, but the other solutions
    /// are missed.
    ///
    /// What: every solution (given or found here) with `|sin theta_5| <
    /// sin(`[`WRIST_SCAN_BAND_DEG`]`)` that no earlier scan met has its soft direction searched
    /// in two ways (`k = -sign(alpha_4 alpha_5) sign(cos theta_5)`, so that `theta_4 + k
    /// theta_6` is kept):
    ///
    /// * a scan over a whole turn of `theta_4`: every `360 deg /` [`WRIST_SCAN_STEPS`] the pose
    ///   is fitted in least squares with `theta_4` held (the other five arm joints, continued
    ///   from the previous step). The weighted error `e` of the fit is then normal to the five
    ///   columns of the weighted Jacobian; its component `r = n . e` along the unit normal `n`
    ///   of those columns (the sign of `n` carried on from step to step, starting as the part of
    ///   the `theta_4` column normal to them) is continuous in `theta_4` and zero exactly at the
    ///   solutions. Every sign change of `r` between two steps brackets a solution, which regula
    ///   falsi on `theta_4` (fits with `theta_4` held) converges to the refinement tolerances;
    ///   this finds solutions a few degrees apart;
    /// * the solution turned by every multiple of `360 deg /` [`WRIST_RESEEDS`] (`theta_4 +
    ///   phi`, `theta_6 - k phi`) and refined as the closed-form seeds are: the curve of fits
    ///   need not stay near the singularity over a whole turn (near the shoulder singularity it
    ///   can swing to large `theta_5` before reaching the wrist-flipped solution).
    ///
    /// Each converged solution that differs from every solution already in `solutions` by more
    /// than 1e-6 rad in some arm joint (modulo a whole turn) is appended (and searched in turn;
    /// the search stops at 16 solutions, the most a 6R arm has); every appended solution
    /// reproduces `target` to the refinement tolerances.
    pub fn add_wrist_band_solutions(&self, target: &Frame, solutions: &mut Vec<JointVector>) {
        let Some(wrist) = self.arm.spherical_wrist() else {
            return;
        };
        if self.corrections == 0 {
            return;
        }
        let (theta5_offset, s45) =
            (wrist.theta_offset_rad[4], wrist.alpha_rad[3].signum() * wrist.alpha_rad[4].signum());
        let first = self.arm.first_joint() - 1;
        let band = deg_to_rad(WRIST_SCAN_BAND_DEG).sin();
        // solutions whose soft direction is still to be searched (every one in the band,
        // including those found here), and those met by a scan (their curve has been scanned)
        let mut queue: Vec<JointVector> = solutions.clone();
        let mut scanned: Vec<JointVector> = Vec::new();
        while let Some(q) = queue.pop() {
            if solutions.len() >= MAX_6R_SOLUTIONS {
                break;
            }
            let theta5 = q[first + 4] + theta5_offset;
            if theta5.sin().abs() >= band || scanned.iter().any(|p| self.same_arm_joints(p, &q, 1e-6)) {
                continue;
            }
            scanned.push(q);
            let (on_curve, other) = self.search_soft_wrist_direction(&q, theta5, s45, target);
            for (found, met) in
                on_curve.into_iter().map(|f| (f, true)).chain(other.into_iter().map(|f| (f, false)))
            {
                let found = self.wrapped(found);
                if met && !scanned.iter().any(|p| self.same_arm_joints(p, &found, 1e-6)) {
                    scanned.push(found);
                }
                if !solutions.iter().any(|p| self.same_arm_joints(p, &found, 1e-6)) {
                    solutions.push(found);
                    queue.push(found);
                }
            }
        }
    }

    /// The solutions near the solution `q` (MDH `theta_5` = `theta5`) along its soft wrist
    /// direction ([`ToolPoseIk::add_wrist_band_solutions`]): those bracketed by the scan of the
    /// curve of least-squares fits with arm joint 4 held (first), and those refined from `q`
    /// turned by a multiple of `360 deg /` [`WRIST_RESEEDS`] (second; the curve need not stay
    /// near the singularity over a whole turn, e.g. to the wrist-flipped solution).
    fn search_soft_wrist_direction(
        &self,
        q: &JointVector,
        theta5: f64,
        s45: f64,
        target: &Frame,
    ) -> (Vec<JointVector>, Vec<JointVector>) {
        let first = self.arm.first_joint() - 1;
        // theta_4 + k theta_6 is the well-determined combination (k = -1 near theta_5 = pi)
        let k = -s45 * theta5.cos().signum();
        let turn = |mut v: JointVector, by: f64| {
            v[first + 3] += by;
            v[first + 5] -= k * by;
            v
        };
        let step = std::f64::consts::TAU / WRIST_SCAN_STEPS as f64;
        // (fit, r, normal) at every step, and once more at the start after the whole turn
        let mut fits: Vec<(JointVector, f64, nalgebra::Vector6<f64>)> =
            Vec::with_capacity(WRIST_SCAN_STEPS + 1);
        let mut current = *q;
        let mut normal: Option<nalgebra::Vector6<f64>> = None;
        for _ in 0..=WRIST_SCAN_STEPS {
            let fit = self.fit_with_joint4_held(current, target, WRIST_FIT_ITERATIONS, 1e-6);
            let Some(n) = fit.normal(normal.unwrap_or(fit.j4)) else {
                break;
            };
            normal = Some(n);
            fits.push((fit.q, n.dot(&fit.e), n));
            current = turn(fit.q, step);
        }
        // the scan starts and ends at the known solution `q`: r = 0 there (up to rounding),
        // and the steps next to it bracket `q` itself
        if let Some(f) = fits.first_mut() {
            f.1 = 0.0;
        }
        if fits.len() == WRIST_SCAN_STEPS + 1 {
            fits[WRIST_SCAN_STEPS].1 = 0.0;
        }
        let mut on_curve = Vec::new();
        for w in fits.windows(2) {
            let ((a, ra, na), (_, rb, _)) = (w[0], w[1]);
            if ra == 0.0 || rb == 0.0 || (ra > 0.0) == (rb > 0.0) {
                continue;
            }
            let seed = self.wrist_root(target, (a, na), (ra, rb), step, &turn);
            if let Ok(r) = self.refine(&seed, target) {
                on_curve.push(r.q);
            }
        }
        let other = (1..WRIST_RESEEDS)
            .filter_map(|m| {
                let by = std::f64::consts::TAU * m as f64 / WRIST_RESEEDS as f64;
                self.refine(&turn(*q, by), target).ok().map(|r| r.q)
            })
            .collect();
        (on_curve, other)
    }

    /// The solution bracketed by a scan step of [`ToolPoseIk::add_wrist_band_solutions`]: the
    /// fit `a` (with its normal `na`) and the next step `step` further, with `r` values `ra`,
    /// `rb` of opposite signs. Regula falsi (Illinois) on the turn `x` in `[0, step]` from `a`
    /// (`turn(a, x)`), each `r` from a fit with arm joint 4 held, until the fit meets the
    /// refinement tolerances; returns the last fit (the refinement decides). A root search in
    /// the one soft variable, not a Newton step of the full arm: at a fold of the solution set
    /// the arm's Jacobian is nearly singular, and its quasi-Newton iteration (gravity torques held
    /// fixed, see the module docs) can stall just short of the tolerances there.
    fn wrist_root(
        &self,
        target: &Frame,
        (a, na): (JointVector, nalgebra::Vector6<f64>),
        (ra, rb): (f64, f64),
        step: f64,
        turn: &dyn Fn(JointVector, f64) -> JointVector,
    ) -> JointVector {
        let scale = self.refine.orientation_scale_mm;
        let (mut xa, mut ra, mut xb, mut rb) = (0.0, ra, step, rb);
        let mut last_side = 0;
        let mut best = turn(a, step * ra / (ra - rb));
        for _ in 0..WRIST_ROOT_ITERATIONS {
            let x = (xa * rb - xb * ra) / (rb - ra);
            let fit = self.fit_with_joint4_held(turn(a, x), target, 2 * WRIST_FIT_ITERATIONS, 1e-14);
            best = fit.q;
            let done = fit.e.fixed_rows::<3>(0).norm() <= self.refine.tol_position_mm
                && fit.e.fixed_rows::<3>(3).norm() / scale <= self.refine.tol_rotation_rad;
            let Some(n) = fit.normal(na) else {
                break;
            };
            let r = n.dot(&fit.e);
            if done || r == 0.0 || xb - xa <= f64::EPSILON * step {
                break;
            }
            if (r > 0.0) == (rb > 0.0) {
                (xb, rb) = (x, r);
                if last_side == -1 {
                    ra /= 2.0;
                }
                last_side = -1;
            } else {
                (xa, ra) = (x, r);
                if last_side == 1 {
                    rb /= 2.0;
                }
                last_side = 1;
            }
        }
        best
    }

    /// Least-squares fit of the tool pose `target` with arm joint 4 held at its value in `q`:
    /// damped Gauss–Newton steps on the other five arm joints (weighted error as in the
    /// refinement) from `q`, up to `iterations`, until a step lowers the cost by less than
    /// `rel_tol` times the cost.
    fn fit_with_joint4_held(
        &self,
        q: JointVector,
        target: &Frame,
        iterations: usize,
        rel_tol: f64,
    ) -> WristFit {
        use nalgebra::{Matrix6x5, Vector6};
        let first = self.arm.first_joint() - 1;
        let scale = self.refine.orientation_scale_mm;
        let weights = Vector6::new(1.0, 1.0, 1.0, scale, scale, scale);
        let free = [0usize, 1, 2, 4, 5];
        let error = |chain: &vatcal_kinematics::Chain| {
            let dp = target.p - chain.tool.p;
            let dr = rotation_vector(&(target.r * chain.tool.r.transpose()));
            Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z).component_mul(&weights)
        };
        let columns = |chain: &vatcal_kinematics::Chain| {
            let j = arm_tool_jacobian(chain, self.arm.first_joint());
            let mut a = Matrix6x5::zeros();
            for (c, f) in free.iter().enumerate() {
                a.set_column(c, &j.column(*f).component_mul(&weights));
            }
            (a, j.column(3).component_mul(&weights))
        };
        let mut q = q;
        let mut chain = self.model.chain(&q);
        let mut e = error(&chain);
        let mut lambda = 1e-9;
        for _ in 0..iterations {
            let (a, _) = columns(&chain);
            let jtj = a.transpose() * a;
            let jte = a.transpose() * e;
            let c0 = e.norm_squared();
            let mut improved = false;
            for _ in 0..8 {
                let mut m = jtj;
                for d in 0..5 {
                    m[(d, d)] += lambda * (1.0 + jtj[(d, d)]);
                }
                let Some(delta) = m.cholesky().map(|ch| ch.solve(&jte)) else {
                    lambda *= 10.0;
                    continue;
                };
                let mut trial = q;
                for (r, f) in free.iter().enumerate() {
                    trial[first + f] += delta[r];
                }
                let trial_chain = self.model.chain(&trial);
                let trial_e = error(&trial_chain);
                let c1 = trial_e.norm_squared();
                if c1 < c0 {
                    (q, chain, e) = (trial, trial_chain, trial_e);
                    lambda = (lambda * 0.1).max(1e-15);
                    improved = c0 - c1 > rel_tol * c0;
                    break;
                }
                lambda *= 10.0;
            }
            if !improved {
                break;
            }
        }
        let (a, j4) = columns(&chain);
        WristFit { q, e, a, j4 }
    }

    /// True when the arm joints of `a` and `b` differ by less than `tol_rad` each (modulo a
    /// whole turn) and the guide is the same.
    fn same_arm_joints(&self, a: &JointVector, b: &JointVector, tol_rad: f64) -> bool {
        let first = self.arm.first_joint() - 1;
        a.as_slice()
            .iter()
            .zip(b.as_slice())
            .enumerate()
            .all(|(j, (x, y))| if j < first { x == y } else { wrap_angle(x - y).abs() < tol_rad })
    }
}

/// A least-squares fit of the tool pose with arm joint 4 held
/// ([`ToolPoseIk::add_wrist_band_solutions`]); all vectors weighted as in the refinement.
struct WristFit {
    /// the fitted joints
    pub(super) q: JointVector,
    /// weighted error `[p* - p; log(R* R^T)]` at the fit
    pub(super) e: nalgebra::Vector6<f64>,
    /// weighted Jacobian columns of the five fitted arm joints
    pub(super) a: nalgebra::Matrix6x5<f64>,
    /// weighted Jacobian column of arm joint 4
    j4: nalgebra::Vector6<f64>,
}

impl WristFit {
    /// The unit normal of the five fitted columns closest to `near` (the part of `near` normal
    /// to them, normalised); `None` when `near` lies in their span or they are dependent.
    fn normal(&self, near: nalgebra::Vector6<f64>) -> Option<nalgebra::Vector6<f64>> {
        let ch = (self.a.transpose() * self.a).cholesky()?;
        let v = near - self.a * ch.solve(&(self.a.transpose() * near));
        let norm = v.norm();
        (norm > 1e-9 * near.norm()).then(|| v / norm)
    }
}
