//! The naive reference: the same exchange with every gain and loss from an SVD, for tests and
//! the benchmark.

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;

use super::candidates::Candidates;
use super::exchange::MIN_IMPROVEMENT;
use super::options::{DetmaxOptions, RestartOutcome, Selection, o1_from_log_det, validate};
use super::restarts::{random_start, restart_seed};
use crate::error::ObservabilityError;

/// `ln det(JᵀJ) = 2 Σ ln σ_i` of the stacked design Jacobian, from its SVD.
pub fn log_det_by_svd(candidates: &Candidates, design: &[usize]) -> f64 {
    let j = candidates.design_jacobian(design);
    match j.singular_values() {
        Ok(s) if s.len() == candidates.parameter_count() => s.iter().map(|x| 2.0 * x.ln()).sum(),
        _ => f64::NEG_INFINITY,
    }
}

/// The plain exchange of [`detmax`](fn@super::detmax) (O1, random starts, same seeds, same tie-breaking and
/// stopping rule, no excursions, no fixed poses) with every gain and loss computed from
/// scratch by an SVD of the trial design. O(N) SVDs per step: a reference, not a tool.
pub fn naive_detmax(
    candidates: &Candidates,
    options: &DetmaxOptions,
) -> Result<Selection, ObservabilityError> {
    validate(candidates, options)?;
    let mut best: Option<(usize, Vec<usize>, f64)> = None;
    let mut restarts = Vec::new();
    for r in 0..options.restarts {
        let seed = restart_seed(options.seed, r);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut design = random_start(&mut rng, candidates.len(), options.count, &options.fixed);
        let mut current = log_det_by_svd(candidates, &design);
        if !current.is_finite() {
            return Err(ObservabilityError::InvalidInput(
                "naive reference: the random start is singular".into(),
            ));
        }
        let mut exchanges = 0;
        while exchanges < options.max_exchanges {
            let mut member = vec![false; candidates.len()];
            for &k in &design {
                member[k] = true;
            }
            let mut add: Option<(usize, f64)> = None;
            for k in (0..candidates.len()).filter(|k| !member[*k]) {
                design.push(k);
                let v = log_det_by_svd(candidates, &design);
                design.pop();
                if add.is_none_or(|(_, b)| v > b) {
                    add = Some((k, v));
                }
            }
            let Some((k_in, with_in)) = add else { break };
            design.push(k_in);
            let loss_in = with_in - current;
            let mut members: Vec<usize> = design[..design.len() - 1].to_vec();
            members.sort_unstable();
            let mut out: Option<(usize, f64)> = None;
            for k in members {
                let trial: Vec<usize> = design.iter().copied().filter(|x| *x != k).collect();
                let loss = with_in - log_det_by_svd(candidates, &trial);
                if out.is_none_or(|(_, b)| loss < b) {
                    out = Some((k, loss));
                }
            }
            match out {
                Some((k_out, loss_out))
                    if loss_out < loss_in && with_in - loss_out - current > MIN_IMPROVEMENT =>
                {
                    design.retain(|x| *x != k_out);
                    current = with_in - loss_out;
                    exchanges += 1;
                }
                _ => {
                    design.pop();
                    break;
                }
            }
        }
        design.sort_unstable();
        let log_det = log_det_by_svd(candidates, &design);
        let objective_value = o1_from_log_det(log_det, candidates.parameter_count(), design.len());
        if best.as_ref().is_none_or(|(b, _, _)| {
            let bo: &RestartOutcome = &restarts[*b];
            objective_value > bo.objective_value
        }) {
            best = Some((r, design, current));
        }
        restarts.push(RestartOutcome {
            seed,
            log_det,
            objective_value,
            exchanges,
            excursions_accepted: 0,
            greedy_start: false,
        });
    }
    Selection::of_best(best, restarts)
}
