//! Numerical inverse kinematics for any serial chain: damped least squares
//! (Levenberg–Marquardt) with joint limits, started from many deterministic seeds.
//!
//! The closed form of [`crate::ik`] covers the Meca500-like arm (spherical wrist). Every other
//! chain — a UR5e-class arm whose wrist axes do not intersect, a 5-axis arm, an arm on two
//! linear axes — is solved here. The code sees the chain only through [`ToolKinematics`]: the
//! tool frame and its 6×N geometric Jacobian at joint values given as a slice, so it works for
//! any joint count and does not care where the frames come from.
//!
//! # One local solve ([`solve_local`])
//! Levenberg–Marquardt on the weighted error `[p* - p; s log(R* R^T)]` (pose target, `s` =
//! [`RefineOptions::orientation_scale_mm`]) or `p* - p` of a TCP point (position target,
//! [`IkTarget::Point`]). Damping `lambda (1 + diag(J^T J))`; a step that does not lower the
//! cost raises `lambda` tenfold (12 times at most), an accepted one lowers it tenfold.
//! Bounded joints are handled by projection: a joint sitting on a bound whose step points
//! outward is frozen for that step, the others are clamped into their range. Continuous
//! joints (no limits) are free. This is the same iteration [`crate::ik::refine_tool_pose`]
//! runs on the closed-form seeds (it calls this function).
//!
//! # Multi-start ([`NumericIk`])
//! A local solve converges to the branch its start lies in, or to a local minimum that is
//! not a solution. [`NumericIk`] starts from a fixed set of seeds: a grid over the first
//! [`MultiStartOptions::grid_joints`] joints (`grid_levels` values each, the other joints at
//! the middle of their range) followed by [`MultiStartOptions::random_starts`] uniform draws
//! in the joint ranges from a ChaCha8 stream (seed [`MultiStartOptions::seed`]); continuous
//! joints use (-pi, pi]. A start whose cost has not halved
//! ([`MultiStartOptions::stall_factor`]) over the last [`MultiStartOptions::stall_iterations`]
//! steps while its position error is above 1e-3 mm is abandoned (a local minimum: on the
//! UR5e-class test arm this cuts the work per target to about 22 forward kinematics per start,
//! about what a converging start needs, while finding the same branches). The converged solutions are normalised (revolute values
//! wrapped into (-pi, pi] when the limits allow, else moved by whole turns into the limits)
//! and deduplicated: two solutions are the same when every prismatic value differs by less
//! than [`MultiStartOptions::duplicate_tol`] mm and every revolute value by less than it
//! (rad) modulo a whole turn. A target that no start reaches is reported as unreachable
//! ([`IkOutcome::is_empty`]) with the smallest residual seen.

use nalgebra::{Matrix6xX, SMatrix, SVector, Vector3, Vector6};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::Frame;

use crate::error::PlanError;
use crate::ik::{RefineOptions, rotation_vector, wrap_angle};

/// Largest joint count of the numerical IK (the workspace's `MAX_JOINTS`).
pub const MAX_IK_JOINTS: usize = 12;
/// Position error (mm) below which a start is never abandoned as stalled (it is converging).
const STALL_FLOOR_MM: f64 = 1e-3;

/// What the numerical IK needs to know about a chain: its tool frame and the tool frame's
/// geometric Jacobian at joint values `q` (internal units: mm for prismatic, rad for
/// revolute joints).
///
/// # Implementation
/// `evaluate` returns the world (or base) pose of the tool frame and whatever intermediate
/// state the Jacobian needs (e.g. the chain's frames), so that the Jacobian of an accepted
/// step does not repeat the forward kinematics. `jacobian` fills the 6×N matrix whose column
/// `k` is `[v_k; w_k]`: the velocity of the tool-frame origin and the angular velocity of the
/// tool frame per unit of joint `k` (same axes as the frame from `evaluate`), i.e.
/// `[z_k × (p - o_k); z_k]` for a revolute and `[z_k; 0]` for a prismatic joint.
pub trait ToolKinematics {
    /// Intermediate state of one evaluation, reused by [`ToolKinematics::jacobian`].
    type Eval;

    /// Number of joints (columns of the Jacobian).
    fn dof(&self) -> usize;

    /// Tool frame at `q` (`q.len() == self.dof()`), and the state for the Jacobian.
    fn evaluate(&self, q: &[f64]) -> (Frame, Self::Eval);

    /// Fills `jacobian` (6 × [`ToolKinematics::dof`]) at the `q` of `eval`.
    fn jacobian(&self, eval: &Self::Eval, jacobian: &mut Matrix6xX<f64>);
}

impl<K: ToolKinematics + ?Sized> ToolKinematics for &K {
    type Eval = K::Eval;

    fn dof(&self) -> usize {
        (**self).dof()
    }

    fn evaluate(&self, q: &[f64]) -> (Frame, K::Eval) {
        (**self).evaluate(q)
    }

    fn jacobian(&self, eval: &K::Eval, jacobian: &mut Matrix6xX<f64>) {
        (**self).jacobian(eval, jacobian)
    }
}

/// One joint as the numerical IK sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointSpec {
    /// true for a revolute joint (rad, angles wrap), false for a prismatic joint (mm)
    pub revolute: bool,
    /// lower and upper limit (internal units); `None` for a continuous revolute joint
    pub limits: Option<(f64, f64)>,
}

impl JointSpec {
    /// A revolute joint with limits (rad).
    pub fn revolute(min_rad: f64, max_rad: f64) -> Self {
        Self { revolute: true, limits: Some((min_rad, max_rad)) }
    }

    /// A continuous (unlimited) revolute joint.
    pub fn continuous() -> Self {
        Self { revolute: true, limits: None }
    }

    /// A prismatic joint with limits (mm).
    pub fn prismatic(min_mm: f64, max_mm: f64) -> Self {
        Self { revolute: false, limits: Some((min_mm, max_mm)) }
    }

    /// The range the seeds are drawn from: the limits, or (-pi, pi] for a continuous joint.
    fn seed_range(&self) -> (f64, f64) {
        self.limits.unwrap_or((-std::f64::consts::PI, std::f64::consts::PI))
    }

    /// The value clamped into the limits.
    fn clamp(&self, v: f64) -> f64 {
        match self.limits {
            Some((lo, hi)) => v.clamp(lo, hi),
            None => v,
        }
    }

    /// Normalised value: revolute values wrapped into (-pi, pi] when the limits allow it,
    /// else moved by whole turns to the representative inside the limits nearest to 0.
    pub fn normalise(&self, v: f64) -> f64 {
        if !self.revolute {
            return v;
        }
        let w = wrap_angle(v);
        let Some((lo, hi)) = self.limits else {
            return w;
        };
        let tau = std::f64::consts::TAU;
        [w, w - tau, w + tau, w - 2.0 * tau, w + 2.0 * tau]
            .into_iter()
            .find(|x| *x >= lo && *x <= hi)
            .unwrap_or(v)
    }
}

/// What the tool should reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum IkTarget {
    /// The tool frame's pose (position and orientation).
    Pose(Frame),
    /// Position only: the point `tcp_in_tool` of the tool frame (mm) at `point` (mm); for
    /// chains with fewer than six joints or when the orientation is free.
    Point {
        /// the TCP in the tool frame (mm)
        tcp_in_tool: Vector3<f64>,
        /// where it must be (mm, same frame as the tool pose)
        point: Vector3<f64>,
    },
}

/// A converged local solve.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalSolution {
    /// the joints (internal units), as the iteration left them (not normalised)
    pub q: Vec<f64>,
    /// iterations used
    pub iterations: usize,
    /// final position error (mm)
    pub position_error_mm: f64,
    /// final orientation error (rad; 0 for a point target)
    pub rotation_error_rad: f64,
}

/// Error vector of the target at a tool frame (unweighted): `[p* - p; log(R* R^T)]`, or
/// `[p* - p_tcp; 0]` for a point target (zero rows add nothing to the normal equations).
fn target_error(target: &IkTarget, tool: &Frame) -> Vector6<f64> {
    match target {
        IkTarget::Pose(t) => {
            let dp = t.p - tool.p;
            let dr = rotation_vector(&(t.r * tool.r.transpose()));
            Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
        }
        IkTarget::Point { tcp_in_tool, point } => {
            let dp = point - tool.transform_point(tcp_in_tool);
            Vector6::new(dp.x, dp.y, dp.z, 0.0, 0.0, 0.0)
        }
    }
}

/// (position error, rotation error) of an error vector.
fn error_norms(e: &Vector6<f64>) -> (f64, f64) {
    (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm())
}

/// Weighted Jacobian of the error components (rows as in [`target_error`], times the weights).
fn weighted_jacobian<const N: usize>(
    target: &IkTarget,
    tool: &Frame,
    j6: &Matrix6xX<f64>,
    weights: &Vector6<f64>,
) -> SMatrix<f64, 6, N> {
    let mut j = SMatrix::<f64, 6, N>::zeros();
    match target {
        IkTarget::Pose(_) => {
            for c in 0..N {
                for r in 0..6 {
                    j[(r, c)] = j6[(r, c)] * weights[r];
                }
            }
        }
        IkTarget::Point { tcp_in_tool, .. } => {
            // v_tcp = v + w × (R t); rows 3..6 stay zero
            let arm = tool.r * tcp_in_tool;
            for c in 0..N {
                let v = Vector3::new(j6[(0, c)], j6[(1, c)], j6[(2, c)]);
                let w = Vector3::new(j6[(3, c)], j6[(4, c)], j6[(5, c)]);
                let lin = v + w.cross(&arm);
                for r in 0..3 {
                    j[(r, c)] = lin[r] * weights[r];
                }
            }
        }
    }
    j
}

/// `(J^T J, J^T e)`, each entry summed over the rows in order (the arithmetic of nalgebra's
/// fixed-size product, so that the 6-joint refinement gives the same bits as before it was
/// made generic).
fn normal_equations<const N: usize>(
    j: &SMatrix<f64, 6, N>,
    e: &Vector6<f64>,
) -> (SMatrix<f64, N, N>, SVector<f64, N>) {
    let mut jtj = SMatrix::<f64, N, N>::zeros();
    let mut jte = SVector::<f64, N>::zeros();
    for c in 0..N {
        for r in 0..N {
            let mut acc = j[(0, r)] * j[(0, c)];
            for k in 1..6 {
                acc += j[(k, r)] * j[(k, c)];
            }
            jtj[(r, c)] = acc;
        }
        let mut acc = j[(0, c)] * e[0];
        for k in 1..6 {
            acc += j[(k, c)] * e[k];
        }
        jte[c] = acc;
    }
    (jtj, jte)
}

/// Stop rule for starts that run into a local minimum (used by the multi-start).
#[derive(Debug, Clone, Copy)]
struct Stall {
    window: usize,
    factor: f64,
}

/// Checks that the joint specs and a joint vector fit the chain.
fn check_dims<K: ToolKinematics>(kin: &K, joints: &[JointSpec], q: &[f64]) -> Result<(), PlanError> {
    let n = kin.dof();
    if n == 0 || n > MAX_IK_JOINTS || joints.len() != n || q.len() != n {
        return Err(PlanError::Option {
            option: "joints".into(),
            reason: format!(
                "the chain has {n} joints (1..={MAX_IK_JOINTS} supported), got {} joint specs and a start of {} values",
                joints.len(),
                q.len()
            ),
        });
    }
    Ok(())
}

/// One Levenberg–Marquardt solve from `seed` (see the module docs). Bounded joints are kept
/// inside their limits (the seed is clamped into them first).
///
/// # Errors
/// [`PlanError::IkNotConverged`] (with the final residual) when the tolerances of `opts` are
/// not met; [`PlanError::Option`] when `joints` or `seed` do not have [`ToolKinematics::dof`]
/// entries.
pub fn solve_local<K: ToolKinematics>(
    kin: &K,
    joints: &[JointSpec],
    seed: &[f64],
    target: &IkTarget,
    opts: &RefineOptions,
) -> Result<LocalSolution, PlanError> {
    check_dims(kin, joints, seed)?;
    levenberg_marquardt(kin, joints, seed, target, opts, None)
}

fn levenberg_marquardt<K: ToolKinematics>(
    kin: &K,
    joints: &[JointSpec],
    seed: &[f64],
    target: &IkTarget,
    opts: &RefineOptions,
    stall: Option<Stall>,
) -> Result<LocalSolution, PlanError> {
    macro_rules! dispatch {
        ($($n:literal)*) => {
            match joints.len() {
                $($n => lm::<K, $n>(kin, joints, seed, target, opts, stall),)*
                n => Err(PlanError::Option {
                    option: "joints".into(),
                    reason: format!("the numerical IK handles 1..={MAX_IK_JOINTS} joints, got {n}"),
                }),
            }
        };
    }
    dispatch!(1 2 3 4 5 6 7 8 9 10 11 12)
}

/// The iteration for `N` joints (fixed-size matrices: no allocation in the loop).
fn lm<K: ToolKinematics, const N: usize>(
    kin: &K,
    joints: &[JointSpec],
    seed: &[f64],
    target: &IkTarget,
    opts: &RefineOptions,
    stall: Option<Stall>,
) -> Result<LocalSolution, PlanError> {
    let scale = opts.orientation_scale_mm;
    let weights = Vector6::new(1.0, 1.0, 1.0, scale, scale, scale);
    let cost = |e: &Vector6<f64>| e.component_mul(&weights).norm_squared();
    let done = |e: &Vector6<f64>| {
        let (p, r) = error_norms(e);
        p <= opts.tol_position_mm && r <= opts.tol_rotation_rad
    };
    let mut q: [f64; N] = std::array::from_fn(|k| joints[k].clamp(seed[k]));
    let (mut tool, mut eval) = kin.evaluate(&q);
    let mut err = target_error(target, &tool);
    // allocated on the first iteration (an exact seed returns without one)
    let mut j6: Option<Matrix6xX<f64>> = None;
    let mut lambda = 1e-6;
    let mut history: Vec<f64> = Vec::new();
    for iteration in 0..=opts.max_iterations {
        if done(&err) {
            let (position_error_mm, rotation_error_rad) = error_norms(&err);
            return Ok(LocalSolution {
                q: q.to_vec(),
                iterations: iteration,
                position_error_mm,
                rotation_error_rad,
            });
        }
        if iteration == opts.max_iterations {
            break;
        }
        let j6 = j6.get_or_insert_with(|| Matrix6xX::zeros(N));
        kin.jacobian(&eval, j6);
        let jw = weighted_jacobian::<N>(target, &tool, j6, &weights);
        let ew = err.component_mul(&weights);
        let (jtj, jte) = normal_equations(&jw, &ew);
        let c0 = cost(&err);
        let mut improved = false;
        for _ in 0..12 {
            let mut a = jtj;
            for d in 0..N {
                a[(d, d)] += lambda * (1.0 + jtj[(d, d)]);
            }
            let Some(mut step) = a.cholesky().map(|ch| ch.solve(&jte)) else {
                lambda *= 10.0;
                continue;
            };
            // joints on a bound whose step points outward are frozen for this step
            let frozen: [bool; N] = std::array::from_fn(|k| match joints[k].limits {
                Some((lo, hi)) => (q[k] <= lo && step[k] < 0.0) || (q[k] >= hi && step[k] > 0.0),
                None => false,
            });
            if frozen.iter().any(|f| *f) {
                let mut rhs = jte;
                for k in (0..N).filter(|k| frozen[*k]) {
                    for c in 0..N {
                        a[(k, c)] = 0.0;
                        a[(c, k)] = 0.0;
                    }
                    a[(k, k)] = 1.0;
                    rhs[k] = 0.0;
                }
                let Some(s) = a.cholesky().map(|ch| ch.solve(&rhs)) else {
                    lambda *= 10.0;
                    continue;
                };
                step = s;
            }
            let trial: [f64; N] = std::array::from_fn(|k| joints[k].clamp(q[k] + step[k]));
            let (t_tool, t_eval) = kin.evaluate(&trial);
            let trial_err = target_error(target, &t_tool);
            let c1 = cost(&trial_err);
            if c1 < c0 || done(&trial_err) {
                q = trial;
                err = trial_err;
                tool = t_tool;
                eval = t_eval;
                lambda = (lambda * 0.1).max(1e-15);
                improved = true;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
        if let Some(s) = stall {
            let c = cost(&err);
            history.push(c);
            let k = history.len();
            if k > s.window
                && c > s.factor * history[k - 1 - s.window]
                && err.fixed_rows::<3>(0).norm() > STALL_FLOOR_MM
            {
                break;
            }
        }
    }
    let (position_error_mm, rotation_error_rad) = error_norms(&err);
    Err(PlanError::IkNotConverged { position_error_mm, rotation_error_rad })
}

/// Options of the multi-start numerical IK.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultiStartOptions {
    /// number of leading joints the start grid spans
    pub grid_joints: usize,
    /// grid values per grid joint (centres of equal parts of the range); 0 = no grid
    pub grid_levels: usize,
    /// random starts after the grid
    pub random_starts: usize,
    /// seed of the random starts (ChaCha8)
    pub seed: u64,
    /// a start is abandoned as stuck in a local minimum when its cost is still above
    /// `stall_factor` times its cost `stall_iterations` steps earlier (and its position error
    /// above 1e-3 mm)
    pub stall_iterations: usize,
    /// see `stall_iterations` (0..1; 0 never abandons)
    pub stall_factor: f64,
    /// two solutions closer than this (rad for revolute, mm for prismatic joints, revolute
    /// modulo a whole turn) in every joint are the same
    pub duplicate_tol: f64,
    /// options of each local solve (tolerances, iteration budget, orientation weight)
    pub refine: RefineOptions,
}

impl Default for MultiStartOptions {
    fn default() -> Self {
        Self {
            grid_joints: 3,
            grid_levels: 2,
            random_starts: 48,
            seed: 1,
            stall_iterations: 4,
            stall_factor: 0.5,
            duplicate_tol: 1e-6,
            refine: RefineOptions { max_iterations: 100, ..RefineOptions::default() },
        }
    }
}

/// Result of a multi-start solve.
#[derive(Debug, Clone, PartialEq)]
pub struct IkOutcome {
    /// distinct solutions (normalised, see the module docs), in the order found
    pub solutions: Vec<LocalSolution>,
    /// smallest position error reached by any start (mm); 0-ish when reachable
    pub best_position_error_mm: f64,
    /// orientation error of that start (rad)
    pub best_rotation_error_rad: f64,
    /// starts run
    pub starts: usize,
}

impl IkOutcome {
    /// True when no start reached the target (unreachable, or missed by every start).
    pub fn is_empty(&self) -> bool {
        self.solutions.is_empty()
    }

    /// The joint vectors of the solutions.
    pub fn joints(&self) -> impl Iterator<Item = &[f64]> {
        self.solutions.iter().map(|s| s.q.as_slice())
    }
}

/// Multi-start numerical IK of one chain (see the module docs); `K` may be a reference.
///
/// # Examples
/// A planar two-link arm (links of 100 mm) reaching a point with both elbows:
/// ```
/// use nalgebra::{Matrix6xX, Vector3};
/// use vatcal_core::Frame;
/// use vatcal_core::frame::rot_z;
/// use vatcal_planning::numeric_ik::{IkTarget, JointSpec, MultiStartOptions, NumericIk, ToolKinematics};
///
/// struct Planar2R;
///
/// impl ToolKinematics for Planar2R {
///     type Eval = [f64; 2];
///     fn dof(&self) -> usize {
///         2
///     }
///     fn evaluate(&self, q: &[f64]) -> (Frame, [f64; 2]) {
///         let (a, b) = (q[0], q[0] + q[1]);
///         let p = Vector3::new(100.0 * (a.cos() + b.cos()), 100.0 * (a.sin() + b.sin()), 0.0);
///         (Frame { r: rot_z(b), p }, [a, b])
///     }
///     fn jacobian(&self, &[a, b]: &[f64; 2], j: &mut Matrix6xX<f64>) {
///         j.fill(0.0);
///         j[(0, 0)] = -100.0 * (a.sin() + b.sin());
///         j[(1, 0)] = 100.0 * (a.cos() + b.cos());
///         j[(0, 1)] = -100.0 * b.sin();
///         j[(1, 1)] = 100.0 * b.cos();
///         j[(5, 0)] = 1.0;
///         j[(5, 1)] = 1.0;
///     }
/// }
///
/// let joints = [JointSpec::continuous(), JointSpec::revolute(-3.0, 3.0)];
/// let ik = NumericIk::new(Planar2R, &joints, MultiStartOptions::default())?;
/// let target = IkTarget::Point { tcp_in_tool: Vector3::zeros(), point: Vector3::new(120.0, 70.0, 0.0) };
/// let out = ik.solve(&target);
/// assert_eq!(out.solutions.len(), 2); // elbow up and elbow down
/// for q in out.joints() {
///     let (tool, _) = Planar2R.evaluate(q);
///     assert!((tool.p - Vector3::new(120.0, 70.0, 0.0)).norm() < 1e-9);
/// }
/// // out of reach: no solution, and the closest miss is reported
/// let far = IkTarget::Point { tcp_in_tool: Vector3::zeros(), point: Vector3::new(250.0, 0.0, 0.0) };
/// let out = ik.solve(&far);
/// assert!(out.is_empty() && (out.best_position_error_mm - 50.0).abs() < 1e-6);
/// # Ok::<(), vatcal_planning::PlanError>(())
/// ```
///
/// # Errors
/// [`NumericIk::new`] rejects mismatched joint counts, bad limits and empty start sets;
/// [`NumericIk::solve`] never fails (an unreachable target gives an empty [`IkOutcome`]).
#[derive(Debug, Clone)]
pub struct NumericIk<K> {
    kin: K,
    joints: Vec<JointSpec>,
    starts: Vec<Vec<f64>>,
    opts: MultiStartOptions,
}

impl<K: ToolKinematics> NumericIk<K> {
    /// The solver for `kin` with joints `joints` (one per [`ToolKinematics::dof`]).
    ///
    /// # Errors
    /// [`PlanError::Option`] when the joint count does not match, a limit is not finite or
    /// reversed, a prismatic joint has no limits (its starts need a range), or there are no
    /// starts (`grid_levels == 0` and `random_starts == 0`).
    pub fn new(kin: K, joints: &[JointSpec], opts: MultiStartOptions) -> Result<Self, PlanError> {
        let n = kin.dof();
        check_dims(&kin, joints, &vec![0.0; joints.len()])?;
        for (k, j) in joints.iter().enumerate() {
            match j.limits {
                Some((lo, hi)) if !(lo.is_finite() && hi.is_finite() && lo <= hi) => {
                    return Err(PlanError::Option {
                        option: format!("joint {} limits", k + 1),
                        reason: format!("need finite min <= max, got {lo}..{hi}"),
                    });
                }
                None if !j.revolute => {
                    return Err(PlanError::Option {
                        option: format!("joint {} limits", k + 1),
                        reason: "a prismatic joint needs limits (its starts are drawn from them)".into(),
                    });
                }
                _ => {}
            }
        }
        let grid_joints = if opts.grid_levels == 0 { 0 } else { opts.grid_joints.min(n) };
        let grid_count = if grid_joints == 0 { 0 } else { opts.grid_levels.pow(grid_joints as u32) };
        if grid_count + opts.random_starts == 0 {
            return Err(PlanError::Option {
                option: "random_starts".into(),
                reason: "no starts: give random_starts > 0 or a grid".into(),
            });
        }
        let mid: Vec<f64> = joints
            .iter()
            .map(|j| {
                let (lo, hi) = j.seed_range();
                0.5 * (lo + hi)
            })
            .collect();
        let mut starts = Vec::with_capacity(grid_count + opts.random_starts);
        for cell in 0..grid_count {
            let mut q = mid.clone();
            let mut rest = cell;
            for (k, v) in q.iter_mut().enumerate().take(grid_joints) {
                let level = rest % opts.grid_levels;
                rest /= opts.grid_levels;
                let (lo, hi) = joints[k].seed_range();
                *v = lo + (hi - lo) * (level as f64 + 0.5) / opts.grid_levels as f64;
            }
            starts.push(q);
        }
        let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
        for _ in 0..opts.random_starts {
            starts.push(
                joints
                    .iter()
                    .map(|j| {
                        let (lo, hi) = j.seed_range();
                        if hi > lo { rng.random_range(lo..hi) } else { lo }
                    })
                    .collect(),
            );
        }
        Ok(Self { kin, joints: joints.to_vec(), starts, opts })
    }

    /// The starts, in the order they are tried.
    pub fn starts(&self) -> &[Vec<f64>] {
        &self.starts
    }

    /// The joints.
    pub fn joints(&self) -> &[JointSpec] {
        &self.joints
    }

    /// The chain.
    pub fn kinematics(&self) -> &K {
        &self.kin
    }

    /// Every solution for `target` reached from the starts (see the module docs). Never
    /// fails: an unreachable target gives an empty outcome with the smallest residual seen.
    pub fn solve(&self, target: &IkTarget) -> IkOutcome {
        self.solve_from(target, &[])
    }

    /// Like [`NumericIk::solve`], trying `extra_starts` (e.g. the solutions of a neighbouring
    /// target) before the fixed starts. Extra starts of the wrong length are skipped.
    pub fn solve_from(&self, target: &IkTarget, extra_starts: &[&[f64]]) -> IkOutcome {
        self.solve_warm(target, extra_starts, 0)
    }

    /// A warm-started solve: `warm_starts` (e.g. the solutions of a neighbouring target, or of
    /// the same target at the previous guide step) are tried first, then the fixed starts, and
    /// the search stops as soon as `enough` distinct solutions are found (0: never early, as
    /// [`NumericIk::solve_from`]). With `enough` = the neighbour's number of solutions, a
    /// target next to a solved one costs one short local solve per branch instead of every
    /// start: each neighbouring solution converges in a few steps to the same branch of this
    /// target, and the fixed starts run only when some branch was lost (two warm starts on one
    /// solution, or one that did not converge). A branch the neighbour did not have is found
    /// only when the fixed starts run. Warm starts of the wrong length are skipped.
    pub fn solve_warm(&self, target: &IkTarget, warm_starts: &[&[f64]], enough: usize) -> IkOutcome {
        let mut out = IkOutcome {
            solutions: Vec::new(),
            best_position_error_mm: f64::INFINITY,
            best_rotation_error_rad: f64::INFINITY,
            starts: 0,
        };
        let stall = Some(Stall { window: self.opts.stall_iterations.max(1), factor: self.opts.stall_factor });
        let n = self.joints.len();
        let fixed = self.starts.iter().map(Vec::as_slice);
        for start in warm_starts.iter().copied().filter(|s| s.len() == n).chain(fixed) {
            if enough > 0 && out.solutions.len() >= enough {
                break;
            }
            out.starts += 1;
            let result =
                levenberg_marquardt(&self.kin, &self.joints, start, target, &self.opts.refine, stall);
            let (p, r) = match &result {
                Ok(s) => (s.position_error_mm, s.rotation_error_rad),
                Err(PlanError::IkNotConverged { position_error_mm, rotation_error_rad }) => {
                    (*position_error_mm, *rotation_error_rad)
                }
                Err(_) => continue,
            };
            if p + r * self.opts.refine.orientation_scale_mm
                < out.best_position_error_mm
                    + out.best_rotation_error_rad * self.opts.refine.orientation_scale_mm
                || !out.best_position_error_mm.is_finite()
            {
                out.best_position_error_mm = p;
                out.best_rotation_error_rad = r;
            }
            let Ok(mut solution) = result else {
                continue;
            };
            for (v, j) in solution.q.iter_mut().zip(&self.joints) {
                *v = j.normalise(*v);
            }
            if !out.solutions.iter().any(|s| self.same(&s.q, &solution.q)) {
                out.solutions.push(solution);
            }
        }
        out
    }

    /// True when two joint vectors are the same solution (see [`MultiStartOptions::duplicate_tol`]).
    pub fn same(&self, a: &[f64], b: &[f64]) -> bool {
        same_solution(&self.joints, a, b, self.opts.duplicate_tol)
    }
}

/// True when `a` and `b` differ by less than `tol` in every joint, revolute joints modulo a
/// whole turn (rad for revolute, mm for prismatic joints).
pub fn same_solution(joints: &[JointSpec], a: &[f64], b: &[f64], tol: f64) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).zip(joints).all(|((x, y), j)| {
            let d = if j.revolute { wrap_angle(x - y) } else { x - y };
            d.abs() < tol
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::frame::rot_z;

    /// Planar 2R arm (links 1 and 1 along x), tool frame at the tip.
    struct Planar2R;

    impl ToolKinematics for Planar2R {
        type Eval = [f64; 2];
        fn dof(&self) -> usize {
            2
        }
        fn evaluate(&self, q: &[f64]) -> (Frame, [f64; 2]) {
            let (a, b) = (q[0], q[0] + q[1]);
            let p = Vector3::new(a.cos() + b.cos(), a.sin() + b.sin(), 0.0);
            (Frame { r: rot_z(b), p }, [q[0], q[1]])
        }
        fn jacobian(&self, q: &[f64; 2], j: &mut Matrix6xX<f64>) {
            let (a, b) = (q[0], q[0] + q[1]);
            j.fill(0.0);
            j[(0, 0)] = -a.sin() - b.sin();
            j[(1, 0)] = a.cos() + b.cos();
            j[(0, 1)] = -b.sin();
            j[(1, 1)] = b.cos();
            j[(5, 0)] = 1.0;
            j[(5, 1)] = 1.0;
        }
    }

    #[test]
    fn planar_point_target_has_both_elbows() {
        let joints = [JointSpec::continuous(), JointSpec::continuous()];
        let ik = NumericIk::new(&Planar2R, &joints, MultiStartOptions::default()).expect("ik");
        let target = IkTarget::Point { tcp_in_tool: Vector3::zeros(), point: Vector3::new(1.2, 0.7, 0.0) };
        let out = ik.solve(&target);
        assert_eq!(out.solutions.len(), 2, "{:?}", out.solutions);
        let elbows: Vec<f64> = out.joints().map(|q| q[1].signum()).collect();
        assert!(elbows.contains(&1.0) && elbows.contains(&-1.0));
    }

    #[test]
    fn limits_keep_one_elbow_and_unreachable_is_empty() {
        let joints = [JointSpec::continuous(), JointSpec::revolute(0.0, 3.0)];
        let ik = NumericIk::new(&Planar2R, &joints, MultiStartOptions::default()).expect("ik");
        let target = IkTarget::Point { tcp_in_tool: Vector3::zeros(), point: Vector3::new(1.2, 0.7, 0.0) };
        let out = ik.solve(&target);
        assert_eq!(out.solutions.len(), 1);
        assert!(out.solutions[0].q[1] > 0.0);
        let far = IkTarget::Point { tcp_in_tool: Vector3::zeros(), point: Vector3::new(2.5, 0.0, 0.0) };
        let out = ik.solve(&far);
        assert!(out.is_empty());
        assert!((out.best_position_error_mm - 0.5).abs() < 1e-6, "{}", out.best_position_error_mm);
    }

    #[test]
    fn mismatched_dimensions_are_errors() {
        let joints = [JointSpec::continuous()];
        assert!(NumericIk::new(&Planar2R, &joints, MultiStartOptions::default()).is_err());
        let two = [JointSpec::continuous(); 2];
        let t = IkTarget::Point { tcp_in_tool: Vector3::zeros(), point: Vector3::zeros() };
        assert!(solve_local(&Planar2R, &two, &[0.0], &t, &RefineOptions::default()).is_err());
        let unlimited_prismatic = [JointSpec::continuous(), JointSpec { revolute: false, limits: None }];
        assert!(NumericIk::new(&Planar2R, &unlimited_prismatic, MultiStartOptions::default()).is_err());
    }

    #[test]
    fn normalise_respects_limits() {
        let wide = JointSpec::revolute(-6.0, 6.0);
        assert!((wide.normalise(5.0) - (5.0 - std::f64::consts::TAU)).abs() < 1e-12);
        let high = JointSpec::revolute(3.0, 9.0);
        let v = high.normalise(8.0);
        assert!((3.0..=9.0).contains(&v) && (wrap_angle(v - 8.0)).abs() < 1e-12, "{v}");
    }
}
