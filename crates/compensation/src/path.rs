//! Compensation of one pose and of a path.

use std::f64::consts::TAU;

use nalgebra::Vector3;
use vatcal_core::frame::{rot_x, rot_y};
use vatcal_core::{Frame, JointVector, MeasurementContext, rad_to_deg};
use vatcal_kinematics::Model;
use vatcal_planning::PlanError;
use vatcal_planning::ik::{ArmGeometry, ChainTool, ModelIk, RefineOptions, ToolPoseIk, robot_base_frame};
use vatcal_planning::numeric_ik::{IkTarget, JointSpec, MultiStartOptions, NumericIk};

use crate::solve::{Branch, JointSplit, NotConverged, SolveOptions, Solved, newton};
use crate::{CompensationError, PoseRequest, ToolTarget, frame_to_meca_pose};

/// Options of a path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathOptions {
    /// solver tolerances
    pub solve: SolveOptions,
    /// report unreachable rows (out of reach, joint limits, branch change, joint jump) as
    /// skips instead of failing
    pub skip_unreachable: bool,
    /// largest change of an arm joint between consecutive solved rows \[deg\]
    pub max_joint_step_deg: f64,
    /// seed of the first row: its solution from this seed fixes the path's branch
    pub start: Option<JointVector>,
    /// the branch the path must use (when `start` is not given or does not converge);
    /// `None`: the first row's solution inside the limits with the largest clearance. On a
    /// numerical-IK chain, [`Branch::DET_POSITIVE`] or [`Branch::DET_NEGATIVE`]
    pub branch: Option<Branch>,
}

impl Default for PathOptions {
    /// Default solver, no skipping, at most 30° per joint between rows, branch chosen on the
    /// first row.
    fn default() -> Self {
        Self {
            solve: SolveOptions::default(),
            skip_unreachable: false,
            max_joint_step_deg: 30.0,
            start: None,
            branch: None,
        }
    }
}

impl PathOptions {
    fn check(&self) -> Result<(), CompensationError> {
        if !(self.max_joint_step_deg.is_finite() && self.max_joint_step_deg > 0.0) {
            return Err(CompensationError::Option {
                option: "max_joint_step_deg",
                reason: format!("must be a positive angle, got {}", self.max_joint_step_deg),
            });
        }
        Ok(())
    }
}

/// The compensated joint targets of one pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Compensated {
    /// joint targets under the calibrated model (given joints as requested)
    pub q: JointVector,
    /// IK branch of the solution
    pub branch: Branch,
    /// predicted residual of the calibrated model at `q`: tool-frame position error \[mm\]
    pub position_residual_mm: f64,
    /// ... and orientation error \[rad\]
    pub rotation_residual_rad: f64,
    /// Newton iterations used (last solve)
    pub iterations: usize,
}

/// A row left out by a path in skip mode.
#[derive(Debug)]
pub struct SkippedRow {
    /// 0-based row index
    pub row: usize,
    /// why
    pub error: CompensationError,
}

/// What happened to one row of a path.
#[derive(Debug)]
pub enum RowOutcome {
    /// solved
    Solved(Compensated),
    /// skipped (skip mode only)
    Skipped(SkippedRow),
}

/// A compensated path.
#[derive(Debug)]
pub struct PathResult {
    /// one outcome per requested row, in order
    pub rows: Vec<RowOutcome>,
    /// the branch of the path (`None` when no row was solved)
    pub branch: Option<Branch>,
}

impl PathResult {
    /// The solved rows as `(row, solution)`.
    pub fn solved(&self) -> impl Iterator<Item = (usize, &Compensated)> {
        self.rows.iter().enumerate().filter_map(|(k, r)| match r {
            RowOutcome::Solved(c) => Some((k, c)),
            RowOutcome::Skipped(_) => None,
        })
    }

    /// The skipped rows.
    pub fn skipped(&self) -> impl Iterator<Item = &SkippedRow> {
        self.rows.iter().filter_map(|r| match r {
            RowOutcome::Skipped(s) => Some(s),
            RowOutcome::Solved(_) => None,
        })
    }
}

/// Seed of the next row of a dense path: the previous solution extrapolated from the ones
/// before it (quadratically from three rows, linearly from two; the joints of a print path are
/// smooth), unless a step is large (then the previous solution itself).
fn predicted_seed(
    free: &[usize; 6],
    prev: &JointVector,
    before: Option<&JointVector>,
    before2: Option<&JointVector>,
    max_step_rad: f64,
) -> JointVector {
    let Some(b) = before else { return *prev };
    let mut seed = *prev;
    for &k in free {
        let d = prev[k] - b[k];
        if d.abs() > 0.5 * max_step_rad {
            return *prev;
        }
        seed[k] += match before2 {
            // q(t+1) = 3 q(t) - 3 q(t-1) + q(t-2)
            Some(b2) => 2.0 * d - (b[k] - b2[k]),
            None => d,
        };
    }
    seed
}

/// What the robot's own controller must be sent for compensated joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrectedPose {
    /// `FK_nominal(q)` in the request format (world frame, the nominal model's TCP)
    pub world: PoseRequest,
    /// the flange (last frame) in the robot's base frame as the nominal Meca500 controller
    /// computes it: `MovePose` arguments `[x, y, z (mm), α, β, γ (deg)]` with WRF = TRF =
    /// identity; `None` when the nominal chain is not a Meca500 arm
    /// ([`Compensator::meca500_arm`])
    pub controller_pose: Option<[f64; 6]>,
    /// `MoveJoints` arguments: the Meca500 joints J1..J6 \[deg\] (cell joints q2..q7 on the
    /// canonical cell); `None` when the nominal chain is not a Meca500 arm
    pub controller_joints_deg: Option<[f64; 6]>,
}

/// Where the IK solutions of the first row (and of a row whose warm start fails) come from.
#[derive(Debug)]
enum Seeder<'a> {
    /// The canonical cell: the closed-form branches of the Meca500 arm.
    ClosedForm { ik: Box<ToolPoseIk<'a>>, arm: Box<ArmGeometry> },
    /// Any other chain whose given joints are what [`ModelIk`] holds (none, or its guide).
    ModelIk(ModelIk<'a>),
    /// Any other chain: multi-start numerical IK of the solved joints.
    Numeric(MultiStartOptions),
}

/// Compensation under a calibrated model, with the nominal model of the robot controller.
///
/// On the canonical Meca500-on-guide cell the IK seeds are the closed-form branches of the
/// Meca500 arm; on any other chain of 6 or more joints (see [`JointSplit`] for which joints
/// a request gives) they come from `vatcal_planning::ik::ModelIk` (its closed form when the
/// arm has one, else the multi-start numerical IK), and the path's branch is the sign of
/// `det J` ([`Branch`]).
#[derive(Debug)]
pub struct Compensator<'a> {
    calibrated: &'a Model,
    nominal: &'a Model,
    split: JointSplit,
    seeder: Seeder<'a>,
    /// first joint (1-based) of the nominal chain's last six joints when they are a Meca500 arm
    meca500_arm: Option<usize>,
}

/// Joint configurations (degrees) at which a chain's last six joints are compared with the
/// Meca500 controller's kinematics.
const MECA500_TEST_DEG: [[f64; 6]; 3] =
    [[30.0, 20.0, -40.0, 50.0, 60.0, -70.0], [-100.0, -50.0, 30.0, -120.0, -20.0, 150.0], [0.0; 6]];

/// The robot base frame of the last six joints of `chain` (first of them `k0`, 1-based): the
/// frame before row `k0` times the fixed part `Rx(α) Tx(a) Ry(β)` of that row.
fn arm_base_frame(model: &Model, chain: &vatcal_kinematics::Chain, k0: usize) -> Frame {
    let row = model.row(k0);
    let fixed = Frame { r: rot_x(row.alpha) * rot_y(row.beta), p: Vector3::new(row.a, 0.0, 0.0) };
    chain.frames[k0 - 1].compose(&fixed)
}

/// The first of the last six joints (1-based) when they are revolute and move the flange, in
/// their base frame, as the Meca500 controller's nominal kinematics do (to 1e-6 mm and 1e-9
/// rad at three configurations), else `None`.
fn meca500_arm_of(model: &Model) -> Option<usize> {
    let n = model.joint_count();
    if n < 6 || !model.joint_kinds()[n - 6..].iter().all(|k| k.is_revolute()) {
        return None;
    }
    let k0 = n - 5;
    let matches = MECA500_TEST_DEG.iter().all(|deg| {
        let mut q = JointVector::zeros(n);
        for (k, d) in deg.iter().enumerate() {
            q[k0 - 1 + k] = d.to_radians();
        }
        let chain = model.chain(&q);
        let flange = arm_base_frame(model, &chain, k0).inverse().compose(&chain.frames[n]);
        let controller = crate::meca_pose_to_frame(&vatcal_drivers_meca500::sim::to_xyzabc(
            &vatcal_drivers_meca500::sim::forward_kinematics(deg),
        ));
        (flange.p - controller.p).norm() < 1e-6
            && vatcal_planning::ik::rotation_angle_between(&flange.r, &controller.r) < 1e-9
    });
    matches.then_some(k0)
}

impl<'a> Compensator<'a> {
    /// A compensator for `calibrated` (the model the cell really follows) and `nominal` (the
    /// model the robot controller uses, for [`Compensator::corrected_pose`]).
    ///
    /// # Errors
    /// [`CompensationError::UnsupportedChain`] for a chain of fewer than six joints, more than
    /// six joints whose prismatic joints do not leave six to solve ([`JointSplit::of`]), or a
    /// nominal model with other joints than the calibrated one; [`CompensationError::Model`]
    /// when the calibrated model is the canonical cell and the nominal one is not;
    /// [`CompensationError::Plan`] for invalid numerical-IK limits.
    pub fn new(calibrated: &'a Model, nominal: &'a Model) -> Result<Self, CompensationError> {
        let split = JointSplit::of(calibrated)?;
        if calibrated.is_meca500_on_guide()
            && let Ok(ik) = ToolPoseIk::new(calibrated, RefineOptions::default())
        {
            nominal.require_meca500_on_guide("compensation's Meca500 output")?;
            let arm = *ik.arm();
            return Ok(Self {
                calibrated,
                nominal,
                split,
                seeder: Seeder::ClosedForm { ik: Box::new(ik), arm: Box::new(arm) },
                meca500_arm: Some(2),
            });
        }
        if nominal.joint_kinds() != calibrated.joint_kinds() {
            return Err(CompensationError::UnsupportedChain {
                chain: calibrated.describe_chain(),
                reason: format!(
                    "the nominal (controller) model is another chain: {}",
                    nominal.describe_chain()
                ),
            });
        }
        let prismatic: Vec<usize> =
            (1..=calibrated.joint_count()).filter(|i| !calibrated.is_revolute(*i)).collect();
        let given: Vec<usize> = split.given_joints().collect();
        let seeder = if prismatic == given && given.len() <= 1 {
            Seeder::ModelIk(ModelIk::new(calibrated, RefineOptions::default(), MultiStartOptions::default())?)
        } else {
            // validate the limits once (NumericIk is built per target)
            numeric_ik(
                calibrated,
                &split,
                JointVector::zeros(calibrated.joint_count()),
                &MultiStartOptions::default(),
            )?;
            Seeder::Numeric(MultiStartOptions::default())
        };
        Ok(Self { calibrated, nominal, split, seeder, meca500_arm: meca500_arm_of(nominal) })
    }

    /// Which joints a request gives and which are solved for.
    pub fn split(&self) -> &JointSplit {
        &self.split
    }

    /// True on the canonical cell (closed-form Meca500 branches 0..=7); false when the branch
    /// is the sign of `det J` ([`Branch`]).
    pub fn is_closed_form(&self) -> bool {
        matches!(self.seeder, Seeder::ClosedForm { .. })
    }

    /// The first joint (1-based) of the nominal chain's last six joints when they are a
    /// Meca500 arm (its controller's kinematics, e.g. joint 2 on the canonical cell, joint 1
    /// for a Meca500 on a table): the chains `--emit meca500` programs exist for.
    pub fn meca500_arm(&self) -> Option<usize> {
        self.meca500_arm
    }

    /// The calibrated model.
    pub fn calibrated(&self) -> &'a Model {
        self.calibrated
    }

    /// The nominal (controller) model.
    pub fn nominal(&self) -> &'a Model {
        self.nominal
    }

    /// The branch of joints `q` (without context).
    pub fn branch_of(&self, q: &JointVector) -> Branch {
        self.branch_at(q, &MeasurementContext::default())
    }

    /// The branch of joints `q` under the calibrated model with `context`.
    fn branch_at(&self, q: &JointVector, context: &MeasurementContext) -> Branch {
        match &self.seeder {
            Seeder::ClosedForm { arm, .. } => Branch::of(arm, q),
            _ => {
                let chain = self.calibrated.chain_full(q, context, false, None);
                Branch::of_determinant(self.split.jacobian(&chain).determinant())
            }
        }
    }

    /// IK seeds of `target` (full joint vectors, given joints as requested) without the
    /// context: closed-form branches on the canonical cell, `ModelIk` or the multi-start
    /// numerical IK otherwise.
    fn seeds(&self, target: &ToolTarget) -> Vec<JointVector> {
        match &self.seeder {
            Seeder::ClosedForm { ik, .. } => {
                let q1 = target.given[0];
                let base = robot_base_frame(self.calibrated, q1);
                ik.seeds(q1, &base, &target.tool).into_iter().map(|s| s.q).collect()
            }
            Seeder::ModelIk(ik) => {
                let guide = ik.guide_joint().map_or(0.0, |g| target.given.get(g));
                ik.solve_at_guide(guide, &target.tool)
            }
            Seeder::Numeric(opts) => match numeric_ik(self.calibrated, &self.split, target.given, opts) {
                Ok(ik) => {
                    let out = ik.solve(&IkTarget::Pose(target.tool));
                    out.joints().map(|q| ik.kinematics().joints(q)).collect()
                }
                Err(_) => Vec::new(),
            },
        }
    }

    /// Every solution of `target` under the calibrated model (IK seeds refined with the
    /// context), revolute joints wrapped into (−180°, 180°] (on another chain than the
    /// canonical cell: where the limits allow), inside or outside the joint limits.
    pub fn all_solutions(&self, target: &ToolTarget, opts: &SolveOptions) -> Vec<(Branch, Solved)> {
        let mut out: Vec<(Branch, Solved)> = Vec::with_capacity(8);
        for seed in self.seeds(target) {
            let Ok(s) = newton(self.calibrated, &self.split, target, &seed, opts) else { continue };
            let Ok(s) = self.wrapped(target, s, opts) else { continue };
            let branch = self.branch_at(&s.q, &target.context);
            let same = |o: &(Branch, Solved)| {
                o.1.q.as_slice().iter().zip(s.q.as_slice()).all(|(a, b)| (a - b).abs() < 1e-7)
            };
            if !out.iter().any(same) {
                out.push((branch, s));
            }
        }
        out
    }

    /// `s` with its arm joints wrapped into (−π, π], re-solved when that moved a joint (joint
    /// effects depend on the joint value itself, not only modulo 2π).
    fn wrapped(&self, target: &ToolTarget, s: Solved, opts: &SolveOptions) -> Result<Solved, NotConverged> {
        let mut q = s.q;
        let mut moved = false;
        let closed_form = self.is_closed_form();
        for (slot, &k) in self.split.free().iter().enumerate() {
            if !self.split.free_revolute(slot) {
                continue;
            }
            let v = q[k];
            let w = vatcal_planning::ik::wrap_angle(v);
            let allowed = closed_form
                || self.calibrated.joint_limit(k + 1).is_none_or(|(lo, hi)| (lo..=hi).contains(&w));
            if allowed {
                moved |= w != v;
                q[k] = w;
            }
        }
        if moved { newton(self.calibrated, &self.split, target, &q, opts) } else { Ok(s) }
    }

    /// Compensates one pose. With `seed`, Newton from it (the solution nearest the seed, e.g.
    /// the previous pose of a path); without, the solution inside the joint limits with the
    /// largest clearance among all branches. The result is inside the joint limits.
    ///
    /// # Examples
    /// The joints that put TCP 2 on a world point under a calibrated model (here a stand-in: the
    /// nominal cell with realistic errors), checked by forward kinematics of that model:
    /// ```
    /// use vatcal_compensation::{Compensator, PoseRequest, SolveOptions};
    /// use vatcal_core::{CellFile, MeasurementContext};
    /// use vatcal_kinematics::Model;
    /// use vatcal_sim::truth::{ErrorBudget, perturbed_truth};
    ///
    /// let nominal = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
    /// let calibrated = perturbed_truth(&nominal, 4, &ErrorBudget::realistic());
    /// // TCP 2 at (60, -40, 40) mm, tool z down, the guide at 100 mm
    /// let request = PoseRequest::on_guide(2, 100.0, [60.0, -40.0, 40.0], [180.0, 0.0, 0.0]);
    /// let compensator = Compensator::new(&calibrated, &nominal)?;
    /// let c = compensator.compensate_pose(&request, None, &SolveOptions::default())?;
    /// let p = calibrated.tcp_position(&c.q, 2)?;
    /// assert!((p - nalgebra::Vector3::from(request.xyz_mm)).norm() < 1e-6);
    /// assert!(calibrated.limit_violation(&c.q).is_none());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`CompensationError::NonFinite`] or [`CompensationError::Model`] for a bad request (a value
    /// that is not finite, an unknown TCP); [`CompensationError::Unreachable`] when no branch reaches
    /// the pose; [`CompensationError::JointLimit`] when every solution leaves the joint limits.
    pub fn compensate_pose(
        &self,
        request: &PoseRequest,
        seed: Option<&JointVector>,
        opts: &SolveOptions,
    ) -> Result<Compensated, CompensationError> {
        let target = request.tool_target(self.calibrated, 0)?;
        let path_opts = PathOptions { solve: *opts, start: seed.copied(), ..PathOptions::default() };
        let mut result = self.compensate_path(&[target], &path_opts)?;
        match result.rows.pop() {
            Some(RowOutcome::Solved(c)) => Ok(c),
            Some(RowOutcome::Skipped(s)) => Err(s.error),
            None => Err(CompensationError::Unreachable { row: 0, reason: "no solution".into() }),
        }
    }

    /// Converts `requests` to tool targets under the calibrated model and compensates them as
    /// a path ([`Compensator::compensate_path`]). A request with an unknown TCP or a non-finite
    /// value is an error even in skip mode (bad input, not an unreachable pose).
    ///
    /// # Errors
    /// [`CompensationError::NonFinite`] or [`CompensationError::Model`] for a bad request (its
    /// row named); otherwise as [`Compensator::compensate_path`].
    pub fn compensate_requests(
        &self,
        requests: &[PoseRequest],
        opts: &PathOptions,
    ) -> Result<PathResult, CompensationError> {
        let targets = requests
            .iter()
            .enumerate()
            .map(|(row, r)| r.tool_target(self.calibrated, row))
            .collect::<Result<Vec<_>, _>>()?;
        self.compensate_path(&targets, opts)
    }

    /// Compensates a path: every row on the same IK branch, seeded from the previous solved
    /// row (joints move continuously, no wrapping after the first row). A row fails when no
    /// solution of the path's branch converges ([`CompensationError::Unreachable`], or
    /// [`CompensationError::BranchChange`] when another branch reaches it), when its solution
    /// leaves the joint limits, or when a joint jumps by more than
    /// [`PathOptions::max_joint_step_deg`]. In skip mode such a row is reported and the path
    /// continues from the last solved row.
    ///
    /// # Errors
    /// [`CompensationError::Option`] for invalid options; without
    /// [`PathOptions::skip_unreachable`], the first failing row's
    /// [`CompensationError::Unreachable`], [`CompensationError::BranchChange`],
    /// [`CompensationError::JointLimit`] or [`CompensationError::JointJump`].
    pub fn compensate_path(
        &self,
        targets: &[ToolTarget],
        opts: &PathOptions,
    ) -> Result<PathResult, CompensationError> {
        opts.check()?;
        let mut rows = Vec::with_capacity(targets.len());
        let mut branch = opts.branch;
        let mut path_branch_fixed = false;
        let mut prev: Option<JointVector> = None;
        // the solved row before `prev`, for a linear prediction of the next seed
        let mut before: Option<JointVector> = None;
        let mut before2: Option<JointVector> = None;
        for (row, target) in targets.iter().enumerate() {
            let outcome = match prev {
                None => self.first_row(row, target, opts, branch),
                Some(p) => {
                    let seed = predicted_seed(
                        self.split.free(),
                        &p,
                        before.as_ref(),
                        before2.as_ref(),
                        opts.max_joint_step_deg.to_radians(),
                    );
                    self.next_row(row, target, &p, &seed, branch.unwrap_or(Branch(0)), opts)
                }
            };
            match outcome {
                Ok(c) => {
                    if !path_branch_fixed {
                        branch = Some(c.branch);
                        path_branch_fixed = true;
                    }
                    before2 = before;
                    before = prev;
                    prev = Some(c.q);
                    rows.push(RowOutcome::Solved(c));
                }
                Err(error) if opts.skip_unreachable && error.row().is_some() => {
                    rows.push(RowOutcome::Skipped(SkippedRow { row, error }));
                }
                Err(e) => return Err(e),
            }
        }
        Ok(PathResult { rows, branch: if path_branch_fixed { branch } else { None } })
    }

    pub(crate) fn limits_ok(&self, row: usize, q: &JointVector) -> Result<(), CompensationError> {
        if let Some((joint, value, min, max)) = self.calibrated.limit_violation(q) {
            let (f, unit): (fn(f64) -> f64, _) = if joint == 1 { (|v| v, "mm") } else { (rad_to_deg, "deg") };
            return Err(CompensationError::JointLimit {
                row,
                joint,
                value: f(value),
                min: f(min),
                max: f(max),
                unit,
            });
        }
        Ok(())
    }

    pub(crate) fn accept(&self, s: Solved, target: &ToolTarget) -> Compensated {
        Compensated {
            q: s.q,
            branch: self.branch_at(&s.q, &target.context),
            position_residual_mm: s.position_error_mm,
            rotation_residual_rad: s.rotation_error_rad,
            iterations: s.iterations,
        }
    }

    fn first_row(
        &self,
        row: usize,
        target: &ToolTarget,
        opts: &PathOptions,
        branch: Option<Branch>,
    ) -> Result<Compensated, CompensationError> {
        if let Some(start) = &opts.start
            && let Ok(s) = newton(self.calibrated, &self.split, target, start, &opts.solve)
        {
            let c = self.accept(s, target);
            if branch.is_none_or(|b| b == c.branch) {
                self.limits_ok(row, &c.q)?;
                return Ok(c);
            }
        }
        let solutions = self.all_solutions(target, &opts.solve);
        if solutions.is_empty() {
            return Err(CompensationError::Unreachable {
                row,
                reason: "no IK branch converges under the calibrated model".into(),
            });
        }
        let candidates: Vec<&(Branch, Solved)> =
            solutions.iter().filter(|(b, _)| branch.is_none_or(|want| *b == want)).collect();
        let inside = candidates
            .iter()
            .filter(|(_, s)| self.calibrated.limit_violation(&s.q).is_none())
            .max_by(|a, b| self.clearance(&a.1.q).total_cmp(&self.clearance(&b.1.q)));
        match (inside, candidates.first(), branch) {
            (Some((_, s)), _, _) => Ok(self.accept(*s, target)),
            (None, Some((_, s)), _) => {
                self.limits_ok(row, &s.q)?;
                Ok(self.accept(*s, target))
            }
            (None, None, Some(want)) => {
                Err(CompensationError::BranchChange { row, from: want, to: solutions[0].0 })
            }
            (None, None, None) => {
                Err(CompensationError::Unreachable { row, reason: "no IK solution".into() })
            }
        }
    }

    /// Smallest distance of a solved joint to its limits (rad or mm; continuous joints have
    /// none).
    pub(crate) fn clearance(&self, q: &JointVector) -> f64 {
        self.split
            .free()
            .iter()
            .filter_map(|&k| self.calibrated.joint_limit(k + 1).map(|(lo, hi)| (q[k] - lo).min(hi - q[k])))
            .fold(f64::INFINITY, f64::min)
    }

    fn next_row(
        &self,
        row: usize,
        target: &ToolTarget,
        prev: &JointVector,
        seed: &JointVector,
        branch: Branch,
        opts: &PathOptions,
    ) -> Result<Compensated, CompensationError> {
        let mut warm = newton(self.calibrated, &self.split, target, seed, &opts.solve);
        if warm.is_err() && seed != prev {
            warm = newton(self.calibrated, &self.split, target, prev, &opts.solve);
        }
        let c = match warm {
            Ok(s) => {
                let c = self.accept(s, target);
                if c.branch == branch {
                    c
                } else {
                    self.accept(self.reseed(row, target, prev, branch, &opts.solve, None)?, target)
                }
            }
            Err(e) => self.accept(self.reseed(row, target, prev, branch, &opts.solve, Some(e))?, target),
        };
        let max_step = opts.max_joint_step_deg.to_radians();
        // a prismatic solved joint (mm) is not an angle: the jump limit applies to revolute ones
        let revolute_free = self
            .split
            .free()
            .iter()
            .enumerate()
            .filter(|(s, _)| self.split.free_revolute(*s))
            .map(|(_, k)| *k);
        if let Some(k) =
            revolute_free.max_by(|&a, &b| (c.q[a] - prev[a]).abs().total_cmp(&(c.q[b] - prev[b]).abs()))
            && (c.q[k] - prev[k]).abs() > max_step
        {
            return Err(CompensationError::JointJump {
                row,
                joint: k + 1,
                step_deg: rad_to_deg((c.q[k] - prev[k]).abs()),
                max_deg: opts.max_joint_step_deg,
            });
        }
        self.limits_ok(row, &c.q)?;
        Ok(c)
    }

    /// The warm start failed or changed branch: closed-form seeds of the path's branch, the
    /// solution unwrapped to the previous row's turn.
    fn reseed(
        &self,
        row: usize,
        target: &ToolTarget,
        prev: &JointVector,
        branch: Branch,
        opts: &SolveOptions,
        warm_error: Option<NotConverged>,
    ) -> Result<Solved, CompensationError> {
        let solutions = self.all_solutions(target, opts);
        let unwrapped = |s: &Solved| {
            let mut q = s.q;
            for (slot, &k) in self.split.free().iter().enumerate() {
                if self.split.free_revolute(slot) {
                    q[k] += TAU * ((prev[k] - q[k]) / TAU).round();
                }
            }
            q
        };
        let distance =
            |q: &JointVector| self.split.free().iter().map(|&k| (q[k] - prev[k]).abs()).fold(0.0, f64::max);
        // the closed form has one solution per branch; a numerical-IK class can have several:
        // the one nearest the previous row
        let nearest = solutions
            .iter()
            .filter(|(b, _)| *b == branch)
            .map(|(_, s)| unwrapped(s))
            .min_by(|a, b| distance(a).total_cmp(&distance(b)));
        if let Some(q) = nearest
            && let Ok(s) = newton(self.calibrated, &self.split, target, &q, opts)
            && self.branch_at(&s.q, &target.context) == branch
        {
            return Ok(s);
        }
        match solutions.iter().find(|(b, _)| *b != branch) {
            Some((other, _)) => Err(CompensationError::BranchChange { row, from: branch, to: *other }),
            None => Err(CompensationError::Unreachable {
                row,
                reason: warm_error.map_or_else(
                    || "no IK branch converges under the calibrated model".to_string(),
                    |e| format!("{e} from the previous row; no IK branch converges"),
                ),
            }),
        }
    }

    /// `FK_nominal(q)`: what the robot controller, moving by its nominal kinematics, must be
    /// sent so that the cell physically reaches the pose compensated into `q`.
    ///
    /// # Errors
    /// An unknown TCP.
    pub fn corrected_pose(
        &self,
        q: &JointVector,
        tcp: u32,
        context: MeasurementContext,
    ) -> Result<CorrectedPose, CompensationError> {
        let chain = self.nominal.chain_full(q, &context, false, None);
        let world = PoseRequest::from_tool_frame(self.nominal, tcp, *q, &chain.tool, context)?;
        let (controller_pose, controller_joints_deg) = match (&self.seeder, self.meca500_arm) {
            (Seeder::ClosedForm { .. }, _) => {
                let base = robot_base_frame(self.nominal, q[0]);
                let pose = frame_to_meca_pose(&base.inverse().compose(&chain.frames[7]));
                let joints: [f64; 6] = std::array::from_fn(|k| rad_to_deg(q[k + 1]));
                (Some(pose), Some(joints))
            }
            (_, Some(k0)) => {
                let n = self.nominal.joint_count();
                let base = arm_base_frame(self.nominal, &chain, k0);
                let pose = frame_to_meca_pose(&base.inverse().compose(&chain.frames[n]));
                let joints: [f64; 6] = std::array::from_fn(|k| rad_to_deg(q[k0 - 1 + k]));
                (Some(pose), Some(joints))
            }
            _ => (None, None),
        };
        Ok(CorrectedPose { world, controller_pose, controller_joints_deg })
    }
}

/// The multi-start numerical IK of the solved joints of `model` with the given joints at their
/// values in `given` (the calibrated model without context; Newton adds it).
fn numeric_ik<'m>(
    model: &'m Model,
    split: &JointSplit,
    given: JointVector,
    opts: &MultiStartOptions,
) -> Result<NumericIk<ChainTool<'m>>, PlanError> {
    let free: Vec<usize> = split.solved_joints().to_vec();
    let revolute: Vec<bool> = free.iter().map(|i| model.is_revolute(*i)).collect();
    let specs: Vec<JointSpec> = free
        .iter()
        .zip(&revolute)
        .map(|(i, r)| match (model.joint_limit(*i), r) {
            (Some((lo, hi)), true) => JointSpec::revolute(lo, hi),
            (Some((lo, hi)), false) => JointSpec::prismatic(lo, hi),
            (None, true) => JointSpec::continuous(),
            (None, false) => JointSpec { revolute: false, limits: None },
        })
        .collect();
    let mut fixed = given;
    if fixed.len() != model.joint_count() {
        fixed = JointVector::zeros(model.joint_count());
    }
    NumericIk::new(ChainTool { model, fixed, free, revolute }, &specs, *opts)
}
