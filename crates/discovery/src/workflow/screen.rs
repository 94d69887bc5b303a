//! **Screening** (module docs of [`super`], step 2): which effects are candidates, their score
//! on the screening part of the data, the weighted Bonferroni level per round and the round's
//! thresholds.

use vatcal_core::effects::EffectSpec;
use vatcal_core::{Measurement, ParamId, ParamSet};
use vatcal_kinematics::Model;
use vatcal_kinematics::effects::{DataAvailability, candidate_effects, missing_data};
use vatcal_observability::assemble_jacobian;

use super::candidate::Candidate;
use super::context::{Context, columns, weigh_rows, weighted_residual};
use super::options::DiscoverOptions;
use super::report::CandidateStatus;
use crate::DiscoveryError;
use crate::distributions::normal_upper_quantile;
use crate::fit::Fit;
use crate::linear::{ColumnSpace, EffectDirections, score_test};

/// Share of a round's screening level spent on the catalog's **generic** effects
/// (`ErrorEffect::generic`, e.g. `link-out-of-plane`) when the round also scores physical
/// ones: a weighted Bonferroni split (weights summing to the number of candidates), so that
/// adding generic fallbacks to the catalog costs the physical effects' power little (their
/// threshold is that of a catalog without the fallbacks, times 0.8).
pub const GENERIC_SCREENING_SHARE: f64 = 0.2;

/// ln weights of the scored candidates (module docs of [`GENERIC_SCREENING_SHARE`]).
pub(super) fn screening_weights(candidates: &mut [Candidate]) {
    let generic = |c: &Candidate| c.spec.effect().is_some_and(|e| e.generic());
    let scored = || candidates.iter().filter(|c| c.score.is_some());
    let m = scored().count() as f64;
    let m_generic = scored().filter(|c| generic(c)).count() as f64;
    let m_physical = m - m_generic;
    for c in candidates.iter_mut() {
        c.ln_weight = if m_generic == 0.0 || m_physical == 0.0 {
            0.0
        } else if generic(c) {
            (GENERIC_SCREENING_SHARE * m / m_generic).ln()
        } else {
            ((1.0 - GENERIC_SCREENING_SHARE) * m / m_physical).ln()
        };
    }
}

/// Share of the false-alarm probability spent in round `r` (1-based): `6/(π² r²)`, which sums
/// to 1 over all rounds, so spending `alpha · spend(r)` per round keeps the family-wise level
/// over every round below `alpha` while later rounds (needed when a cell has many missing
/// effects) stay testable (round 8 still spends 0.95 %, where `2⁻ʳ` would spend 0.39 %).
pub fn round_spending(r: usize) -> f64 {
    let r = r.max(1) as f64;
    6.0 / (std::f64::consts::PI * std::f64::consts::PI * r * r)
}

/// Highest gear harmonic [`candidates`] proposes.
pub const MAX_PROPOSED_HARMONIC: u8 = vatcal_core::effects::joint_cyclic::MAX_PROPOSED_HARMONIC;

/// The catalog's candidates plus what each effect's module adds: further candidates once an
/// instance is in the model (`ErrorEffect::follow_ups`: the next gear harmonic of a joint
/// once the model has its harmonic h ≥ 2, harmonics entering in order up to
/// [`MAX_PROPOSED_HARMONIC`]: a strain-wave gear whose error curve has a second harmonic has
/// higher ones too, and proposing them only then keeps the number of scored candidates, and
/// so the Bonferroni price, small), then candidates tested beside another
/// (`ErrorEffect::also_try`: the lower orders of the guide-angular polynomial; order 1 = a
/// linear pitch/yaw/roll, 3 parameters, is tested on its own so that a linear error does not
/// have to pay for the 3 quadratic parameters too; the order-2 candidate is then the test of
/// the quadratic terms).
pub fn candidates(model: &Model, measurements: &[Measurement]) -> Vec<EffectSpec> {
    let mut v = candidate_effects(model, measurements);
    for spec in model.effects() {
        for next in spec.effect().map(|e| e.follow_ups(spec)).unwrap_or_default() {
            if !v.contains(&next) {
                v.push(next);
            }
        }
    }
    let mut lower = Vec::new();
    for spec in &v {
        lower.extend(spec.effect().map(|e| e.also_try(spec)).unwrap_or_default());
    }
    for spec in lower {
        if !v.contains(&spec) {
            v.push(spec);
        }
    }
    v
}

/// Scores every candidate effect on the screening data (`screen_fit` = the current model
/// refitted to the screening measurements).
pub(super) fn score_candidates(
    current: &Fit,
    screen_fit: &Fit,
    space: &ColumnSpace,
    ctx: &Context<'_>,
    notes: &mut Vec<String>,
) -> Result<Vec<Candidate>, DiscoveryError> {
    let data = DataAvailability::of(ctx.measurements);
    let mut out: Vec<Candidate> = Vec::new();
    let excluded = |spec: &EffectSpec| ctx.options.excluded_effects.iter().any(|n| n == spec.kind().name());
    for spec in candidates(&current.model, ctx.measurements).into_iter().filter(|s| !excluded(s)) {
        let new_params: Vec<ParamId> = missing_prerequisites(&spec, current)
            .iter()
            .flat_map(|e| e.params())
            .chain(spec.params())
            .filter(|p| current.params.index_of(*p).is_none())
            .collect();
        let status = if let Some(why) = missing_data(&spec, &data) {
            let what = match spec.joint() {
                Some(_) => format!("{} (every joint)", spec.kind()),
                None => spec.label(),
            };
            let note = format!("{what} not tested: {why}");
            if !notes.contains(&note) {
                notes.push(note);
            }
            CandidateStatus::MissingData(why.to_string())
        } else if new_params.is_empty() {
            CandidateStatus::AlreadyInModel
        } else {
            CandidateStatus::NotSignificant
        };
        out.push(Candidate {
            spec,
            new_params,
            directions: None,
            score: None,
            status,
            refit: None,
            detect: None,
            ln_weight: 0.0,
        });
    }
    // one Jacobian for the parameters of every live candidate
    let mut all: Vec<ParamId> = Vec::new();
    for c in out.iter().filter(|c| c.status == CandidateStatus::NotSignificant) {
        for p in &c.new_params {
            if !all.contains(p) {
                all.push(*p);
            }
        }
    }
    if all.is_empty() {
        return Ok(out);
    }
    let w = ctx.options.identify.weights;
    let mut zall = assemble_jacobian(&screen_fit.model, &ctx.screen, &ParamSet(all.clone()))
        .map_err(DiscoveryError::Jacobian)?;
    weigh_rows(&mut zall, &ctx.screen, &w);
    let r = weighted_residual(screen_fit, &ctx.screen, &w);
    let sigma = ctx.sigma_hat(screen_fit, &ctx.screen, space.rank());
    // columns at round-off size (e.g. the compliance of a vertical joint: no gravity torque)
    // are no direction at all, however they look after unit normalisation
    let norms: Vec<f64> = (0..zall.ncols()).map(|c| zall.col(c).norm_l2()).collect();
    let negligible = vatcal_observability::identifiability::negligible_columns(&norms, &all);
    for c in out.iter_mut().filter(|c| c.status == CandidateStatus::NotSignificant) {
        let cols: Vec<usize> = c.new_params.iter().filter_map(|p| all.iter().position(|q| q == p)).collect();
        if cols.iter().all(|k| negligible.contains(k)) {
            c.status = CandidateStatus::NotDiscoverable;
            continue;
        }
        let z = columns(&zall, &cols);
        let d = EffectDirections::new(space, z.as_ref(), ctx.options.novelty_floor)?;
        if d.dof == 0 {
            c.status = CandidateStatus::NotDiscoverable;
        } else {
            c.score = Some(score_test(space, &d, &r, sigma * sigma));
        }
        c.directions = Some(d);
    }
    Ok(out)
}

/// The thresholds of one round.
pub(super) struct Thresholds {
    pub(super) ln_screen: f64,
    pub(super) z_required: f64,
    /// the held-out gap is well above its floor estimate ([`super::Round::far_from_floor`])
    pub(super) far_from_floor: bool,
}

impl Thresholds {
    /// Round `r`'s thresholds (`spend` = [`round_spending`]`(r)`, `m` scored candidates): the
    /// screening level `ln(alpha·spend/m)`, the held-out z at `confirm_alpha·spend/max_refits`,
    /// and whether the gap is more than [`DiscoverOptions::floor_gap_factor`] times its floor.
    pub(super) fn new(options: &DiscoverOptions, spend: f64, m: usize, gap_over_floor: Option<f64>) -> Self {
        Self {
            ln_screen: (options.alpha * spend / m as f64).ln(),
            z_required: normal_upper_quantile(
                options.confirm_alpha * spend / options.max_refits.max(1) as f64,
            ),
            far_from_floor: gap_over_floor.is_some_and(|r| r > options.floor_gap_factor),
        }
    }

    /// Whether any candidate is to be confirmed: one passes the screening threshold, or the
    /// gap is far from its floor and one was scored.
    pub(super) fn any_screened(&self, candidates: &[Candidate]) -> bool {
        candidates
            .iter()
            .any(|c| c.weighted_ln_p().is_some_and(|p| self.far_from_floor || p < self.ln_screen))
    }
}

/// Sorts the scored candidates by weighted screening p-value, best first (unscored last),
/// after setting their weights ([`screening_weights`]).
pub(super) fn rank_candidates(candidates: &mut [Candidate]) {
    screening_weights(candidates);
    let key = |c: &Candidate| c.weighted_ln_p().unwrap_or(f64::INFINITY);
    candidates.sort_by(|a, b| key(a).total_cmp(&key(b)));
}

/// The lower-order effects of `spec` ([`vatcal_core::effects::ErrorEffect::prerequisites`])
/// that are not in the model `current`: none of their parameters fitted and all of them zero.
/// Discovery proposes `spec` together with them.
pub(super) fn missing_prerequisites(spec: &EffectSpec, current: &Fit) -> Vec<EffectSpec> {
    let absent = |p: &ParamId| {
        current.params.index_of(*p).is_none() && current.model.param(*p).is_ok_and(|v| v == 0.0)
    };
    spec.prerequisites().into_iter().filter(|lower| lower.params().iter().all(absent)).collect()
}

#[cfg(test)]
mod tests {
    use super::round_spending;

    #[test]
    fn round_spending_sums_to_at_most_one_and_decreases() {
        let total: f64 = (1..=100_000).map(round_spending).sum();
        assert!(total < 1.0 && total > 0.9999, "{total}");
        assert!((1..50).all(|r| round_spending(r + 1) < round_spending(r)));
        assert!((round_spending(1) - 6.0 / std::f64::consts::PI.powi(2)).abs() < 1e-15);
    }

    fn candidate(spec: vatcal_core::effects::EffectSpec, scored: bool) -> super::Candidate {
        super::Candidate {
            spec,
            new_params: Vec::new(),
            directions: None,
            score: scored.then_some(crate::linear::ScoreTest { statistic: 1.0, dof: 1, ln_p_value: -3.0 }),
            status: super::CandidateStatus::NotSignificant,
            refit: None,
            detect: None,
            ln_weight: f64::NAN,
        }
    }

    /// Weighted Bonferroni: the weights of the scored candidates sum to their number, the
    /// generic ones share `GENERIC_SCREENING_SHARE` of it, and a round with one class only
    /// weighs every candidate 1.
    #[test]
    fn screening_weights_split_the_level_between_physical_and_generic_effects() {
        use vatcal_core::effects::EffectSpec;
        use vatcal_core::effects::link_out_of_plane::{Component, spec};
        let mut cs = vec![
            candidate(EffectSpec::JointScale { joint: 3 }, true),
            candidate(EffectSpec::ToolFrame, true),
            candidate(EffectSpec::JointBacklash { joint: 2 }, true),
            candidate(spec(4, Component::Axial), true),
            candidate(spec(5, Component::TiltX), false),
        ];
        super::screening_weights(&mut cs);
        let w: Vec<f64> = cs.iter().filter(|c| c.score.is_some()).map(|c| c.ln_weight.exp()).collect();
        assert!((w.iter().sum::<f64>() - 4.0).abs() < 1e-12, "{w:?}");
        assert!((w[3] - super::GENERIC_SCREENING_SHARE * 4.0).abs() < 1e-12, "{w:?}");
        assert!((w[0] - (1.0 - super::GENERIC_SCREENING_SHARE) * 4.0 / 3.0).abs() < 1e-12, "{w:?}");
        let mut physical =
            vec![candidate(EffectSpec::ToolFrame, true), candidate(EffectSpec::GuideScale, true)];
        super::screening_weights(&mut physical);
        assert!(physical.iter().all(|c| c.ln_weight == 0.0));
    }
}
