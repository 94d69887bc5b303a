//! Candidate measurement poses (paper Section 4.1).
//!
//! For every calibration position × calibration TCP, `orientations` random tool orientations are
//! drawn (seeded ChaCha8, see [`sample_orientation`]); each gives a world pose of the
//! tool-changer frame that puts the TCP on the calibration position. Each pose is solved at
//! every guide step (closed form, up to 8 branches, refined on the model), and the solutions
//! go through the stages
//!
//! 1. **IK solutions**: all branches at all guide steps;
//! 2. **within limits**: every joint inside its limits shrunk by the joint margin;
//! 3. **clear of singularities**: wrist, elbow and shoulder margins ([`SingularityMargins`]);
//! 4. **collision-free**: no contact at the measurement pose (the measuring ball may touch the
//!    probe, nothing else);
//! 5. **retreat clear**: the *retreat pose* — the same tool orientation with the ball
//!    `retreat_height_mm` straight above the probe origin, solved from the measurement joints —
//!    is within the joint limits (less [`MOVE_MARGIN_DEG`]) and collision-free with a probe at
//!    *every* placement (the robot waits there while the operator re-places the plate), and the
//!    straight joint-space descent from it to the measurement pose is collision-free at the
//!    check resolution. The robot comes in to a measurement from its retreat pose and leaves
//!    back to it.
//!
//! Only candidates that pass all stages are returned; the count after each stage is reported.
//!
//! # Any serial chain
//! The above is the canonical Meca500-on-guide cell. On any other chain
//! ([`vatcal_kinematics::Model::is_meca500_on_guide`] false) stage 1 uses
//! [`ModelIk::closed_form_first`] ([`CandidateOptions::ik`]): the closed form + refinement
//! where the chain is a 6R arm with a spherical wrist ([`crate::ik::ArmGeometry::from_model`],
//! e.g. the Meca500 alone on a table) or with three parallel middle axes and a UR-type wrist
//! ([`crate::ik::ParallelArm::from_model`], e.g. the UR5e), the multi-start numerical IK
//! ([`crate::numeric_ik`]) otherwise, with the first prismatic joint, if the chain has one,
//! held at each of the `guide_steps` positions over its stroke (one pass when the chain has no
//! prismatic joint); every distinct converged branch counts as an IK solution.
//! [`CandidateSet::ik`] says which IK was used. Stage 3 uses the chain-agnostic singularity
//! test of [`SingularityMargins`], and the retreat pose is a local solve from the measurement
//! joints ([`ModelIk::refine_from`]). The other stages are the same.
//!
//! # Warm-started numerical IK
//! With the numerical IK (and [`CandidateOptions::warm_start`], the default) the TCP poses of
//! each calibration position × TCP are put in a greedy nearest-neighbour order of their tool
//! poses (distance `|R_a - R_b|_F^2 + (|p_a - p_b| / 100 mm)^2`, from orientation 0) and cut
//! into chains of [`WARM_CHAIN_LEN`]; the chains run in parallel, the poses of a chain one
//! after the other. A pose is started from the solutions of the previous pose of its chain at
//! the same guide step, then from its own solutions at the previous guide step, and its search
//! stops as soon as it has as many distinct solutions as the first of them that has any
//! ([`crate::numeric_ik::NumericIk::solve_warm`]); the fixed starts run only when a branch was
//! lost, and fully for the first pose of a chain. The candidates come out in the same order
//! (position, TCP, orientation, guide step, branch) and do not depend on the thread count.
//!
//! # Orientation distribution
//! The ball must enter the probe from above: the TriCal's three gauges hold the ball from below
//! and the sides, so the rest of the end-effector has to be above it. Let `u_k = -t_k / |t_k|`
//! be the direction from ball k to the flange in the tool frame. A sample is
//! `R = Rot(a, psi) · R_0(a)` where `a` is uniform on the spherical cap of half-angle
//! `cone_half_angle_deg` around world +z, `psi` uniform in [0, 2 pi), and `R_0(a)` the minimal
//! rotation taking `u_k` to `a`. This is the uniform (Haar) distribution over all tool
//! orientations whose ball-to-flange direction lies in the cone: the flange (and with it the
//! robot) is above the ball, every spin about that direction is tried, and the collision stage
//! rejects the spins that bring another ball or the plate into the probe or the tank. The
//! default half-angle, 60°, keeps the flange at least 30° above the horizontal through the ball.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;
use vatcal_core::{Frame, JointVector, deg_to_rad};
use vatcal_kinematics::Model;

use crate::collision::{CollisionChecker, ProbeState};
use crate::error::PlanError;
use crate::ik::{
    IkMethod, ModelIk, RefineOptions, ToolPoseIk, max_abs_diff, refine_tool_pose, robot_base_frame,
    tool_pose_for_tcp, wrap_angle,
};
use crate::motion::{JointBounds, MOVE_MARGIN_DEG, Resolution, SingularityMargins};
use crate::numeric_ik::MultiStartOptions;
use crate::paths::segment_is_free;

/// Options of candidate generation.
#[derive(Debug, Clone, PartialEq)]
pub struct CandidateOptions {
    /// random tool orientations per TCP × calibration position (paper: 500)
    pub orientations: usize,
    /// guide positions, evenly spaced over the stroke shrunk by `guide_margin_mm` (paper: 10)
    pub guide_steps: usize,
    /// distance kept from the guide's stroke ends (mm)
    pub guide_margin_mm: f64,
    /// half-angle of the cone around world +z holding the ball-to-flange direction (deg)
    pub cone_half_angle_deg: f64,
    /// distance kept from every arm joint limit (deg)
    pub joint_margin_deg: f64,
    /// singularity margins
    pub singularity: SingularityMargins,
    /// height of the retreat pose above the measurement pose (mm)
    pub retreat_height_mm: f64,
    /// inflation of the robot bodies in collision checks (mm)
    pub collision_margin_mm: f64,
    /// collision-check resolution of the descent from the retreat pose
    pub resolution: Resolution,
    /// IK refinement options
    pub refine: RefineOptions,
    /// multi-start numerical IK of a chain without a closed form (any chain other than the
    /// canonical cell)
    pub numeric: MultiStartOptions,
    /// which IK solves the TCP poses of a chain other than the canonical cell (default: a
    /// closed form where the chain has one)
    pub ik: IkChoice,
    /// warm-start the numerical IK (see the module docs): each TCP pose from the solutions of
    /// its neighbour in a nearest-neighbour chain of the tool poses, each guide step also from
    /// the previous one; `false`: every pose and guide step from every fixed start
    pub warm_start: bool,
    /// calibration positions to use (`None`: all of the model's)
    pub positions: Option<Vec<u32>>,
    /// TCPs to use (`None`: all of the model's)
    pub tcps: Option<Vec<u32>>,
    /// seed of the orientation sampler
    pub seed: u64,
    /// show a progress bar (only drawn when stderr is a terminal)
    pub progress: bool,
}

impl Default for CandidateOptions {
    fn default() -> Self {
        Self {
            orientations: 500,
            guide_steps: 10,
            guide_margin_mm: 5.0,
            cone_half_angle_deg: 60.0,
            joint_margin_deg: 5.0,
            singularity: SingularityMargins::default(),
            retreat_height_mm: 30.0,
            collision_margin_mm: 2.0,
            resolution: Resolution::default(),
            refine: RefineOptions::default(),
            numeric: MultiStartOptions::default(),
            ik: IkChoice::default(),
            warm_start: true,
            positions: None,
            tcps: None,
            seed: 1,
            progress: false,
        }
    }
}

/// Which inverse kinematics solves the TCP poses of a chain other than the canonical cell
/// (the canonical cell always uses its closed form).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IkChoice {
    /// A closed form where the chain has one (spherical wrist, or three parallel middle axes
    /// and a UR-type wrist), the numerical IK otherwise ([`ModelIk::closed_form_first`]).
    #[default]
    ClosedFormFirst,
    /// The spherical-wrist closed form where the chain has one, the numerical IK otherwise
    /// (the planner before the parallel closed form; [`ModelIk::new`]).
    WithoutParallelClosedForm,
    /// Always the numerical IK ([`ModelIk::numerical`]).
    Numerical,
}

/// Length of the chains of TCP poses solved one after the other with warm starts (the first
/// of each chain from the fixed starts alone); the chains run in parallel.
pub const WARM_CHAIN_LEN: usize = 24;

/// One measurable joint configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// calibration position id
    pub position: u32,
    /// TCP id
    pub tcp: u32,
    /// measurement joints (TCP on the calibration position)
    pub q: JointVector,
    /// retreat joints: ball `retreat_height_mm` straight above the probe origin, same tool
    /// orientation; the robot comes in from here and leaves to here
    pub retreat: JointVector,
    /// index of the sampled orientation (per position × TCP)
    pub orientation: usize,
    /// index of the guide step (0 on a chain without a prismatic joint)
    pub guide_step: usize,
}

/// Number of solutions left after each stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct StageCounts {
    /// TCP poses (orientations × TCPs × positions)
    pub poses: usize,
    /// closed-form IK solutions over all guide steps (at most 8 × guide steps × poses), plus
    /// refined solutions of a calibrated arm just beyond its nominal structure's reach
    pub ik_solutions: usize,
    /// solutions inside the joint limits shrunk by the margins
    pub within_limits: usize,
    /// ... and clear of the singularities
    pub clear_of_singularities: usize,
    /// ... and collision-free at the measurement pose
    pub collision_free: usize,
    /// ... and with a reachable, collision-free retreat pose and descent (the final candidates)
    pub retreat_clear: usize,
}

impl StageCounts {
    fn add(&mut self, o: &StageCounts) {
        self.poses += o.poses;
        self.ik_solutions += o.ik_solutions;
        self.within_limits += o.within_limits;
        self.clear_of_singularities += o.clear_of_singularities;
        self.collision_free += o.collision_free;
        self.retreat_clear += o.retreat_clear;
    }
}

/// The candidate set and its stage counts.
#[derive(Debug, Clone, PartialEq)]
pub struct CandidateSet {
    /// the candidates, ordered by position, TCP, orientation, guide step, branch
    pub candidates: Vec<Candidate>,
    /// counts per stage
    pub counts: StageCounts,
    /// the guide positions used (mm; empty for a chain without a prismatic joint)
    pub guide_positions_mm: Vec<f64>,
    /// kinds of the model's joints (the units of the joint columns in the output files)
    pub joint_kinds: Vec<vatcal_core::JointKind>,
    /// the IK that solved the TCP poses (stage 1)
    pub ik: IkMethod,
}

/// Evenly spaced guide positions over the stroke shrunk by `margin_mm` (the middle for one
/// step). The guide is joint 1 on the canonical cell, the first prismatic joint on any other
/// chain; a chain without a prismatic joint has no guide positions (empty).
pub fn guide_positions(model: &Model, steps: usize, margin_mm: f64) -> Result<Vec<f64>, PlanError> {
    if steps == 0 {
        return Err(PlanError::Option { option: "guide_steps".into(), reason: "must be at least 1".into() });
    }
    let Some(guide) = model.joint_kinds().iter().position(|k| !k.is_revolute()) else {
        return Ok(Vec::new());
    };
    let (lo, hi) = model.joint_limits()[guide];
    let (a, b) = (lo + margin_mm, hi - margin_mm);
    if a > b || a.is_nan() || b.is_nan() {
        return Err(PlanError::Option {
            option: "guide_margin_mm".into(),
            reason: format!("{margin_mm} mm leaves nothing of the stroke {lo}..{hi} mm"),
        });
    }
    if steps == 1 {
        return Ok(vec![0.5 * (a + b)]);
    }
    Ok((0..steps).map(|i| a + (b - a) * i as f64 / (steps - 1) as f64).collect())
}

/// A rotation taking unit vector `from` to unit vector `to` (the minimal one).
fn align(from: &Vector3<f64>, to: &Vector3<f64>) -> Matrix3<f64> {
    match Rotation3::rotation_between(from, to) {
        Some(r) => *r.matrix(),
        None => {
            // opposite vectors: half turn about any axis perpendicular to `from`
            let helper = if from.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
            let axis = Unit::new_normalize(from.cross(&helper));
            *Rotation3::from_axis_angle(&axis, std::f64::consts::PI).matrix()
        }
    }
}

/// Draws one tool orientation (see the module docs): `R` with `R · u` uniform on the cap of
/// half-angle `cone_half_angle_rad` around world +z and a uniform spin about it, where `u` is
/// the ball-to-flange direction in the tool frame.
pub fn sample_orientation(
    rng: &mut ChaCha8Rng,
    ball_to_flange_tool: &Vector3<f64>,
    cone_half_angle_rad: f64,
) -> Matrix3<f64> {
    let u = ball_to_flange_tool.normalize();
    let cos_min = cone_half_angle_rad.cos();
    let cos_t = 1.0 - rng.random_range(0.0..1.0) * (1.0 - cos_min);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = rng.random_range(0.0..std::f64::consts::TAU);
    let a = Vector3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
    let psi = rng.random_range(0.0..std::f64::consts::TAU);
    let spin = Rotation3::from_axis_angle(&Unit::new_unchecked(a), psi);
    spin.matrix() * align(&u, &a)
}

/// How the pipeline solves a TCP pose.
enum Solver<'a> {
    /// canonical cell: closed-form seeds at every guide step, refined on the model
    Canonical {
        ik: Box<ToolPoseIk<'a>>,
        /// (guide position, robot base frame) per guide step
        bases: Vec<(f64, Frame)>,
    },
    /// any other chain: [`ModelIk`] at every guide step (one pass without a guide)
    Any { ik: ModelIk<'a>, guide: Vec<f64> },
}

/// Everything needed to evaluate one TCP pose.
struct Pipeline<'a> {
    model: &'a Model,
    solver: Solver<'a>,
    checker: &'a CollisionChecker<'a>,
    bounds: JointBounds,
    move_bounds: JointBounds,
    opts: &'a CandidateOptions,
}

/// Outcome of stages 3..5 for one solution.
enum Screen {
    Singular,
    Colliding,
    NoRetreat,
    Measurable(JointVector),
}

/// One TCP pose to solve.
#[derive(Debug, Clone, Copy)]
struct PoseTask {
    position: u32,
    tcp: u32,
    orientation: usize,
    target: Frame,
}

/// The IK solutions of one TCP pose at every guide step (the warm starts of the next pose).
type StepSolutions = Vec<Vec<JointVector>>;

impl Pipeline<'_> {
    fn run(&self, task: &PoseTask) -> (Vec<Candidate>, StageCounts) {
        match &self.solver {
            Solver::Canonical { ik, bases } => self.run_canonical(ik, bases, task),
            Solver::Any { ik, guide } => {
                let (candidates, counts, _) = self.run_any(ik, guide, task, false, None);
                (candidates, counts)
            }
        }
    }

    /// The IK and guide positions when the TCP poses are solved in warm-started chains
    /// (numerical IK, warm starts on).
    fn warm_solver(&self) -> Option<(&ModelIk<'_>, &[f64])> {
        match &self.solver {
            Solver::Any { ik, guide } if self.opts.warm_start && !ik.is_closed_form() => Some((ik, guide)),
            _ => None,
        }
    }

    /// Stages 1..5 on any chain (see the module docs); with `warm` starts, `previous` holds
    /// the solutions of the preceding pose of the chain at every guide step. Also returns this
    /// pose's solutions at every guide step.
    fn run_any(
        &self,
        ik: &ModelIk<'_>,
        guide: &[f64],
        task: &PoseTask,
        warm: bool,
        previous: Option<&[Vec<JointVector>]>,
    ) -> (Vec<Candidate>, StageCounts, StepSolutions) {
        let mut counts = StageCounts { poses: 1, ..StageCounts::default() };
        let mut out = Vec::new();
        let steps: &[f64] = if guide.is_empty() { &[0.0] } else { guide };
        let mut solved: StepSolutions = Vec::with_capacity(steps.len());
        for (step, g) in steps.iter().enumerate() {
            let solutions = if warm {
                // the neighbouring pose at this guide step, then this pose at the previous one;
                // enough: as many solutions as the first of them that has any
                let neighbour = previous.and_then(|p| p.get(step)).filter(|p| !p.is_empty());
                let before = step.checked_sub(1).and_then(|s| solved.get(s)).filter(|p| !p.is_empty());
                let enough = neighbour.or(before).map_or(0, Vec::len);
                let starts: Vec<JointVector> =
                    neighbour.into_iter().chain(before).flat_map(|p| p.iter().copied()).collect();
                ik.solve_at_guide_warm(*g, &task.target, &starts, enough)
            } else {
                ik.solve_at_guide(*g, &task.target)
            };
            for q in &solutions {
                counts.ik_solutions += 1;
                if !self.bounds.contains(q) {
                    continue;
                }
                counts.within_limits += 1;
                self.screen_and_count(task, *q, step, &mut counts, &mut out);
            }
            solved.push(solutions);
        }
        (out, counts, solved)
    }

    /// Stages 1..5 of the TCP poses `chain` (indices into `tasks`) one after the other with the
    /// warm-started IK `ik` ([`Pipeline::warm_solver`]), each from the previous one's
    /// solutions; results by task index.
    fn run_chain(
        &self,
        (ik, guide): (&ModelIk<'_>, &[f64]),
        tasks: &[PoseTask],
        chain: &[usize],
        bar: &ProgressBar,
    ) -> Vec<(usize, (Vec<Candidate>, StageCounts))> {
        let mut previous: Option<StepSolutions> = None;
        let mut out = Vec::with_capacity(chain.len());
        for &i in chain {
            let (candidates, counts, solved) = self.run_any(ik, guide, &tasks[i], true, previous.as_deref());
            previous = Some(solved);
            bar.inc(1);
            out.push((i, (candidates, counts)));
        }
        out
    }

    /// Stages 3..5 of one solution within the limits: counts it and keeps it when measurable.
    fn screen_and_count(
        &self,
        task: &PoseTask,
        q: JointVector,
        step: usize,
        counts: &mut StageCounts,
        out: &mut Vec<Candidate>,
    ) {
        match self.screen(task, q) {
            Screen::Singular => {}
            Screen::Colliding => counts.clear_of_singularities += 1,
            Screen::NoRetreat => {
                counts.clear_of_singularities += 1;
                counts.collision_free += 1;
            }
            Screen::Measurable(retreat) => {
                counts.clear_of_singularities += 1;
                counts.collision_free += 1;
                counts.retreat_clear += 1;
                out.push(Candidate {
                    position: task.position,
                    tcp: task.tcp,
                    q,
                    retreat,
                    orientation: task.orientation,
                    guide_step: step,
                });
            }
        }
    }

    /// Stages 1..5 on the canonical cell (closed-form seeds).
    fn run_canonical(
        &self,
        ik: &ToolPoseIk<'_>,
        bases: &[(f64, Frame)],
        task: &PoseTask,
    ) -> (Vec<Candidate>, StageCounts) {
        let mut counts = StageCounts { poses: 1, ..StageCounts::default() };
        let mut out = Vec::new();
        // refinement moves a calibrated model's joints by well under a degree
        let slack_rad = deg_to_rad(2.0);
        for (step, (q1, base)) in bases.iter().enumerate() {
            let mut found: Vec<JointVector> = Vec::with_capacity(8);
            for seed in ik.seeds(*q1, base, &task.target) {
                if !seed.beyond_reach {
                    counts.ik_solutions += 1;
                }
                if !self.bounds.contains_with_slack(&seed.q, 0.0, slack_rad) {
                    continue;
                }
                let Ok(refined) = ik.refine(&seed.q, &task.target) else {
                    continue;
                };
                if seed.beyond_reach {
                    // the calibrated arm reaches what its nominal structure cannot
                    counts.ik_solutions += 1;
                }
                let mut q = refined.q;
                for v in q.as_mut_slice().iter_mut().skip(1) {
                    *v = wrap_angle(*v);
                }
                if found.iter().any(|p| max_abs_diff(p, &q) < 1e-9) || !self.bounds.contains(&q) {
                    continue;
                }
                found.push(q);
                counts.within_limits += 1;
                self.screen_and_count(task, q, step, &mut counts, &mut out);
            }
        }
        (out, counts)
    }

    /// Stages 3..5 for a solution inside the limits.
    fn screen(&self, task: &PoseTask, q: JointVector) -> Screen {
        let chain = self.model.chain(&q);
        if !self.opts.singularity.clear(self.model, &chain) {
            return Screen::Singular;
        }
        let measuring = ProbeState::Measuring { position: task.position, tcp: task.tcp };
        if self.checker.check_chain(&chain, measuring).is_some() {
            return Screen::Colliding;
        }
        self.retreat_pose(task, &q).map_or(Screen::NoRetreat, Screen::Measurable)
    }

    fn retreat_pose(&self, task: &PoseTask, q: &JointVector) -> Option<JointVector> {
        let mut target = task.target;
        target.p.z += self.opts.retreat_height_mm;
        let a = match &self.solver {
            Solver::Canonical { .. } => {
                let refined = refine_tool_pose(self.model, q, &target, &self.opts.refine).ok()?;
                let mut a = refined.q;
                for (v, q0) in a.as_mut_slice().iter_mut().zip(q.as_slice()).skip(1) {
                    // stay on the same side of the +-pi cut as the measurement pose
                    *v = q0 + wrap_angle(*v - q0);
                }
                a
            }
            Solver::Any { ik, .. } => ik.refine_from(q, &target, &self.opts.refine).ok()?,
        };
        if !self.move_bounds.contains(&a) || !self.checker.is_free(&a, ProbeState::Everywhere) {
            return None;
        }
        let measuring = ProbeState::Measuring { position: task.position, tcp: task.tcp };
        segment_is_free(self.checker, &a, q, measuring, &self.opts.resolution).then_some(a)
    }
}

/// Generates the candidate set (see the module docs). Parallel over TCP poses (rayon);
/// deterministic for a given seed.
pub fn generate_candidates(
    model: &Model,
    checker: &CollisionChecker<'_>,
    opts: &CandidateOptions,
) -> Result<CandidateSet, PlanError> {
    validate(opts)?;
    let positions = select_ids(&model.position_ids(), opts.positions.as_deref(), "positions")?;
    let tcps = select_ids(&model.tcp_ids(), opts.tcps.as_deref(), "tcps")?;
    let guide = guide_positions(model, opts.guide_steps, opts.guide_margin_mm)?;
    let solver = if model.is_meca500_on_guide() {
        let bases: Vec<(f64, Frame)> = guide.iter().map(|q1| (*q1, robot_base_frame(model, *q1))).collect();
        Solver::Canonical { ik: Box::new(ToolPoseIk::new(model, opts.refine)?), bases }
    } else {
        let ik = match opts.ik {
            IkChoice::ClosedFormFirst => ModelIk::closed_form_first(model, opts.refine, opts.numeric)?,
            IkChoice::WithoutParallelClosedForm => ModelIk::new(model, opts.refine, opts.numeric)?,
            IkChoice::Numerical => ModelIk::numerical(model, opts.numeric)?,
        };
        Solver::Any { ik, guide: guide.clone() }
    };
    let ik = match &solver {
        Solver::Canonical { .. } => IkMethod::ClosedForm,
        Solver::Any { ik, .. } => ik.method(),
    };
    let pipeline = Pipeline {
        model,
        solver,
        checker,
        bounds: JointBounds::new(model, opts.joint_margin_deg, 0.0)?,
        move_bounds: JointBounds::new(model, MOVE_MARGIN_DEG.min(opts.joint_margin_deg), 0.0)?,
        opts,
    };
    let tasks = sample_tasks(model, &positions, &tcps, opts)?;
    let bar = progress_bar(tasks.len() as u64, opts.progress);
    let results: Vec<(Vec<Candidate>, StageCounts)> = if let Some(warm) = pipeline.warm_solver() {
        let chains = warm_chains(&tasks, WARM_CHAIN_LEN);
        let mut by_task: Vec<(usize, (Vec<Candidate>, StageCounts))> =
            chains.par_iter().flat_map_iter(|c| pipeline.run_chain(warm, &tasks, c, &bar)).collect();
        by_task.sort_unstable_by_key(|(i, _)| *i);
        by_task.into_iter().map(|(_, r)| r).collect()
    } else {
        tasks
            .par_iter()
            .map(|t| {
                let r = pipeline.run(t);
                bar.inc(1);
                r
            })
            .collect()
    };
    bar.finish_and_clear();
    let mut counts = StageCounts::default();
    let mut candidates = Vec::new();
    for (c, n) in results {
        counts.add(&n);
        candidates.extend(c);
    }
    Ok(CandidateSet {
        candidates,
        counts,
        guide_positions_mm: guide,
        joint_kinds: model.joint_kinds().to_vec(),
        ik,
    })
}

/// The TCP poses cut into chains for warm starts: within each run of tasks of one calibration
/// position and TCP (consecutive in `tasks`), a greedy nearest-neighbour order of the tool poses
/// (from the first; distance `|R_a - R_b|_F^2 + (|p_a - p_b| / 100 mm)^2`, ties to the lower
/// index), cut into pieces of `len`. Depends on the tasks only (not on the thread count).
fn warm_chains(tasks: &[PoseTask], len: usize) -> Vec<Vec<usize>> {
    let mut chains = Vec::new();
    let mut start = 0;
    while start < tasks.len() {
        let key = |t: &PoseTask| (t.position, t.tcp);
        let end = tasks[start..]
            .iter()
            .position(|t| key(t) != key(&tasks[start]))
            .map_or(tasks.len(), |k| start + k);
        let order = nearest_neighbour_order(&tasks[start..end]);
        chains.extend(order.chunks(len.max(1)).map(|c| c.iter().map(|k| start + k).collect()));
        start = end;
    }
    chains
}

/// Greedy nearest-neighbour order of the tool poses of `tasks`, from the first.
fn nearest_neighbour_order(tasks: &[PoseTask]) -> Vec<usize> {
    let distance = |a: &Frame, b: &Frame| (a.r - b.r).norm_squared() + ((a.p - b.p) / 100.0).norm_squared();
    let mut left: Vec<usize> = (1..tasks.len()).collect();
    let mut order = Vec::with_capacity(tasks.len());
    if tasks.is_empty() {
        return order;
    }
    order.push(0);
    let mut current = 0;
    while !left.is_empty() {
        let (k, _) = left.iter().enumerate().fold((0, f64::INFINITY), |best, (k, &j)| {
            let d = distance(&tasks[current].target, &tasks[j].target);
            if d < best.1 { (k, d) } else { best }
        });
        current = left.remove(k);
        order.push(current);
    }
    order
}

fn validate(opts: &CandidateOptions) -> Result<(), PlanError> {
    let bad = |option: &str, reason: String| Err(PlanError::Option { option: option.into(), reason });
    if opts.orientations == 0 {
        return bad("orientations", "must be at least 1".into());
    }
    if !(opts.cone_half_angle_deg > 0.0 && opts.cone_half_angle_deg <= 180.0) {
        return bad("cone_half_angle_deg", format!("must be in (0, 180], got {}", opts.cone_half_angle_deg));
    }
    for (name, v) in [
        ("joint_margin_deg", opts.joint_margin_deg),
        ("retreat_height_mm", opts.retreat_height_mm),
        ("collision_margin_mm", opts.collision_margin_mm),
        ("singularity.wrist_deg", opts.singularity.wrist_deg),
        ("singularity.elbow_deg", opts.singularity.elbow_deg),
        ("singularity.shoulder_mm", opts.singularity.shoulder_mm),
        ("guide_margin_mm", opts.guide_margin_mm),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return bad(name, format!("must be a finite value >= 0, got {v}"));
        }
    }
    opts.resolution.validate()
}

fn select_ids(all: &[u32], wanted: Option<&[u32]>, what: &str) -> Result<Vec<u32>, PlanError> {
    match wanted {
        None => Ok(all.to_vec()),
        Some(w) => {
            if let Some(bad) = w.iter().find(|id| !all.contains(id)) {
                return Err(PlanError::Option {
                    option: what.into(),
                    reason: format!("unknown id {bad} (the model has {all:?})"),
                });
            }
            if w.is_empty() {
                return Err(PlanError::Option { option: what.into(), reason: "must not be empty".into() });
            }
            Ok(w.to_vec())
        }
    }
}

/// Draws every TCP pose sequentially (so the stream does not depend on the thread count): one
/// ChaCha8 stream per run, positions outer, TCPs middle, orientations inner.
fn sample_tasks(
    model: &Model,
    positions: &[u32],
    tcps: &[u32],
    opts: &CandidateOptions,
) -> Result<Vec<PoseTask>, PlanError> {
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let cone = deg_to_rad(opts.cone_half_angle_deg);
    let mut tasks = Vec::with_capacity(positions.len() * tcps.len() * opts.orientations);
    for &position in positions {
        let p = model.position(position).ok_or_else(|| PlanError::Option {
            option: "positions".into(),
            reason: format!("unknown calibration position {position}"),
        })?;
        for &tcp in tcps {
            let t = model.tcp(tcp).ok_or_else(|| PlanError::Option {
                option: "tcps".into(),
                reason: format!("unknown TCP {tcp}"),
            })?;
            if t.norm() < 1e-9 {
                return Err(PlanError::Option {
                    option: "tcps".into(),
                    reason: format!("TCP {tcp} is at the flange: no ball-to-flange direction"),
                });
            }
            for orientation in 0..opts.orientations {
                let r = sample_orientation(&mut rng, &(-t), cone);
                tasks.push(PoseTask { position, tcp, orientation, target: tool_pose_for_tcp(&r, &t, &p) });
            }
        }
    }
    Ok(tasks)
}

/// A progress bar that draws only when asked to and when stderr is a terminal.
pub(crate) fn progress_bar(len: u64, wanted: bool) -> ProgressBar {
    if !wanted || !std::io::stderr().is_terminal() {
        return ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::hidden());
    }
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template("{msg:12} [{bar:40}] {pos}/{len} poses ({eta})") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message("candidates");
    bar
}
