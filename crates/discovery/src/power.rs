//! Minimum detectable effect size and the measurements a decision needs (background.md §8.2,
//! "Detectability before measuring").
//!
//! The score test of a candidate with k novel directions is χ²(k) under "no effect" and
//! non-central χ²(k, λ) with an effect `a`: `λ = ‖P⊥ Z a‖² / σ²` — the part of the effect's
//! prediction change the current parameters cannot mimic, in units of the noise. At the
//! round's level (`ln_threshold`) and a power of 80 %, the smallest detectable effect has
//! `λ_min` ([`noncentrality_for_power`]); spread over the n measurements of the test that is an
//! RMS novel prediction change of `σ √(λ_min/n)` per measurement, and `σ √(λ_min/n) / novelty`
//! of the whole prediction change ([`Detectability`]).
//!
//! λ grows in proportion to the number of measurements of the same kind (same pose
//! distribution), so a candidate whose observed score says `λ̂ = LM − k` needs about
//! `n (λ_min/λ̂ − 1)` more of them; a refitted candidate whose held-out z fell short of `z_r`
//! needs `n ((z_r/z)² − 1)` more (z grows with √n). [`Detectability::more_measurements`] is
//! the larger of the two.

use serde::Serialize;

use crate::distributions::{chi2_ln_sf, ln_gamma};

/// `P(χ'²_k(λ) > x)`, the survival function of the non-central χ² distribution (Poisson
/// mixture of central χ² tails, summed until the weights are negligible).
pub fn noncentral_chi2_sf(x: f64, k: usize, lambda: f64) -> f64 {
    if k == 0 || x.is_nan() || lambda.is_nan() {
        return f64::NAN;
    }
    if lambda <= 0.0 {
        return chi2_ln_sf(x, k).exp();
    }
    let half = 0.5 * lambda;
    // sum from the Poisson mode outwards (both directions) until the terms vanish
    let mode = half.floor() as usize;
    let term = |j: usize| {
        let ln_w = -half + j as f64 * half.ln() - ln_gamma(j as f64 + 1.0);
        (ln_w + chi2_ln_sf(x, k + 2 * j)).exp()
    };
    let weight = |j: usize| (-half + j as f64 * half.ln() - ln_gamma(j as f64 + 1.0)).exp();
    let mut sum = 0.0;
    let mut j = mode;
    loop {
        sum += term(j);
        if (j > mode + 10 && weight(j) < 1e-16) || j > mode + 100_000 {
            break;
        }
        j += 1;
    }
    for j in (0..mode).rev() {
        sum += term(j);
        if weight(j) < 1e-16 && j + 10 < mode {
            break;
        }
    }
    sum.clamp(0.0, 1.0)
}

/// The critical value `c` of a χ²(k) test at `ln P(χ²_k > c) = ln_alpha`.
pub fn chi2_critical(k: usize, ln_alpha: f64) -> f64 {
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    while chi2_ln_sf(hi, k) > ln_alpha {
        hi *= 2.0;
        if hi > 1e7 {
            break;
        }
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi2_ln_sf(mid, k) > ln_alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The non-centrality λ at which a χ²(k) test at level `exp(ln_alpha)` rejects with
/// probability `power`.
pub fn noncentrality_for_power(k: usize, ln_alpha: f64, power: f64) -> f64 {
    let c = chi2_critical(k, ln_alpha);
    let power = power.clamp(1e-6, 1.0 - 1e-9);
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    while noncentral_chi2_sf(c, k, hi) < power {
        hi *= 2.0;
        if hi > 1e7 {
            break;
        }
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if noncentral_chi2_sf(c, k, mid) < power {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Power used by the reports: the smallest effect detected 4 times in 5.
pub const DEFAULT_POWER: f64 = 0.8;

/// What the data at hand can detect of one candidate, and what it would take to decide it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Detectability {
    /// novel directions of the candidate (degrees of freedom of its score test)
    pub dof: usize,
    /// `ln` of the test's level (the round's screening threshold)
    pub ln_level: f64,
    /// the power the minimum refers to
    pub power: f64,
    /// non-centrality needed: `λ_min`
    pub noncentrality_needed: f64,
    /// σ per axis the test uses \[mm\]
    pub sigma_mm: f64,
    /// measurements the test sees
    pub measurements: usize,
    /// overall novelty of the candidate's columns (fraction of the effect the current
    /// parameters cannot mimic)
    pub novelty: f64,
    /// smallest detectable RMS of the novel part of the prediction change per measurement
    /// \[mm\]: `σ √(λ_min / n)`
    pub min_novel_change_mm: f64,
    /// smallest detectable RMS of the whole prediction change \[mm\]: the novel part over the
    /// novelty
    pub min_change_mm: f64,
    /// λ̂ = max(LM − k, 0) from the observed score (`None` when not scored)
    pub estimated_noncentrality: Option<f64>,
    /// more measurements of the same kind that would decide it (80 % power in the screening
    /// and the held-out z reaching the round's threshold, when refitted); `None` when the
    /// data show no sign of the effect (λ̂ = 0) or it already passes
    pub more_measurements: Option<usize>,
}

impl Detectability {
    /// The minimum detectable size of a candidate with `dof` novel directions and overall
    /// `novelty`, tested on `measurements` measurements with noise `sigma_mm` per axis at
    /// level `exp(ln_level)` with `power`.
    pub fn new(
        dof: usize,
        novelty: f64,
        sigma_mm: f64,
        measurements: usize,
        ln_level: f64,
        power: f64,
    ) -> Self {
        let lambda = if dof == 0 { f64::INFINITY } else { noncentrality_for_power(dof, ln_level, power) };
        let min_novel = sigma_mm * (lambda / measurements.max(1) as f64).sqrt();
        Self {
            dof,
            ln_level,
            power,
            noncentrality_needed: lambda,
            sigma_mm,
            measurements,
            novelty,
            min_novel_change_mm: min_novel,
            min_change_mm: if novelty > 0.0 { min_novel / novelty } else { f64::INFINITY },
            estimated_noncentrality: None,
            more_measurements: None,
        }
    }

    /// Adds what the observed score statistic `lm` (on the `measurements` of the test) and,
    /// for a refitted candidate, the held-out `z` against the required `z_required` say about
    /// the measurements still needed; `total` is the size of the whole data set (the test saw
    /// a share of it, and more data of the kind keeps that share).
    pub fn with_observed(mut self, lm: f64, heldout: Option<(f64, f64)>, total: usize) -> Self {
        let lambda_hat = (lm - self.dof as f64).max(0.0);
        self.estimated_noncentrality = Some(lambda_hat);
        let total = total.max(1) as f64;
        let screening = if lambda_hat <= 0.0 {
            None
        } else {
            Some((self.noncentrality_needed / lambda_hat - 1.0).max(0.0) * total)
        };
        let confirming = match heldout {
            Some((z, z_required)) if z > 0.0 && z.is_finite() => {
                Some(((z_required / z).powi(2) - 1.0).max(0.0) * total)
            }
            Some(_) => None,
            None => Some(0.0),
        };
        self.more_measurements = match (screening, confirming) {
            (Some(a), Some(b)) if a.max(b) > 0.0 => Some(a.max(b).ceil() as usize),
            _ => None,
        };
        self
    }

    /// One sentence for people.
    pub fn sentence(&self) -> String {
        let more = match (self.more_measurements, self.estimated_noncentrality) {
            (Some(m), _) => format!("; about {m} more measurements of the kind would decide it"),
            (None, Some(l)) if l <= 0.0 => {
                "; the data show no sign of it, so no number of measurements can be named".into()
            }
            _ => String::new(),
        };
        format!(
            "smallest detectable size with these data: {:.1} um RMS prediction change ({:.1} um of it novel; {} dof, power {:.0} %, sigma {:.1} um, {} measurements){more}",
            1e3 * self.min_change_mm,
            1e3 * self.min_novel_change_mm,
            self.dof,
            100.0 * self.power,
            1e3 * self.sigma_mm,
            self.measurements
        )
    }
}

/// The minimum detectable size of catalog effect `spec` for a model fitted with `params` on
/// `measurements` (e.g. the data at hand plus a proposed design): its novel directions
/// against the fitted parameters (`novelty_floor` as in discovery, 1e-3), and the size a score
/// test at `exp(ln_level)` detects with `power` when the noise is `sigma_mm` per axis. The
/// proposer of new measurements maximises `1 / min_change_mm` of the rival or borderline
/// candidates. Rows are unweighted (probe and tracker rows alike).
///
/// # Errors
/// The effect cannot be switched on in `model`, or a Jacobian cannot be assembled.
pub fn candidate_detectability(
    model: &vatcal_kinematics::Model,
    params: &vatcal_core::ParamSet,
    measurements: &[vatcal_core::Measurement],
    spec: &vatcal_core::effects::EffectSpec,
    sigma_mm: f64,
    ln_level: f64,
    power: f64,
) -> Result<Detectability, crate::DiscoveryError> {
    use crate::linear::{ColumnSpace, EffectDirections};
    let mut m = model.clone();
    if !m.effects().contains(spec) {
        m.enable_effect(*spec).map_err(|e| crate::DiscoveryError::Numerical(e.to_string()))?;
    }
    let new: Vec<vatcal_core::ParamId> =
        spec.params().into_iter().filter(|p| params.index_of(*p).is_none()).collect();
    let j = vatcal_observability::assemble_jacobian(&m, measurements, params)
        .map_err(crate::DiscoveryError::Jacobian)?;
    let z = vatcal_observability::assemble_jacobian(&m, measurements, &vatcal_core::ParamSet(new))
        .map_err(crate::DiscoveryError::Jacobian)?;
    let space = ColumnSpace::of(j.as_ref())?;
    let d = EffectDirections::new(&space, z.as_ref(), 1e-3)?;
    Ok(Detectability::new(d.dof, d.novelty, sigma_mm, measurements.len(), ln_level, power))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noncentral_chi2_matches_the_central_case_and_known_values() {
        // λ = 0: the central distribution
        assert!((noncentral_chi2_sf(3.84146, 1, 0.0) - 0.05).abs() < 1e-5);
        // χ'²(1, λ) = (Z + √λ)²: P(|Z + √λ| > 1.96) with √λ = 2.8 ≈ 0.7995 + P(Z < −4.76)
        let p = noncentral_chi2_sf(1.959964f64.powi(2), 1, 2.8f64.powi(2));
        let want = 1.0 - 0.5 * (1.0 + libm_erf((1.959964 - 2.8) / 2f64.sqrt()));
        assert!((p - want).abs() < 1e-4, "{p} vs {want}");
        // the background's rule of thumb: 5 % level, 80 % power, one column: √λ ≈ 2.8
        let l = noncentrality_for_power(1, 0.05f64.ln(), 0.8);
        assert!((l.sqrt() - 2.80).abs() < 0.01, "{}", l.sqrt());
        // more dof or a stricter level need more
        assert!(noncentrality_for_power(3, 0.05f64.ln(), 0.8) > l);
        assert!(noncentrality_for_power(1, 1e-4f64.ln(), 0.8) > l);
    }

    /// erf by its series / continued fraction is not in std; Abramowitz–Stegun 7.1.26 is
    /// good to 1.5e-7, enough here.
    fn libm_erf(x: f64) -> f64 {
        let t = 1.0 / (1.0 + 0.3275911 * x.abs());
        let y = 1.0
            - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592)
                * t
                * (-x * x).exp();
        if x >= 0.0 { y } else { -y }
    }

    #[test]
    fn detectability_scales_with_noise_and_measurements() {
        let a = Detectability::new(2, 0.5, 0.002, 100, 1e-4f64.ln(), DEFAULT_POWER);
        let b = Detectability::new(2, 0.5, 0.002, 400, 1e-4f64.ln(), DEFAULT_POWER);
        assert!((a.min_change_mm / b.min_change_mm - 2.0).abs() < 1e-9);
        assert!((a.min_change_mm - 2.0 * a.min_novel_change_mm).abs() < 1e-15);
        // an observed λ̂ at a quarter of what is needed: three times the data again
        let lm = 2.0 + a.noncentrality_needed / 4.0;
        let c = a.with_observed(lm, None, 100);
        assert_eq!(c.more_measurements, Some(300));
        // a held-out z at half the required one needs 4× the data
        let d = a.with_observed(2.0 + a.noncentrality_needed * 2.0, Some((1.5, 3.0)), 100);
        assert_eq!(d.more_measurements, Some(300));
        // no sign of it: no number
        assert_eq!(a.with_observed(1.0, None, 100).more_measurements, None);
        assert!(a.with_observed(1.0, None, 100).sentence().contains("no sign"));
    }
}
