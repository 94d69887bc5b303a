//! Restarts and the two front doors: [`detmax`] (random or greedy starts, each exchanged to
//! convergence, in parallel; the best restart wins) and [`greedy`] (Dykstra, no exchange).

use std::cmp::Ordering;

use faer::Mat;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

use super::bookkeeping::{State, Work, factor, with_ridge};
use super::candidates::Candidates;
use super::exchange::{MIN_IMPROVEMENT, exact_objective_value, refine_exact};
use super::options::{
    DetmaxOptions, Initialisation, Objective, RestartOutcome, Selection, o1_from_log_det, validate,
};
use crate::error::ObservabilityError;
use crate::identifiability::{AnalysisOptions, analyze_jacobian, rank_deficient_error};

/// Relative ridge used by the greedy start before it is removed again.
const GREEDY_RIDGE: f64 = 1e-6;

fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seed of restart `r`.
pub fn restart_seed(seed: u64, restart: usize) -> u64 {
    splitmix64(seed ^ splitmix64(restart as u64))
}

/// `fixed` plus `count − fixed.len()` distinct random non-fixed candidates.
pub(super) fn random_start(
    rng: &mut ChaCha8Rng,
    n_candidates: usize,
    count: usize,
    fixed: &[usize],
) -> Vec<usize> {
    let mut is_fixed = vec![false; n_candidates];
    for &f in fixed {
        is_fixed[f] = true;
    }
    let mut pool: Vec<usize> = (0..n_candidates).filter(|k| !is_fixed[*k]).collect();
    let need = count - fixed.len();
    for i in 0..need {
        let j = rng.random_range(i..pool.len());
        pool.swap(i, j);
    }
    let mut design = fixed.to_vec();
    design.extend_from_slice(&pool[..need]);
    design
}

/// Greedy (Dykstra) design: from `fixed` and a tiny ridge, add the best candidate until
/// `count`; then rebuild with the requested ridge. None if the result is singular.
fn greedy_state<'a>(w: &'a Work<'a>, o: &DetmaxOptions, fixed_mask: &[bool]) -> Option<State<'a>> {
    let n = w.len().max(1) as f64;
    let greedy_ridge: Vec<f64> =
        (0..w.l()).map(|j| w.ridge.get(j).copied().unwrap_or(0.0).max(GREEDY_RIDGE / n)).collect();
    let mut s = State::new(w, o.fixed.clone(), fixed_mask, greedy_ridge, o.refactor_every)?;
    while s.design.len() < o.count {
        let (k, _) = s.best_addition()?;
        if !s.add(k) {
            return None;
        }
    }
    s.ridge = w.ridge.clone();
    s.refactor().then_some(s)
}

/// ln det(M + R) in natural units of a design, from scratch.
fn natural_log_det(w: &Work<'_>, design: &[usize]) -> f64 {
    factor(&with_ridge(w.information(design), &w.ridge)).map_or(f64::NEG_INFINITY, |f| f.1 - w.log_scale)
}

fn run_restart<'a>(
    c: &Candidates,
    w: &'a Work<'a>,
    o: &DetmaxOptions,
    r: usize,
) -> Result<(State<'a>, RestartOutcome), ObservabilityError> {
    let seed = restart_seed(o.seed, r);
    let mut fixed_mask = vec![false; c.len()];
    for &f in &o.fixed {
        fixed_mask[f] = true;
    }
    let mut greedy_start = o.init == Initialisation::Greedy;
    let mut state = if greedy_start {
        None
    } else {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let start = random_start(&mut rng, c.len(), o.count, &o.fixed);
        State::new(w, start, &fixed_mask, w.ridge.clone(), o.refactor_every)
    };
    if state.is_none() {
        // A singular start: first make sure the candidate set itself is not rank-deficient
        // (a clear error naming the parameters), then start greedily.
        if o.ridge == 0.0 {
            check_candidate_rank(c)?;
        }
        greedy_start = true;
        state = greedy_state(w, o, &fixed_mask);
    }
    let mut s = state.ok_or_else(|| {
        ObservabilityError::InvalidInput(format!(
            "no non-singular design of {} poses found (greedy start failed); the candidates cannot identify the {} parameters together",
            o.count,
            c.parameter_count()
        ))
    })?;
    let mut exchanges = s.exchange_until_converged(o.max_exchanges);
    let mut excursions_accepted = 0;
    if let Some(max_depth) = o.excursions {
        let mut depth = 1;
        while depth <= max_depth && exchanges < o.max_exchanges {
            let mut improved = false;
            for up in [true, false] {
                let snapshot = s.clone();
                if s.excursion(depth, up) && s.log_det > snapshot.log_det + MIN_IMPROVEMENT {
                    exchanges += 2 * depth + s.exchange_until_converged(o.max_exchanges - exchanges);
                    excursions_accepted += 1;
                    improved = true;
                    break;
                }
                s = snapshot;
            }
            depth = if improved { 1 } else { depth + 1 };
        }
    }
    if o.objective != Objective::O1 {
        exchanges += refine_exact(&mut s, c, o);
    }
    let design = s.sorted_design();
    let log_det = natural_log_det(w, &design);
    let objective_value = match o.objective {
        Objective::O1 => o1_from_log_det(log_det, c.parameter_count(), design.len()),
        other => exact_objective_value(c, &design, other),
    };
    Ok((s, RestartOutcome { seed, log_det, objective_value, exchanges, excursions_accepted, greedy_start }))
}

/// A finished restart: sorted design, tracked natural ln det, summary.
type RestartRun = (Vec<usize>, f64, RestartOutcome);

/// Detmax selection of `options.count` candidates (module docs).
///
/// # Examples
/// 40 of 240 candidate probe poses for the paper's 34 parameters; the selection beats the first
/// 40 candidates (a random design) on the criterion:
/// ```
/// use vatcal_core::{CellFile, ParamSet};
/// use vatcal_kinematics::Model;
/// use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax, log_det};
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// let poses = vatcal_sim::truth::probe_start_poses(&model, 240, 1);
/// let candidates = Candidates::from_measurements(&model, &poses, &ParamSet::paper34())?;
/// let selection = detmax(&candidates, &DetmaxOptions { restarts: 2, seed: 7, ..DetmaxOptions::new(40) })?;
/// assert_eq!(selection.selected.len(), 40);
/// let random: Vec<usize> = (0..40).collect();
/// let random_log_det = log_det(&candidates, &random, 0.0).ok_or("singular random design")?;
/// assert!(selection.log_det > random_log_det);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`ObservabilityError::TooFewCandidates`] (fewer candidates than `options.count`);
/// [`ObservabilityError::InvalidInput`] for invalid options (no restart, a design size of 0,
/// fixed indices out of range or repeated, more fixed poses than the design size);
/// [`ObservabilityError::RankDeficient`] when even all candidates together cannot identify the
/// parameters (naming them); [`ObservabilityError::Numerical`] for a failed factorisation.
pub fn detmax(candidates: &Candidates, options: &DetmaxOptions) -> Result<Selection, ObservabilityError> {
    validate(candidates, options)?;
    let work = Work::new(candidates, options.ridge);
    let runs: Vec<Result<RestartRun, ObservabilityError>> = (0..options.restarts)
        .into_par_iter()
        .map(|r| {
            run_restart(candidates, &work, options, r)
                .map(|(s, out)| (s.sorted_design(), s.log_det - work.log_scale, out))
        })
        .collect();
    let mut best: Option<(usize, Vec<usize>, f64)> = None;
    let mut restarts: Vec<RestartOutcome> = Vec::with_capacity(runs.len());
    for (r, run) in runs.into_iter().enumerate() {
        let (design, tracked, outcome) = run?;
        let better = best.as_ref().is_none_or(|(b, _, _)| {
            outcome.objective_value.total_cmp(&restarts[*b].objective_value) == Ordering::Greater
        });
        if better {
            best = Some((r, design, tracked));
        }
        restarts.push(outcome);
    }
    Selection::of_best(best, restarts)
}

/// Greedy sequential D-optimal design (Dykstra): from `fixed` (and a tiny ridge while the
/// design is singular), add the candidate with the largest gain `count` times. No exchanges.
pub fn greedy(candidates: &Candidates, options: &DetmaxOptions) -> Result<Selection, ObservabilityError> {
    validate(candidates, options)?;
    let work = Work::new(candidates, options.ridge);
    let mut fixed_mask = vec![false; candidates.len()];
    for &f in &options.fixed {
        fixed_mask[f] = true;
    }
    let s = greedy_state(&work, options, &fixed_mask)
        .ok_or_else(|| ObservabilityError::InvalidInput("the greedy design is singular".into()))?;
    let selected = s.sorted_design();
    let log_det = natural_log_det(&work, &selected);
    let objective_value = o1_from_log_det(log_det, candidates.parameter_count(), selected.len());
    Ok(Selection {
        selected,
        log_det,
        tracked_log_det: s.log_det - work.log_scale,
        objective_value,
        best_restart: 0,
        restarts: vec![RestartOutcome {
            seed: 0,
            log_det,
            objective_value,
            exchanges: 0,
            excursions_accepted: 0,
            greedy_start: true,
        }],
    })
}

/// Refuses a candidate set whose information matrix is singular, naming the parameters
/// through the identifiability analysis.
fn check_candidate_rank(c: &Candidates) -> Result<(), ObservabilityError> {
    let total = c.total_information();
    let l = c.parameter_count();
    let d: Vec<f64> = (0..l).map(|j| total[(j, j)]).collect();
    let normalized = Mat::from_fn(l, l, |r, col| {
        let s = (d[r] * d[col]).sqrt();
        if s > 0.0 { total[(r, col)] / s } else { 0.0 }
    });
    if d.iter().all(|x| *x > 0.0) && factor(&normalized).is_some() {
        return Ok(());
    }
    let report = analyze_jacobian(c.stacked(), c.params(), &AnalysisOptions::default())?;
    if report.is_full_rank() {
        return Ok(());
    }
    Err(match rank_deficient_error(&report) {
        ObservabilityError::RankDeficient { rank, needed, unidentifiable, message } => {
            ObservabilityError::RankDeficient {
                rank,
                needed,
                unidentifiable,
                message: format!("the candidate set is rank-deficient: {message}"),
            }
        }
        other => other,
    })
}
