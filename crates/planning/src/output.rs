//! Files written by `vatcal plan` (see `docs/planning.md`).
//!
//! * `candidates.csv`, `selected.csv`: `position,tcp,q1..qN` (mm for prismatic, deg for
//!   revolute joints; N = 7 on the canonical cell) — the candidate-pose format of
//!   `docs/formats.md`;
//! * `tour.csv`: `step,kind,position,tcp,q1..qN,time_s` — the executable tour;
//! * `summary.json`: counts, observability indices, times ([`PlanSummary`]).

use std::path::Path;

use serde::Serialize;
use vatcal_core::{JointKind, JointVector};

use crate::candidates::{Candidate, StageCounts};
use crate::error::PlanError;
use crate::plan::{Plan, Timing, TourStep, rrt_legs};

use vatcal_core::MECA500_ON_GUIDE_KINDS as CANONICAL_KINDS;

/// Column names `q1..qN`.
fn joint_columns(n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("q{i}")).collect()
}

/// The path named by errors of CSV text built in memory.
const MEMORY: &str = "<memory>";

fn write_error(path: &Path, e: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> PlanError {
    PlanError::Write { path: path.to_path_buf(), source: e.into() }
}

fn joint_fields(q: &JointVector, kinds: &[JointKind]) -> impl Iterator<Item = String> {
    q.to_file_units(kinds).into_iter().map(|v| v.to_string())
}

/// CSV text `position,tcp,q1..q7` of candidates of the canonical cell (mm, deg, round-trip
/// precision).
pub fn candidates_csv<'a>(candidates: impl IntoIterator<Item = &'a Candidate>) -> Result<String, PlanError> {
    candidates_csv_for(candidates, &CANONICAL_KINDS)
}

/// CSV text `position,tcp,q1..qN` of candidates of a chain with joints `kinds` (mm for
/// prismatic, deg for revolute joints, round-trip precision).
pub fn candidates_csv_for<'a>(
    candidates: impl IntoIterator<Item = &'a Candidate>,
    kinds: &[JointKind],
) -> Result<String, PlanError> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let header = ["position".to_string(), "tcp".to_string()].into_iter().chain(joint_columns(kinds.len()));
    let e = |e: csv::Error| write_error(Path::new(MEMORY), e);
    w.write_record(header).map_err(e)?;
    for c in candidates {
        let rec = [c.position.to_string(), c.tcp.to_string()].into_iter().chain(joint_fields(&c.q, kinds));
        w.write_record(rec).map_err(e)?;
    }
    let bytes = w.into_inner().map_err(|e| write_error(Path::new(MEMORY), e.into_error()))?;
    String::from_utf8(bytes).map_err(|e| write_error(Path::new(MEMORY), e))
}

/// CSV text of the tour of the canonical cell: `step,kind,position,tcp,q1..q7,time_s`.
pub fn tour_csv(steps: &[TourStep]) -> Result<String, PlanError> {
    tour_csv_for(steps, &CANONICAL_KINDS)
}

/// CSV text of the tour of a chain with joints `kinds`: `step,kind,position,tcp,q1..qN,time_s`.
pub fn tour_csv_for(steps: &[TourStep], kinds: &[JointKind]) -> Result<String, PlanError> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let e = |e: csv::Error| write_error(Path::new(MEMORY), e);
    let header = ["step", "kind", "position", "tcp"]
        .into_iter()
        .map(String::from)
        .chain(joint_columns(kinds.len()))
        .chain(["time_s".to_string()]);
    w.write_record(header).map_err(e)?;
    for (k, s) in steps.iter().enumerate() {
        let rec = [k.to_string(), s.kind.name().to_string(), s.position.to_string(), s.tcp.to_string()]
            .into_iter()
            .chain(joint_fields(&s.q, kinds))
            .chain([format!("{:.3}", s.time_s)]);
        w.write_record(rec).map_err(e)?;
    }
    let bytes = w.into_inner().map_err(|e| write_error(Path::new(MEMORY), e.into_error()))?;
    String::from_utf8(bytes).map_err(|e| write_error(Path::new(MEMORY), e))
}

/// Observability indices as written to `summary.json`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IndicesSummary {
    /// O1
    pub o1: f64,
    /// O2
    pub o2: f64,
    /// O3
    pub o3: f64,
    /// O4
    pub o4: f64,
    /// O5
    pub o5: f64,
    /// numerical rank
    pub rank: usize,
    /// condition number
    pub condition_number: f64,
}

impl From<&vatcal_observability::ObservabilityIndices> for IndicesSummary {
    fn from(i: &vatcal_observability::ObservabilityIndices) -> Self {
        Self {
            o1: i.o1,
            o2: i.o2,
            o3: i.o3,
            o4: i.o4,
            o5: i.o5,
            rank: i.rank,
            condition_number: i.condition_number,
        }
    }
}

/// Contents of `summary.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlanSummary {
    /// candidate counts per stage
    pub counts: StageCounts,
    /// guide positions used (mm)
    pub guide_positions_mm: Vec<f64>,
    /// number of selected measurements
    pub selected: usize,
    /// selected measurements per calibration position `[(position, count)]`
    pub selected_per_position: Vec<(u32, usize)>,
    /// number of parameters of the selection criterion
    pub parameters: usize,
    /// O1..O5 in natural units (paper convention)
    pub observability_raw: IndicesSummary,
    /// O1..O5 with unit-norm columns
    pub observability_unit_norm: IndicesSummary,
    /// O1 of the whole candidate set (natural units)
    pub candidates_o1: f64,
    /// durations (s)
    pub timing: Timing,
    /// legs that needed RRT-Connect (the others are straight joint moves)
    pub rrt_legs: usize,
    /// rows of tour.csv
    pub tour_steps: usize,
    /// the IK that solved the candidate poses (printed by [`PlanSummary::text`]; not written to
    /// `summary.json`, which stays as it was)
    #[serde(skip)]
    pub ik: String,
}

impl PlanSummary {
    /// Summarises a plan.
    pub fn of(plan: &Plan) -> Self {
        let mut per_position: Vec<(u32, usize)> = Vec::new();
        for &i in &plan.order {
            let p = plan.candidates.candidates[i].position;
            match per_position.iter_mut().find(|e| e.0 == p) {
                Some(e) => e.1 += 1,
                None => per_position.push((p, 1)),
            }
        }
        Self {
            counts: plan.candidates.counts,
            guide_positions_mm: plan.candidates.guide_positions_mm.clone(),
            selected: plan.selected.len(),
            selected_per_position: per_position,
            parameters: plan.quality.raw.parameter_count,
            observability_raw: (&plan.quality.raw).into(),
            observability_unit_norm: (&plan.quality.unit_norm).into(),
            candidates_o1: plan.quality.candidates_o1,
            timing: plan.timing,
            rrt_legs: rrt_legs(plan),
            tour_steps: plan.steps.len(),
            ik: plan.candidates.ik.to_string(),
        }
    }

    /// A human-readable multi-line summary.
    pub fn text(&self) -> String {
        let c = &self.counts;
        let t = &self.timing;
        let r = &self.observability_raw;
        let u = &self.observability_unit_norm;
        let per: Vec<String> =
            self.selected_per_position.iter().map(|(p, n)| format!("position {p}: {n}")).collect();
        format!(
            "candidates per stage:\n  TCP poses                {}\n  IK solutions             {}\n  within joint limits      {}\n  clear of singularities   {}\n  collision-free           {}\n  retreat pose clear (N)   {}\n\
             selected: {} ({})\n\
             observability (natural units, {} parameters): O1 {:.3}  O2 {:.3e}  O3 {:.3e}  O4 {:.3e}  O5 {:.3e}  rank {}  cond {:.3e}\n\
             observability (unit-norm columns):             O1 {:.3}  O2 {:.3e}  O3 {:.3e}  O4 {:.3e}  O5 {:.3e}  cond {:.3e}\n\
             O1 of all {} candidates: {:.3}\n\
             estimated measurement time: ordered {:.0} s ({:.1} min, {} re-placements), along planned paths {:.0} s; \
             unordered (selection order) {:.0} s, shuffled {:.0} s ({} re-placements)\n\
             tour: {} steps, {} of {} legs needed RRT-Connect\n\
             IK: {}",
            c.poses,
            c.ik_solutions,
            c.within_limits,
            c.clear_of_singularities,
            c.collision_free,
            c.retreat_clear,
            self.selected,
            per.join(", "),
            self.parameters,
            r.o1,
            r.o2,
            r.o3,
            r.o4,
            r.o5,
            r.rank,
            r.condition_number,
            u.o1,
            u.o2,
            u.o3,
            u.o4,
            u.o5,
            u.condition_number,
            c.retreat_clear,
            self.candidates_o1,
            t.ordered_s,
            t.ordered_s / 60.0,
            t.replacements,
            t.planned_paths_s,
            t.selection_order_s,
            t.shuffled_order_s,
            t.shuffled_replacements,
            self.tour_steps,
            self.rrt_legs,
            self.selected,
            self.ik,
        )
    }
}

fn write_text(path: &Path, text: &str) -> Result<(), PlanError> {
    std::fs::write(path, text).map_err(|e| write_error(path, e))
}

/// Writes `candidates.csv`, `selected.csv` (in visiting order), `tour.csv` and `summary.json`
/// into `dir` (created if missing). Returns the summary.
pub fn write_plan(plan: &Plan, dir: &Path) -> Result<PlanSummary, PlanError> {
    std::fs::create_dir_all(dir).map_err(|e| write_error(dir, e))?;
    let kinds = &plan.candidates.joint_kinds;
    write_text(&dir.join("candidates.csv"), &candidates_csv_for(&plan.candidates.candidates, kinds)?)?;
    let selected = plan.order.iter().map(|&i| &plan.candidates.candidates[i]);
    write_text(&dir.join("selected.csv"), &candidates_csv_for(selected, kinds)?)?;
    write_text(&dir.join("tour.csv"), &tour_csv_for(&plan.steps, kinds)?)?;
    let summary = PlanSummary::of(plan);
    let json =
        serde_json::to_string_pretty(&summary).map_err(|e| write_error(&dir.join("summary.json"), e))?;
    write_text(&dir.join("summary.json"), &json)?;
    Ok(summary)
}
