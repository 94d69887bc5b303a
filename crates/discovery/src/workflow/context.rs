//! The fixed inputs of one run (data, split, folds, options, noise reference) and what every
//! decision computes from them: cross-validation, the gap, σ̂, weighted rows.

use nalgebra::Vector3;
use rayon::prelude::*;
use vatcal_core::canonical::bounds::ChainScale;
use vatcal_core::{Measurement, ParamSet};
use vatcal_identification::{ErrorStats, KindSigmas, KindWeights};
use vatcal_kinematics::Model;

use super::options::DiscoverOptions;
use super::report::{FitSummary, Gap};
use crate::DiscoveryError;
use crate::distributions::chi2_ln_sf;
use crate::fit::{Fit, fit, residuals};
use crate::location::PoseData;

/// Held-out predictions of a cross-validation: one error per measurement (`None` = not
/// predicted: not in the evaluated part, or its fold was skipped).
pub(super) struct CrossValidation {
    pub(super) errors: Vec<Option<Vector3<f64>>>,
    pub(super) skipped: Vec<String>,
}

impl CrossValidation {
    pub(super) fn stats(&self) -> ErrorStats {
        let e: Vec<Vector3<f64>> = self.errors.iter().flatten().copied().collect();
        ErrorStats::from_errors(&e)
    }
}

/// Fixed inputs of one run.
pub(super) struct Context<'a> {
    pub(super) measurements: &'a [Measurement],
    pub(super) validation: Option<&'a [Measurement]>,
    /// fold of every measurement over all data (reported gap)
    pub(super) all_folds: Vec<Option<usize>>,
    /// fold of every confirmation measurement (`None` for screening ones)
    pub(super) confirm_folds: Vec<Option<usize>>,
    /// the screening measurements
    pub(super) screen: Vec<Measurement>,
    pub(super) options: DiscoverOptions,
    /// σ per axis of each kind the size rule compares with (replicates or instruments);
    /// `None`: σ̂ of each fit ([`NoiseSource::Estimated`])
    pub(super) reference: Option<KindSigmas>,
    /// without a reference: σ̂ of the round's saturated linear model (bits of an f64, NaN =
    /// unknown), the lower of it and a refit's σ̂ is the size rule's noise
    pub(super) saturated_bits: std::sync::atomic::AtomicU64,
    /// the chain's size as the data see it (plausibility bounds)
    pub(super) scale: ChainScale,
}

impl Context<'_> {
    /// Held-out residual of every measurement with `Some` fold: one fit per fold on every
    /// other measurement (a failing fold is skipped and named).
    pub(super) fn cross_validate(
        &self,
        start: &Model,
        params: &ParamSet,
        folds: &[Option<usize>],
    ) -> CrossValidation {
        let k = folds.iter().flatten().copied().max().map_or(0, |m| m + 1);
        let mut cv = CrossValidation { errors: vec![None; self.measurements.len()], skipped: Vec::new() };
        // the folds' fits are independent: run them in parallel, collect in fold order (the
        // result does not depend on the thread count)
        let per_fold: Vec<_> = (0..k)
            .into_par_iter()
            .map(|f| {
                let test: Vec<usize> = (0..folds.len()).filter(|i| folds[*i] == Some(f)).collect();
                if test.is_empty() {
                    return (test, None);
                }
                let train: Vec<Measurement> =
                    (0..folds.len()).filter(|i| folds[*i] != Some(f)).map(|i| self.measurements[i]).collect();
                let test_ms: Vec<Measurement> = test.iter().map(|i| self.measurements[*i]).collect();
                let predicted = fit(start, &train, params, &self.options.identify)
                    .and_then(|trained| residuals(&trained.model, &test_ms));
                (test, Some(predicted))
            })
            .collect();
        for (f, (test, predicted)) in per_fold.into_iter().enumerate() {
            match predicted {
                None => {}
                Some(Ok(r)) => {
                    for (i, e) in test.iter().zip(r) {
                        cv.errors[*i] = Some(e);
                    }
                }
                Some(Err(e)) => {
                    cv.skipped.push(format!("fold {} of {k} ({} measurements): {e}", f + 1, test.len()))
                }
            }
        }
        cv
    }

    /// Fills `held0`, the confirmation CV of `current`, when the round has not computed it (its
    /// screening passed nothing, so it had nothing to confirm): once per round, shared by the
    /// joint search and the swap check, which need it whatever the screening found.
    pub(super) fn ensure_confirmation_baseline(&self, held0: &mut CrossValidation, current: &Fit) {
        if held0.errors.iter().all(Option::is_none) {
            *held0 = self.cross_validate(&current.model, &current.params, &self.confirm_folds);
        }
    }

    /// The validation rows when they take part in decisions
    /// ([`DiscoverOptions::validation_decides`]); `None` otherwise (they only report the gap).
    pub(super) fn deciding_validation(&self) -> Option<&[Measurement]> {
        self.validation.filter(|v| !v.is_empty() && self.options.validation_decides)
    }

    pub(super) fn gap(&self, model: &Model, heldout: &CrossValidation) -> Result<Gap, DiscoveryError> {
        let validation = match self.validation {
            Some(v) if !v.is_empty() => Some(ErrorStats::from_errors(&residuals(model, v)?)),
            _ => None,
        };
        Ok(Gap { heldout: heldout.stats(), skipped_folds: heldout.skipped.len(), validation })
    }

    /// Per-axis noise estimate of a weight-1 measurement from a fit with `rank` identified
    /// directions (or the known σ).
    pub(super) fn sigma_hat(&self, f: &Fit, ms: &[Measurement], rank: usize) -> f64 {
        if let Some(s) = self.options.known_sigma_mm {
            return s;
        }
        let w = &self.options.identify.weights;
        let rss: f64 = ms.iter().zip(&f.residuals).map(|(m, r)| kind_weight(m, w) * r.norm_squared()).sum();
        (rss / (3 * ms.len()).saturating_sub(rank).max(1) as f64).sqrt()
    }
}

/// Weight of a measurement's kind.
pub(super) fn kind_weight(m: &Measurement, w: &KindWeights) -> f64 {
    w.of(&m.target)
}

/// Multiplies the row block of every measurement by `√w` of its kind.
pub(super) fn weigh_rows(j: &mut faer::Mat<f64>, ms: &[Measurement], w: &KindWeights) {
    if w.probe == 1.0 && w.tracker == 1.0 {
        return;
    }
    for (k, m) in ms.iter().enumerate() {
        let s = kind_weight(m, w).sqrt();
        for c in 0..j.ncols() {
            for a in 0..3 {
                j[(3 * k + a, c)] *= s;
            }
        }
    }
}

/// The stacked residual of a fit, rows weighted by `√w`.
pub(super) fn weighted_residual(f: &Fit, ms: &[Measurement], w: &KindWeights) -> Vec<f64> {
    ms.iter()
        .zip(&f.residuals)
        .flat_map(|(m, r)| {
            let s = kind_weight(m, w).sqrt();
            [s * r.x, s * r.y, s * r.z]
        })
        .collect()
}

pub(super) fn summarize_fit(f: &Fit, ms: &[Measurement], rank: usize, ctx: &Context<'_>) -> FitSummary {
    let n = f.n();
    let dof = n.saturating_sub(rank).max(1);
    FitSummary {
        params: f.params.names(),
        measurements: f.residuals.len(),
        residuals: n,
        rank,
        rss_mm2: f.rss_mm2,
        sigma_hat_mm: ctx.sigma_hat(f, ms, rank),
        fit_errors: ErrorStats::from_errors(&f.residuals),
        chi2_ln_p_value: ctx.options.known_sigma_mm.map(|s| chi2_ln_sf(f.rss_mm2 / (s * s), dof)),
        iterations: f.iterations,
        converged: f.converged,
    }
}

/// The columns `cols` of `j` as a new matrix.
pub(super) fn columns(j: &faer::Mat<f64>, cols: &[usize]) -> faer::Mat<f64> {
    faer::Mat::from_fn(j.nrows(), cols.len(), |r, c| j[(r, cols[c])])
}

/// The chain's size as the measurements see it: each joint's largest gravity torque, bending
/// moment and lever arm over the poses (plausibility bounds, [`vatcal_core::canonical::bounds`]).
pub(super) fn chain_scale(model: &Model, ms: &[Measurement]) -> Result<ChainScale, DiscoveryError> {
    let pose = PoseData::of(model, ms)?;
    let mut scale = ChainScale {
        max_torque_nm: [0.0; vatcal_core::MAX_JOINTS],
        max_lever_mm: [0.0; vatcal_core::MAX_JOINTS],
        max_bending_nm: [0.0; vatcal_core::MAX_JOINTS],
    };
    for m in ms {
        for (b, v) in scale.max_bending_nm.iter_mut().zip(model.link_bending_moments(&m.q)) {
            *b = b.max(v[0].hypot(v[1]));
        }
    }
    for t in &pose.torques {
        for (m, v) in scale.max_torque_nm.iter_mut().zip(t) {
            *m = m.max(v.abs());
        }
    }
    for d in pose.joint_directions.iter().flatten() {
        for (m, v) in scale.max_lever_mm.iter_mut().zip(d) {
            *m = m.max(v.norm());
        }
    }
    Ok(scale)
}
