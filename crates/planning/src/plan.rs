//! The whole planning pipeline: candidates → Detmax selection → tour → paths.

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use rayon::prelude::*;
use serde::Serialize;
use vatcal_core::cell::MotionLimits;
use vatcal_core::{JointVector, Measurement, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax};
use vatcal_observability::{ColumnScaling, ObservabilityIndices, observability_indices};

use crate::candidates::{CandidateOptions, CandidateSet, StageCounts, generate_candidates};
use crate::collision::{CollisionChecker, ProbeState};
use crate::error::PlanError;
use crate::geometry::CellGeometry;
use crate::motion::{JointBounds, MOVE_MARGIN_DEG, MotionTimer};
use crate::paths::{JointPath, PathMethod, PathOptions, PathPlanner};
use crate::tour::{TourCosts, TourOptions, solve_open_path};

/// Options of [`plan_campaign`].
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOptions {
    /// candidate generation (its `seed` is replaced by [`PlanOptions::seed`])
    pub candidates: CandidateOptions,
    /// number of measurements to select (paper: 40)
    pub count: usize,
    /// parameters the selection must identify (default: the paper's 34); an empty set means
    /// the model's default set for the candidates
    /// (`vatcal_observability::identifiability::default_params`: the paper's 34 on the
    /// canonical cell, the identifiable basis of all parameters on any other chain)
    pub params: ParamSet,
    /// Detmax restarts
    pub detmax_restarts: usize,
    /// tour heuristic restarts
    pub tour_restarts: usize,
    /// path planner options
    pub paths: PathOptions,
    /// speeds and fixed times (the cell's `[motion]` table)
    pub motion: MotionLimits,
    /// robot configuration at the start of the campaign (`None`: start at the first
    /// measurement's retreat pose)
    pub start: Option<JointVector>,
    /// master seed of every random stage (orientations, Detmax, tour restarts, RRT)
    pub seed: u64,
}

impl Default for PlanOptions {
    fn default() -> Self {
        Self {
            candidates: CandidateOptions::default(),
            count: 40,
            params: ParamSet::paper34(),
            detmax_restarts: 8,
            tour_restarts: 16,
            paths: PathOptions::default(),
            motion: MotionLimits::default(),
            start: None,
            seed: 1,
        }
    }
}

/// What a tour step asks the campaign to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StepKind {
    /// joint move to `q` (a waypoint of a collision-free path; the last one before a
    /// measurement and the one right after it are the retreat pose)
    Move,
    /// straight joint move from the retreat pose down to `q`, auto-centre TCP `tcp` on the
    /// probe at `position`, record the joints
    Measure,
    /// pause: the operator places the probe plate at `position` (the robot stays at `q`)
    ReplaceProbe,
}

impl StepKind {
    /// Name used in `tour.csv`.
    pub fn name(self) -> &'static str {
        match self {
            StepKind::Move => "move",
            StepKind::Measure => "measure",
            StepKind::ReplaceProbe => "replace_probe",
        }
    }
}

/// One row of the executable tour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TourStep {
    /// what to do
    pub kind: StepKind,
    /// calibration position where the probe is (or goes, for `ReplaceProbe`)
    pub position: u32,
    /// TCP of the current or next measurement
    pub tcp: u32,
    /// target joints
    pub q: JointVector,
    /// estimated campaign time at the end of this step (s)
    pub time_s: f64,
}

/// One leg of the tour: the path from the previous retreat pose to the next one.
#[derive(Debug, Clone, PartialEq)]
pub struct Leg {
    /// the verified path
    pub path: JointPath,
    /// calibration position of the probe during the leg
    pub position: u32,
    /// whether the probe plate is re-placed before the leg
    pub replace_probe: bool,
}

/// Estimated campaign durations (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Timing {
    /// the optimised order, straight joint moves between retreat poses
    pub ordered_s: f64,
    /// the optimised order along the planned (collision-free) paths
    pub planned_paths_s: f64,
    /// Detmax output order (candidate order: grouped by position, arbitrary inside)
    pub selection_order_s: f64,
    /// a seeded random shuffle of the selection
    pub shuffled_order_s: f64,
    /// probe re-placements in the optimised order
    pub replacements: usize,
    /// probe re-placements in the shuffled order
    pub shuffled_replacements: usize,
}

/// Quality of the selection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectionQuality {
    /// O1..O5 in natural units (mm per mm, rad, rad/(N·m)) — the paper's O1 convention
    pub raw: ObservabilityIndices,
    /// O1..O5 of the unit-column-norm Jacobian (column norms of the selection)
    pub unit_norm: ObservabilityIndices,
    /// O1 (natural units) of the whole candidate set, for comparison
    pub candidates_o1: f64,
    /// Detmax log-determinant of the selection
    pub log_det: f64,
}

/// A planned campaign.
#[derive(Debug, Clone)]
pub struct Plan {
    /// the candidate set with its stage counts
    pub candidates: CandidateSet,
    /// Detmax selection: indices into `candidates.candidates`, ascending
    pub selected: Vec<usize>,
    /// quality of the selection
    pub quality: SelectionQuality,
    /// visiting order: indices into `candidates.candidates`
    pub order: Vec<usize>,
    /// one leg per measurement in `order` (the path to its retreat pose)
    pub legs: Vec<Leg>,
    /// the executable tour
    pub steps: Vec<TourStep>,
    /// durations
    pub timing: Timing,
    /// the parameters the selection identifies ([`PlanOptions::params`], or the model's
    /// default set when that was empty)
    pub params: ParamSet,
}

impl Plan {
    /// The selected candidates in visiting order, as probe measurements (for simulation or
    /// identification).
    pub fn measurements(&self) -> Vec<Measurement> {
        self.order
            .iter()
            .map(|&i| {
                let c = &self.candidates.candidates[i];
                Measurement::probe(c.position, c.tcp, c.q)
            })
            .collect()
    }

    /// The stage counts (candidate generation) plus the selected count.
    pub fn counts(&self) -> (StageCounts, usize) {
        (self.candidates.counts, self.selected.len())
    }
}

/// Plans a measurement campaign: candidate poses (IK, limits, singularities, collisions),
/// Detmax selection of `count` of them, the time-optimal visiting order, and a verified
/// collision-free path for every leg.
///
/// # Examples
/// A small campaign for the Meca500 alone on a table (`examples/plan_campaign.rs` prints it):
/// ```
/// use vatcal_core::{CellFile, ParamSet};
/// use vatcal_kinematics::Model;
/// use vatcal_planning::candidates::CandidateOptions;
/// use vatcal_planning::plan::{PlanOptions, StepKind, plan_campaign};
/// use vatcal_planning::CellGeometry;
///
/// let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-table.toml"))?;
/// let model = Model::from_cell(&cell)?;
/// let opts = PlanOptions {
///     candidates: CandidateOptions { orientations: 12, ..CandidateOptions::default() },
///     params: ParamSet(Vec::new()), // the chain's identifiable default set
///     detmax_restarts: 1,
///     tour_restarts: 2,
///     motion: cell.motion_limits(),
///     seed: 4,
///     ..PlanOptions::default()
/// };
/// let plan = plan_campaign(&model, &CellGeometry::from_cell(&cell)?, &opts)?;
/// assert_eq!(plan.selected.len(), 40);
/// assert_eq!(plan.quality.raw.rank, plan.params.len()); // the selection identifies the set
/// assert_eq!(plan.steps.iter().filter(|s| s.kind == StepKind::Measure).count(), 40);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`PlanError::Option`] for an invalid option (naming it); [`PlanError::UnsupportedArm`] for an
/// arm the closed-form IK does not support; [`PlanError::Empty`] when no candidate survives the
/// screening; [`PlanError::Selection`] when Detmax fails (e.g. too few candidates, or candidates
/// that cannot identify the parameters); [`PlanError::NoPath`] for a leg with no collision-free
/// path; [`PlanError::Model`] for a model error.
pub fn plan_campaign(model: &Model, geometry: &CellGeometry, opts: &PlanOptions) -> Result<Plan, PlanError> {
    if opts.count == 0 {
        return Err(PlanError::Option { option: "count".into(), reason: "must be at least 1".into() });
    }
    let candidates = campaign_candidates(model, geometry, opts)?;
    if candidates.candidates.len() < opts.count {
        return Err(PlanError::Empty(format!(
            "only {} measurable candidates for {} requested measurements (stage counts: {:?})",
            candidates.candidates.len(),
            opts.count,
            candidates.counts
        )));
    }
    let measurements: Vec<Measurement> =
        candidates.candidates.iter().map(|c| Measurement::probe(c.position, c.tcp, c.q)).collect();
    let opts = &with_resolved_params(model, &measurements, opts)?;
    let (selected, quality) = select(model, &candidates, opts)?;
    plan_tour(model, geometry, candidates, selected, quality, opts)
}

/// `opts` with an empty parameter set replaced by the chain's default set on `measurements`
/// (`vatcal_observability::identifiability::default_params`).
fn with_resolved_params(
    model: &Model,
    measurements: &[Measurement],
    opts: &PlanOptions,
) -> Result<PlanOptions, PlanError> {
    if !opts.params.is_empty() {
        return Ok(opts.clone());
    }
    let params = vatcal_observability::identifiability::default_params(model, measurements)
        .map_err(PlanError::Selection)?;
    Ok(PlanOptions { params, ..opts.clone() })
}

/// The candidate poses [`plan_campaign`] selects from (IK, limits, singularities, collisions),
/// generated with `opts.candidates` and `opts.seed`.
///
/// # Errors
/// As [`plan_campaign`]'s candidate stage.
pub fn campaign_candidates(
    model: &Model,
    geometry: &CellGeometry,
    opts: &PlanOptions,
) -> Result<CandidateSet, PlanError> {
    let checker = CollisionChecker::new(model, geometry, opts.candidates.collision_margin_mm)?;
    let cand_opts = CandidateOptions { seed: opts.seed, ..opts.candidates.clone() };
    generate_candidates(model, &checker, &cand_opts)
}

/// A plan of a selection made elsewhere (e.g. the measurements discovery proposes to decide a
/// candidate effect, `vatcal discover --propose`): `selected` indexes `candidates` (from
/// [`campaign_candidates`]); the visiting order, the collision-free paths and the timing are
/// planned as [`plan_campaign`] plans them, and the quality indices are those of the selection
/// for `opts.params` (the chain's default set when empty).
///
/// # Errors
/// An index outside the candidates, an empty selection, or as [`plan_campaign`]'s tour and path
/// stages.
pub fn plan_selection(
    model: &Model,
    geometry: &CellGeometry,
    candidates: CandidateSet,
    selected: Vec<usize>,
    opts: &PlanOptions,
) -> Result<Plan, PlanError> {
    if selected.is_empty() || selected.iter().any(|i| *i >= candidates.candidates.len()) {
        return Err(PlanError::Option {
            option: "selection".into(),
            reason: format!("{} indices into {} candidates", selected.len(), candidates.candidates.len()),
        });
    }
    let measurements: Vec<Measurement> =
        candidates.candidates.iter().map(|c| Measurement::probe(c.position, c.tcp, c.q)).collect();
    let opts = &with_resolved_params(model, &measurements, opts)?;
    let cands =
        Candidates::from_measurements(model, &measurements, &opts.params).map_err(PlanError::Selection)?;
    let log_det = vatcal_observability::detmax::log_det(&cands, &selected, 0.0).unwrap_or(f64::NEG_INFINITY);
    let quality = selection_quality(&cands, &selected, log_det, &opts.params)?;
    let mut selected = selected;
    selected.sort_unstable();
    plan_tour(model, geometry, candidates, selected, quality, opts)
}

/// Order, paths, steps and timing of a selection.
fn plan_tour(
    model: &Model,
    geometry: &CellGeometry,
    candidates: CandidateSet,
    selected: Vec<usize>,
    quality: SelectionQuality,
    opts: &PlanOptions,
) -> Result<Plan, PlanError> {
    let timer = MotionTimer::for_model(&opts.motion, model)?;
    let checker = CollisionChecker::new(model, geometry, opts.candidates.collision_margin_mm)?;
    let order = order_tour(&candidates, &selected, &timer, opts);
    let bounds = JointBounds::new(model, MOVE_MARGIN_DEG.min(opts.candidates.joint_margin_deg), 0.0)?;
    let legs = plan_legs(&checker, &bounds, &timer, &candidates, &order, opts)?;
    let steps = build_steps(&candidates, &order, &legs, &timer, opts.start.is_some());
    let timing = timing(&candidates, &selected, &order, &legs, &timer, opts);
    Ok(Plan { candidates, selected, quality, order, legs, steps, timing, params: opts.params.clone() })
}

fn select(
    model: &Model,
    set: &CandidateSet,
    opts: &PlanOptions,
) -> Result<(Vec<usize>, SelectionQuality), PlanError> {
    let err = PlanError::Selection;
    let measurements: Vec<Measurement> =
        set.candidates.iter().map(|c| Measurement::probe(c.position, c.tcp, c.q)).collect();
    let cands = Candidates::from_measurements(model, &measurements, &opts.params).map_err(err)?;
    let mut d = DetmaxOptions::new(opts.count);
    d.restarts = opts.detmax_restarts.max(1);
    d.seed = opts.seed;
    let selection = detmax(&cands, &d).map_err(err)?;
    let quality = selection_quality(&cands, &selection.selected, selection.log_det, &opts.params)?;
    Ok((selection.selected.clone(), quality))
}

/// Observability indices of the selection `selected` of `cands`.
fn selection_quality(
    cands: &Candidates,
    selected: &[usize],
    log_det: f64,
    params: &ParamSet,
) -> Result<SelectionQuality, PlanError> {
    let err = PlanError::Selection;
    let jac = cands.design_jacobian(selected);
    let raw = observability_indices(jac.as_ref(), params, ColumnScaling::None).map_err(err)?;
    let unit_norm = observability_indices(jac.as_ref(), params, ColumnScaling::UnitNorm).map_err(err)?;
    let all = observability_indices(cands.stacked(), params, ColumnScaling::None).map_err(err)?;
    Ok(SelectionQuality { raw, unit_norm, candidates_o1: all.o1, log_det })
}

/// Tour costs between the retreat poses of `nodes` (candidate indices).
fn tour_costs(
    set: &CandidateSet,
    nodes: &[usize],
    timer: &MotionTimer,
    start: Option<&JointVector>,
) -> TourCosts {
    let c = |i: usize| &set.candidates[nodes[i]];
    let cost = |i: usize, j: usize| {
        let replace = if c(i).position != c(j).position { timer.probe_replacement_s } else { 0.0 };
        timer.move_time_s(&c(i).retreat, &c(j).retreat) + replace
    };
    match start {
        Some(s) => {
            let from_start = |j: usize| timer.move_time_s(s, &c(j).retreat);
            TourCosts::new(nodes.len(), cost, Some(&from_start))
        }
        None => TourCosts::new(nodes.len(), cost, None),
    }
}

fn order_tour(set: &CandidateSet, nodes: &[usize], timer: &MotionTimer, opts: &PlanOptions) -> Vec<usize> {
    let costs = tour_costs(set, nodes, timer, opts.start.as_ref());
    let groups: Vec<u32> = nodes.iter().map(|&i| set.candidates[i].position).collect();
    let tour = TourOptions { restarts: opts.tour_restarts.max(1), seed: opts.seed };
    solve_open_path(&costs, &groups, &tour).into_iter().map(|k| nodes[k]).collect()
}

/// Estimated duration of visiting `order` with straight moves (+ descent, auto-centring, retreat
/// and re-placement times).
fn estimated_time(
    set: &CandidateSet,
    order: &[usize],
    timer: &MotionTimer,
    start: Option<&JointVector>,
) -> (f64, usize) {
    let mut t = 0.0;
    let mut replacements = 0;
    let mut prev: Option<&crate::candidates::Candidate> = None;
    for &i in order {
        let c = &set.candidates[i];
        match prev {
            Some(p) => {
                t += timer.move_time_s(&p.retreat, &c.retreat);
                if p.position != c.position {
                    t += timer.probe_replacement_s;
                    replacements += 1;
                }
            }
            None => t += start.map_or(0.0, |s| timer.move_time_s(s, &c.retreat)),
        }
        t += per_measurement_s(c, timer);
        prev = Some(c);
    }
    (t, replacements)
}

/// Descent, auto-centring and retreat of one measurement (s).
fn per_measurement_s(c: &crate::candidates::Candidate, timer: &MotionTimer) -> f64 {
    2.0 * timer.move_time_s(&c.retreat, &c.q) + timer.measurement_s
}

fn leg_origin(leg: usize) -> String {
    if leg == 0 { "the start pose".into() } else { format!("measurement {leg}") }
}

fn leg_seed(seed: u64, leg: usize) -> u64 {
    seed ^ (leg as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

fn plan_legs(
    checker: &CollisionChecker<'_>,
    bounds: &JointBounds,
    timer: &MotionTimer,
    set: &CandidateSet,
    order: &[usize],
    opts: &PlanOptions,
) -> Result<Vec<Leg>, PlanError> {
    let planner = PathPlanner { checker, bounds, timer, opts: &opts.paths };
    let results: Vec<Result<Leg, PlanError>> = (0..order.len())
        .into_par_iter()
        .map(|k| {
            let c = &set.candidates[order[k]];
            let (from, replace_probe) = match k {
                0 => match &opts.start {
                    Some(s) => (*s, false),
                    None => (c.retreat, false),
                },
                _ => {
                    let p = &set.candidates[order[k - 1]];
                    (p.retreat, p.position != c.position)
                }
            };
            let probe = ProbeState::At { position: c.position };
            if from == c.retreat {
                if let Some(contact) = checker.check(&from, probe) {
                    return Err(PlanError::NoPath {
                        measurement: k + 1,
                        from: leg_origin(k),
                        reason: format!("retreat pose in collision ({contact})"),
                    });
                }
                let path = JointPath { waypoints: vec![from], method: PathMethod::Straight };
                return Ok(Leg { path, position: c.position, replace_probe });
            }
            let path = planner.plan(&from, &c.retreat, probe, leg_seed(opts.seed, k)).map_err(|f| {
                PlanError::NoPath { measurement: k + 1, from: leg_origin(k), reason: f.to_string() }
            })?;
            Ok(Leg { path, position: c.position, replace_probe })
        })
        .collect();
    results.into_iter().collect()
}

fn build_steps(
    set: &CandidateSet,
    order: &[usize],
    legs: &[Leg],
    timer: &MotionTimer,
    has_start: bool,
) -> Vec<TourStep> {
    let mut steps = Vec::new();
    let mut t = 0.0;
    for (k, (&i, leg)) in order.iter().zip(legs).enumerate() {
        let c = &set.candidates[i];
        let from = leg.path.waypoints.first().copied().unwrap_or(c.retreat);
        if k == 0 {
            // the initial placement of the plate (set-up: no time counted)
            steps.push(TourStep {
                kind: StepKind::ReplaceProbe,
                position: c.position,
                tcp: c.tcp,
                q: from,
                time_s: t,
            });
        } else if leg.replace_probe {
            t += timer.probe_replacement_s;
            steps.push(TourStep {
                kind: StepKind::ReplaceProbe,
                position: c.position,
                tcp: c.tcp,
                q: from,
                time_s: t,
            });
        }
        let skip = if k == 0 && !has_start { 0 } else { 1 };
        let mut prev = from;
        for w in leg.path.waypoints.iter().skip(skip) {
            t += timer.move_time_s(&prev, w);
            steps.push(TourStep { kind: StepKind::Move, position: c.position, tcp: c.tcp, q: *w, time_s: t });
            prev = *w;
        }
        t += timer.move_time_s(&c.retreat, &c.q) + timer.measurement_s;
        steps.push(TourStep { kind: StepKind::Measure, position: c.position, tcp: c.tcp, q: c.q, time_s: t });
        t += timer.move_time_s(&c.q, &c.retreat);
        steps.push(TourStep {
            kind: StepKind::Move,
            position: c.position,
            tcp: c.tcp,
            q: c.retreat,
            time_s: t,
        });
    }
    steps
}

fn timing(
    set: &CandidateSet,
    selected: &[usize],
    order: &[usize],
    legs: &[Leg],
    timer: &MotionTimer,
    opts: &PlanOptions,
) -> Timing {
    let start = opts.start.as_ref();
    let (ordered_s, replacements) = estimated_time(set, order, timer, start);
    let (selection_order_s, _) = estimated_time(set, selected, timer, start);
    let mut shuffled = selected.to_vec();
    shuffled.shuffle(&mut ChaCha8Rng::seed_from_u64(opts.seed));
    let (shuffled_order_s, shuffled_replacements) = estimated_time(set, &shuffled, timer, start);
    let planned_paths_s = legs.iter().map(|l| timer.path_time_s(&l.path.waypoints)).sum::<f64>()
        + replacements as f64 * timer.probe_replacement_s
        + order.iter().map(|&i| per_measurement_s(&set.candidates[i], timer)).sum::<f64>();
    Timing {
        ordered_s,
        planned_paths_s,
        selection_order_s,
        shuffled_order_s,
        replacements,
        shuffled_replacements,
    }
}

/// Number of legs that needed RRT-Connect.
pub fn rrt_legs(plan: &Plan) -> usize {
    plan.legs.iter().filter(|l| l.path.method == PathMethod::RrtConnect).count()
}
