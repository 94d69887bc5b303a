//! The validation plan: random poses and printing-path runs as campaign steps, and the
//! measurements read back from the campaign's records.

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use vatcal_core::cell::MotionLimits;
use vatcal_core::{JointVector, Measurement, Target};
use vatcal_kinematics::Model;
use vatcal_planning::CellGeometry;
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::motion::{JointBounds, MOVE_MARGIN_DEG, MotionTimer, SingularityMargins};
use vatcal_planning::paths::{PathMethod, PathOptions, PathPlanner};
use vatcal_planning::tour::{TourCosts, TourOptions, solve_open_path};

use super::printing::{PrintingJointRules, command_printing_joints, plan_printing_joints};
use super::{
    PrintingPathError, PrintingPathOptions, PrintingSlice, RandomPoseOptions, ValidationError,
    ValidationPose, printing_path, random_validation_poses,
};
use crate::{Campaign, CampaignPlan, CampaignReport, CampaignStep, StepOutcome, StepRecord};

/// Options of [`build_validation_plan`].
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationPlanOptions {
    /// the random poses
    pub random: RandomPoseOptions,
    /// the printing path
    pub printing: PrintingPathOptions,
    /// inflation of the robot bodies in collision checks \[mm\]
    pub collision_margin_mm: f64,
    /// distance kept from the arm joint limits along the printing path \[deg\]
    pub printing_joint_margin_deg: f64,
    /// singularity margins along the printing path
    pub printing_singularity: SingularityMargins,
    /// largest arm-joint change between consecutive slices \[deg\] (no IK branch flips)
    pub printing_max_joint_step_deg: f64,
    /// guide start positions tried for the printing path
    pub printing_guide_candidates: usize,
    /// path planner between poses (straight joint moves when free, else RRT-Connect)
    pub paths: PathOptions,
    /// speeds (the metric of the pose order and of the path planner)
    pub motion: MotionLimits,
    /// where the robot is when the validation starts (`None`: the first move is a straight
    /// joint move from wherever it is)
    pub start: Option<JointVector>,
    /// restarts of the tour heuristic ordering the random poses
    pub tour_restarts: usize,
    /// seed of every random stage (poses, SMR choice, tour, RRT)
    pub seed: u64,
}

impl Default for ValidationPlanOptions {
    /// 573 random poses, the default 300-slice printing path, 2 mm collision margin, 5° joint
    /// margin, default singularity margins and at most 10° per slice along the printing path
    /// (a branch flip of the IK jumps by tens of degrees; 300 slices move by ~0.1°),
    /// 11 guide starts, default path planner and motion limits, 2 tour restarts, seed 1.
    fn default() -> Self {
        Self {
            random: RandomPoseOptions::default(),
            printing: PrintingPathOptions::default(),
            collision_margin_mm: 2.0,
            printing_joint_margin_deg: 5.0,
            printing_singularity: SingularityMargins::default(),
            printing_max_joint_step_deg: 10.0,
            printing_guide_candidates: 11,
            paths: PathOptions::default(),
            motion: MotionLimits::default(),
            start: None,
            tour_restarts: 2,
            seed: 1,
        }
    }
}

/// The printing path commanded by one model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PathRun {
    /// label of the commanding model (e.g. `nominal`, `calibrated`)
    pub label: String,
    /// joints of every slice (q1 mm, q2..q7 rad)
    pub joints: Vec<JointVector>,
}

/// Which planned measurement a `track` step takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TrackTarget {
    /// random pose `.0` (visiting order)
    Random(usize),
    /// slice `slice` of path run `run`
    Slice { run: usize, slice: usize },
}

/// A planned validation campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationPlan {
    /// the random poses in visiting order
    pub random_poses: Vec<ValidationPose>,
    /// the printing path
    pub slices: Vec<PrintingSlice>,
    /// the printing path commanded by each model, in execution order
    pub path_runs: Vec<PathRun>,
    /// SMR (TCP) ids measured at every slice
    pub slice_targets: Vec<u32>,
    /// the executable steps
    pub campaign: CampaignPlan,
    /// legs between poses that needed RRT-Connect (the others are straight joint moves)
    pub rrt_legs: usize,
    /// for every campaign step: the measurement it takes, if it is a `track` step
    targets: Vec<Option<TrackTarget>>,
}

/// Plans the validation campaign.
///
/// * `reference` is the model the robot controller believes (the nominal cell): collision
///   checks, random poses, joint limits and the printing path's guide start and IK branch use
///   it;
/// * `commanding` lists the models whose accuracy is measured along the printing path, each
///   commanding its own run (e.g. `[("nominal", &nominal), ("calibrated", &calibrated)]`);
/// * the random poses are ordered by the tour heuristic of `vatcal-planning` (joint-move time),
///   and every leg between consecutive poses is a verified collision-free path with the probe
///   removed;
/// * `opts.printing.slices == 0` plans no printing path (random poses only): what a chain
///   without the Meca500-on-guide's tank path is validated with (any serial chain).
///
/// # Errors
/// Invalid options or geometry, too few collision-free random poses, a printing path that no
/// model can command, a leg without a collision-free path.
pub fn build_validation_plan(
    reference: &Model,
    geometry: &CellGeometry,
    commanding: &[(&str, &Model)],
    opts: &ValidationPlanOptions,
) -> Result<ValidationPlan, ValidationError> {
    let checker = CollisionChecker::new(reference, geometry, opts.collision_margin_mm)?;
    let timer = MotionTimer::for_model(&opts.motion, reference)?;
    let poses = random_validation_poses(reference, &checker, &opts.random, opts.seed)?;
    let random_poses = order_poses(&poses, &timer, opts);
    // no printing path: random poses only (a chain without a guide and tank path). A random
    // pose the path planner cannot connect to its neighbour (a pocket of free space, or a
    // detour longer than the planner's iterations, on a ±360° arm) is dropped and the legs are
    // planned again: when both legs of a pose fail, that pose is the isolated one; when only
    // the leg into a pose fails, the pose it leads to. At most one pose in four is
    // dropped, which also bounds the rounds (each drops at least one); the validation
    // statistics need many poses, not these particular ones, and the report gives the count.
    if opts.printing.slices == 0 {
        let mut random_poses = random_poses;
        let max_drops = (random_poses.len() / 4).max(2);
        let mut drops = 0;
        let (campaign, targets, rrt_legs) = loop {
            let mut builder = StepBuilder::new(&checker, &timer, opts);
            builder.add_random(&random_poses);
            match builder.finish_indexed() {
                Ok(done) => break done,
                Err((failed, e)) => {
                    let drop = isolated_poses(&failed, random_poses.len());
                    if drop.is_empty() || drops + drop.len() > max_drops {
                        return Err(e);
                    }
                    drops += drop.len();
                    for k in drop.iter().rev() {
                        random_poses.remove(*k);
                    }
                }
            }
        };
        let slice_targets = Vec::new();
        return Ok(ValidationPlan {
            random_poses,
            slices: Vec::new(),
            path_runs: Vec::new(),
            slice_targets,
            campaign,
            rrt_legs,
            targets,
        });
    }
    let slices = printing_path(&opts.printing)?;
    let bounds = JointBounds::new(reference, opts.printing_joint_margin_deg, opts.random.guide_margin_mm)?;
    let rules = PrintingJointRules {
        bounds: &bounds,
        singularity: opts.printing_singularity,
        checker: &checker,
        max_joint_step_rad: opts.printing_max_joint_step_deg.to_radians(),
        guide_candidates: opts.printing_guide_candidates,
    };
    let reference_joints = plan_printing_joints(reference, &slices, &rules)?;
    let mut path_runs = Vec::with_capacity(commanding.len());
    for (label, model) in commanding {
        let joints = command_printing_joints(model, &slices, &reference_joints)?;
        if let Some((k, contact)) =
            joints.iter().enumerate().find_map(|(k, q)| checker.check(q, ProbeState::Absent).map(|c| (k, c)))
        {
            return Err(
                PrintingPathError::Collision { label: (*label).to_string(), slice: k, contact }.into()
            );
        }
        path_runs.push(PathRun { label: (*label).to_string(), joints });
    }
    let slice_targets = reference.tcp_ids();
    let mut builder = StepBuilder::new(&checker, &timer, opts);
    builder.add_random(&random_poses);
    for (run, r) in path_runs.iter().enumerate() {
        builder.add_run(run, r, &slice_targets);
    }
    let (campaign, targets, rrt_legs) = builder.finish()?;
    Ok(ValidationPlan { random_poses, slices, path_runs, slice_targets, campaign, rrt_legs, targets })
}

/// The poses to drop after the legs into the goals `failed` (ascending) failed: a pose whose
/// incoming and outgoing legs both failed is the isolated one; otherwise the goal of the failed
/// leg. Ascending, without repeats, all `< count`.
fn isolated_poses(failed: &[usize], count: usize) -> Vec<usize> {
    let blame_start = |k: usize| failed.binary_search(&(k - 1)).is_ok();
    let mut drop: Vec<usize> = failed
        .iter()
        .map(|&k| if k > 0 && blame_start(k) { k - 1 } else { k })
        .filter(|&k| k < count)
        .collect();
    drop.sort_unstable();
    drop.dedup();
    drop
}

/// The random poses in a short visiting order (joint-move time, from the start if given).
fn order_poses(
    poses: &[ValidationPose],
    timer: &MotionTimer,
    opts: &ValidationPlanOptions,
) -> Vec<ValidationPose> {
    let cost = |i: usize, j: usize| timer.move_time_s(&poses[i].q, &poses[j].q);
    let costs = match &opts.start {
        Some(s) => {
            let from_start = |j: usize| timer.move_time_s(s, &poses[j].q);
            TourCosts::new(poses.len(), cost, Some(&from_start))
        }
        None => TourCosts::new(poses.len(), cost, None),
    };
    let groups = vec![0u32; poses.len()];
    let tour = TourOptions { restarts: opts.tour_restarts.max(1), seed: opts.seed };
    solve_open_path(&costs, &groups, &tour).into_iter().map(|k| poses[k]).collect()
}

/// One goal of the campaign: a pose to reach and what to measure there.
struct Goal {
    q: JointVector,
    name: String,
    /// consecutive slices of a run are joined by direct moves (checked slice by slice)
    direct: bool,
    tracks: Vec<(u32, TrackTarget)>,
}

/// Collects goals, then plans the legs between them (in parallel) and emits the steps.
struct StepBuilder<'a> {
    checker: &'a CollisionChecker<'a>,
    timer: &'a MotionTimer,
    opts: &'a ValidationPlanOptions,
    goals: Vec<Goal>,
}

impl<'a> StepBuilder<'a> {
    fn new(
        checker: &'a CollisionChecker<'a>,
        timer: &'a MotionTimer,
        opts: &'a ValidationPlanOptions,
    ) -> Self {
        Self { checker, timer, opts, goals: Vec::new() }
    }

    fn add_random(&mut self, poses: &[ValidationPose]) {
        for (i, p) in poses.iter().enumerate() {
            self.goals.push(Goal {
                q: p.q,
                name: format!("random pose {i}"),
                direct: false,
                tracks: vec![(p.tcp, TrackTarget::Random(i))],
            });
        }
    }

    fn add_run(&mut self, run: usize, r: &PathRun, targets: &[u32]) {
        for (slice, q) in r.joints.iter().enumerate() {
            self.goals.push(Goal {
                q: *q,
                name: format!("`{}` slice {slice}", r.label),
                direct: slice > 0,
                tracks: targets.iter().map(|t| (*t, TrackTarget::Slice { run, slice })).collect(),
            });
        }
    }

    /// Plans every leg and returns the campaign plan, the step targets and the RRT leg count.
    fn finish(self) -> Result<(CampaignPlan, Vec<Option<TrackTarget>>, usize), ValidationError> {
        self.finish_indexed().map_err(|(_, e)| e)
    }

    /// [`StepBuilder::finish`]; a failure lists every goal whose leg failed (ascending) with the
    /// first error.
    #[allow(clippy::type_complexity)]
    fn finish_indexed(
        self,
    ) -> Result<(CampaignPlan, Vec<Option<TrackTarget>>, usize), (Vec<usize>, ValidationError)> {
        let reference = self.checker.model();
        let bounds = JointBounds::new(reference, MOVE_MARGIN_DEG, 0.0).map_err(|e| (Vec::new(), e.into()))?;
        let planner =
            PathPlanner { checker: self.checker, bounds: &bounds, timer: self.timer, opts: &self.opts.paths };
        let start = self.opts.start;
        let legs: Vec<Result<(Vec<JointVector>, bool), ValidationError>> = (0..self.goals.len())
            .into_par_iter()
            .map(|k| {
                let goal = &self.goals[k];
                let from = match k {
                    0 => match start {
                        Some(s) => (s, "the start pose".to_string()),
                        None => return Ok((vec![goal.q], false)),
                    },
                    _ => (self.goals[k - 1].q, self.goals[k - 1].name.clone()),
                };
                if goal.direct {
                    return Ok((vec![goal.q], false));
                }
                let seed = self.opts.seed ^ (k as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                let path = planner.plan(&from.0, &goal.q, ProbeState::Absent, seed).map_err(|f| {
                    ValidationError::NoPath {
                        from: from.1.clone(),
                        to: goal.name.clone(),
                        reason: f.to_string(),
                    }
                })?;
                let rrt = path.method == PathMethod::RrtConnect;
                Ok((path.waypoints.into_iter().skip(1).collect(), rrt))
            })
            .collect();
        let failed: Vec<usize> =
            legs.iter().enumerate().filter(|(_, l)| l.is_err()).map(|(k, _)| k).collect();
        let mut steps = Vec::new();
        let mut targets = Vec::new();
        let mut rrt_legs = 0;
        for (goal, leg) in self.goals.iter().zip(legs) {
            let (path, rrt) = leg.map_err(|e| (failed.clone(), e))?;
            rrt_legs += usize::from(rrt);
            steps.push(CampaignStep::Move { path });
            targets.push(None);
            for (tcp, target) in &goal.tracks {
                steps.push(CampaignStep::Track { tcp: *tcp });
                targets.push(Some(*target));
            }
        }
        Ok((CampaignPlan { steps }, targets, rrt_legs))
    }
}

/// The tracker measurements of one slice.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SliceRecord {
    /// one tracker measurement per SMR (joints as read back after the move)
    pub measurements: Vec<Measurement>,
}

impl SliceRecord {
    /// The measured SMRs: `(tcp, world position [mm])`.
    pub fn smr_positions(&self) -> Vec<(u32, nalgebra::Vector3<f64>)> {
        self.measurements
            .iter()
            .filter_map(|m| match m.target {
                Target::Tracker { xyz_mm } => Some((m.tcp, xyz_mm)),
                Target::Probe { .. } | Target::Orientation { .. } | Target::Plane { .. } => None,
            })
            .collect()
    }
}

/// The measurements of one printing-path run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PathRecords {
    /// label of the commanding model
    pub label: String,
    /// one record per slice
    pub slices: Vec<SliceRecord>,
}

/// Everything a validation campaign measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationRecords {
    /// one tracker measurement per random pose, in visiting order
    pub random: Vec<Measurement>,
    /// one record per printing-path run
    pub paths: Vec<PathRecords>,
    /// tracker points the campaign skipped (line of sight lost after the retries, with
    /// `skip_failed_tracks`): random poses left out, SMRs missing from their slice
    #[serde(default, skip_serializing_if = "is_zero")]
    pub skipped: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl ValidationRecords {
    /// The tracker measurements of path run `label`, slice by slice (for a CSV).
    pub fn path_measurements(&self, label: &str) -> Vec<Measurement> {
        self.paths
            .iter()
            .filter(|p| p.label == label)
            .flat_map(|p| p.slices.iter().flat_map(|s| s.measurements.iter().copied()))
            .collect()
    }
}

impl ValidationPlan {
    /// Number of tracker measurements the plan takes.
    pub fn measurement_count(&self) -> usize {
        self.campaign.measurement_count()
    }

    /// Runs the plan with `campaign` (devices with a tracker, the controller model, the
    /// settings), journaling into `journal`, and reads the measurements back. A journal of
    /// the same plan is resumed, like any campaign.
    ///
    /// # Errors
    /// The campaign's errors; records that do not hold every planned measurement.
    pub fn run(
        &self,
        campaign: &mut Campaign<'_>,
        journal: impl AsRef<Path>,
    ) -> Result<ValidationRecords, ValidationError> {
        let report: CampaignReport = campaign.run(&self.campaign, journal)?;
        self.collect(&report.records)
    }

    /// The validation measurements held by the campaign records of this plan (e.g. the
    /// records of a journal).
    ///
    /// # Errors
    /// A planned measurement is missing, or a record does not match its step.
    pub fn collect(&self, records: &[StepRecord]) -> Result<ValidationRecords, ValidationError> {
        let mut random: Vec<Option<Measurement>> = vec![None; self.random_poses.len()];
        let mut paths: Vec<PathRecords> = self
            .path_runs
            .iter()
            .map(|r| PathRecords {
                label: r.label.clone(),
                slices: vec![SliceRecord { measurements: Vec::new() }; r.joints.len()],
            })
            .collect();
        let mut skipped = 0;
        let mut skipped_random = vec![false; self.random_poses.len()];
        let mut skipped_smrs = 0;
        for r in records {
            let Some(Some(target)) = self.targets.get(r.step) else { continue };
            let m = match (&r.outcome, r.measurement()) {
                (StepOutcome::Tracked { .. }, Some(m)) => m,
                (StepOutcome::Skipped { .. }, _) => {
                    skipped += 1;
                    match *target {
                        TrackTarget::Random(i) => skipped_random[i] = true,
                        TrackTarget::Slice { .. } => skipped_smrs += 1,
                    }
                    continue;
                }
                (other, _) => {
                    return Err(ValidationError::Incomplete(format!(
                        "step {} should be a tracker measurement, the record holds {other:?}",
                        r.step
                    )));
                }
            };
            match *target {
                TrackTarget::Random(i) => random[i] = Some(m),
                TrackTarget::Slice { run, slice } => paths[run].slices[slice].measurements.push(m),
            }
        }
        let random = random
            .into_iter()
            .enumerate()
            .filter(|(i, _)| !skipped_random[*i])
            .map(|(i, m)| {
                m.ok_or_else(|| ValidationError::Incomplete(format!("random pose {i} was not measured")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let planned = self.slice_targets.len();
        for p in &paths {
            // a skipped SMR leaves its slice short (the slice is left out of the evaluation when
            // fewer than three remain); an unrecorded one makes the records incomplete
            if let Some(k) = p.slices.iter().position(|s| s.measurements.len() > planned) {
                return Err(ValidationError::Incomplete(format!(
                    "`{}` slice {k}: {} of {} SMRs measured",
                    p.label,
                    p.slices[k].measurements.len(),
                    self.slice_targets.len()
                )));
            }
        }
        let missing: usize =
            paths.iter().flat_map(|p| &p.slices).map(|s| planned.saturating_sub(s.measurements.len())).sum();
        if missing > skipped_smrs {
            return Err(ValidationError::Incomplete(format!(
                "{} printing-path SMR measurements were neither recorded nor skipped",
                missing - skipped_smrs
            )));
        }
        Ok(ValidationRecords { random, paths, skipped })
    }
}

#[cfg(test)]
mod tests {
    use super::isolated_poses;

    #[test]
    fn the_pose_whose_both_legs_fail_is_the_one_dropped() {
        // pose 4 isolated: the legs into 4 and into 5 (out of 4) fail
        assert_eq!(isolated_poses(&[4, 5], 10), vec![4]);
        // only the leg into 7 fails: drop 7
        assert_eq!(isolated_poses(&[7], 10), vec![7]);
        // two separate failures, one isolated pose and one single leg
        assert_eq!(isolated_poses(&[2, 3, 8], 10), vec![2, 8]);
        // the first pose's leg (from the start pose) fails
        assert_eq!(isolated_poses(&[0, 1], 5), vec![0]);
        assert!(isolated_poses(&[], 5).is_empty());
    }
}
