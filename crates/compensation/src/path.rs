//! Compensation of one pose and of a path.

use std::f64::consts::TAU;

use vatcal_core::{JointVector, MeasurementContext, rad_to_deg};
use vatcal_kinematics::Model;
use vatcal_planning::ik::{ArmGeometry, RefineOptions, ToolPoseIk, robot_base_frame};

use crate::solve::{Branch, NotConverged, SolveOptions, Solved, newton};
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
    /// `None`: the first row's solution inside the limits with the largest clearance
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
    /// joint targets under the calibrated model (q1 as requested)
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
    prev: &JointVector,
    before: Option<&JointVector>,
    before2: Option<&JointVector>,
    max_step_rad: f64,
) -> JointVector {
    let Some(b) = before else { return *prev };
    let mut seed = *prev;
    for k in 1..7 {
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
    /// the flange (frame 7) in the robot's base frame as the nominal controller computes it:
    /// `MovePose` arguments `[x, y, z (mm), α, β, γ (deg)]` with WRF = TRF = identity
    pub controller_pose: [f64; 6],
    /// `MoveJoints` arguments: q2..q7 \[deg\] (Meca500 J1..J6)
    pub controller_joints_deg: [f64; 6],
}

/// Compensation under a calibrated model, with the nominal model of the robot controller.
#[derive(Debug, Clone)]
pub struct Compensator<'a> {
    calibrated: &'a Model,
    nominal: &'a Model,
    ik: ToolPoseIk<'a>,
    arm: ArmGeometry,
}

impl<'a> Compensator<'a> {
    /// A compensator for `calibrated` (the model the cell really follows) and `nominal` (the
    /// model the robot controller uses, for [`Compensator::corrected_pose`]).
    ///
    /// # Errors
    /// The calibrated arm is not Meca500-like (the closed-form seeds need its structure).
    pub fn new(calibrated: &'a Model, nominal: &'a Model) -> Result<Self, CompensationError> {
        nominal.require_meca500_on_guide("compensation's Meca500 output")?;
        let ik = ToolPoseIk::new(calibrated, RefineOptions::default())?;
        let arm = *ik.arm();
        Ok(Self { calibrated, nominal, ik, arm })
    }

    /// The calibrated model.
    pub fn calibrated(&self) -> &'a Model {
        self.calibrated
    }

    /// The nominal (controller) model.
    pub fn nominal(&self) -> &'a Model {
        self.nominal
    }

    /// The branch of joints `q`.
    pub fn branch_of(&self, q: &JointVector) -> Branch {
        Branch::of(&self.arm, q)
    }

    /// Every solution of `target` under the calibrated model (closed-form seeds of each branch
    /// refined with the context), arm joints wrapped into (−180°, 180°], inside or outside the
    /// joint limits.
    pub fn all_solutions(&self, target: &ToolTarget, opts: &SolveOptions) -> Vec<(Branch, Solved)> {
        let base = robot_base_frame(self.calibrated, target.q1_mm);
        let mut out: Vec<(Branch, Solved)> = Vec::with_capacity(8);
        for seed in self.ik.seeds(target.q1_mm, &base, &target.tool) {
            let Ok(s) = newton(self.calibrated, target, &seed.q, opts) else { continue };
            let Ok(s) = self.wrapped(target, s, opts) else { continue };
            let branch = self.branch_of(&s.q);
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
        for v in q.as_mut_slice().iter_mut().skip(1) {
            let w = vatcal_planning::ik::wrap_angle(*v);
            moved |= w != *v;
            *v = w;
        }
        if moved { newton(self.calibrated, target, &q, opts) } else { Ok(s) }
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
    /// let request = PoseRequest {
    ///     tcp: 2,
    ///     q1_mm: 100.0,
    ///     xyz_mm: [60.0, -40.0, 40.0],
    ///     abc_deg: [180.0, 0.0, 0.0],
    ///     context: MeasurementContext::default(),
    /// };
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

    fn limits_ok(&self, row: usize, q: &JointVector) -> Result<(), CompensationError> {
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

    fn accept(&self, s: Solved) -> Compensated {
        Compensated {
            q: s.q,
            branch: self.branch_of(&s.q),
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
            && let Ok(s) = newton(self.calibrated, target, start, &opts.solve)
        {
            let c = self.accept(s);
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
            (Some((_, s)), _, _) => Ok(self.accept(*s)),
            (None, Some((_, s)), _) => {
                self.limits_ok(row, &s.q)?;
                Ok(self.accept(*s))
            }
            (None, None, Some(want)) => {
                Err(CompensationError::BranchChange { row, from: want, to: solutions[0].0 })
            }
            (None, None, None) => {
                Err(CompensationError::Unreachable { row, reason: "no IK solution".into() })
            }
        }
    }

    /// Smallest distance of an arm joint to its limits \[rad\].
    fn clearance(&self, q: &JointVector) -> f64 {
        let limits = self.calibrated.joint_limits();
        (1..7).map(|k| (q[k] - limits[k].0).min(limits[k].1 - q[k])).fold(f64::INFINITY, f64::min)
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
        let mut warm = newton(self.calibrated, target, seed, &opts.solve);
        if warm.is_err() && seed != prev {
            warm = newton(self.calibrated, target, prev, &opts.solve);
        }
        let c = match warm {
            Ok(s) => {
                let c = self.accept(s);
                if c.branch == branch {
                    c
                } else {
                    self.accept(self.reseed(row, target, prev, branch, &opts.solve, None)?)
                }
            }
            Err(e) => self.accept(self.reseed(row, target, prev, branch, &opts.solve, Some(e))?),
        };
        let max_step = opts.max_joint_step_deg.to_radians();
        if let Some(k) = (1..7).max_by(|&a, &b| (c.q[a] - prev[a]).abs().total_cmp(&(c.q[b] - prev[b]).abs()))
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
        if let Some((_, s)) = solutions.iter().find(|(b, _)| *b == branch) {
            let mut q = s.q;
            for k in 1..7 {
                q[k] += TAU * ((prev[k] - q[k]) / TAU).round();
            }
            if let Ok(s) = newton(self.calibrated, target, &q, opts)
                && self.branch_of(&s.q) == branch
            {
                return Ok(s);
            }
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
    pub fn corrected_pose(
        &self,
        q: &JointVector,
        tcp: u32,
        context: MeasurementContext,
    ) -> Result<CorrectedPose, CompensationError> {
        let chain = self.nominal.chain_full(q, &context, false, None);
        let world = PoseRequest::from_tool_frame(self.nominal, tcp, q[0], &chain.tool, context)?;
        let base = robot_base_frame(self.nominal, q[0]);
        let controller_pose = frame_to_meca_pose(&base.inverse().compose(&chain.frames[7]));
        let controller_joints_deg: [f64; 6] = std::array::from_fn(|k| rad_to_deg(q[k + 1]));
        Ok(CorrectedPose { world, controller_pose, controller_joints_deg })
    }
}
