//! Comparison of nested least-squares fits: F-test and information criteria
//! (background.md §8.2, Gaussian least squares, constants dropped).

use nalgebra::Vector3;
use serde::Serialize;

use crate::distributions::{f_ln_sf, normal_ln_sf};

/// Akaike's criterion corrected for small samples, `N ln(RSS/N) + 2p + 2p(p+1)/(N − p − 1)`.
/// Infinite when `N ≤ p + 1`.
pub fn aicc(rss: f64, n: usize, p: usize) -> f64 {
    let (nf, pf) = (n as f64, p as f64);
    if n <= p + 1 || rss <= 0.0 {
        return f64::INFINITY;
    }
    nf * (rss / nf).ln() + 2.0 * pf + 2.0 * pf * (pf + 1.0) / (nf - pf - 1.0)
}

/// Bayesian (Schwarz) criterion `N ln(RSS/N) + p ln N`.
pub fn bic(rss: f64, n: usize, p: usize) -> f64 {
    let (nf, pf) = (n as f64, p as f64);
    if rss <= 0.0 || n == 0 {
        return f64::INFINITY;
    }
    nf * (rss / nf).ln() + pf * nf.ln()
}

/// Model 0 (p₀ parameters) against model 1 = model 0 + k parameters, on the same N residuals.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NestedComparison {
    /// number of scalar residuals (3 per measurement)
    pub n: usize,
    /// identified parameters of model 0
    pub p0: usize,
    /// identified parameters of model 1
    pub p1: usize,
    /// residual sum of squares of model 0 \[mm²\]
    pub rss0_mm2: f64,
    /// residual sum of squares of model 1 \[mm²\]
    pub rss1_mm2: f64,
    /// `F = [(RSS₀ − RSS₁)/k] / [RSS₁/(N − p₁)]`
    pub f: f64,
    /// `ln P(F_{k, N−p₁} > F)`
    pub f_ln_p_value: f64,
    /// AICc₁ − AICc₀ (negative favours the effect)
    pub delta_aicc: f64,
    /// BIC₁ − BIC₀ (negative favours the effect; below −10 is strong evidence)
    pub delta_bic: f64,
}

impl NestedComparison {
    /// Compares the two fits. `p1` must exceed `p0` and `n` must exceed `p1`.
    pub fn new(n: usize, p0: usize, rss0_mm2: f64, p1: usize, rss1_mm2: f64) -> Self {
        let k = p1.saturating_sub(p0);
        let dof1 = n.saturating_sub(p1);
        let f = if k == 0 || dof1 == 0 {
            f64::NAN
        } else if rss1_mm2 <= 0.0 {
            f64::INFINITY
        } else {
            ((rss0_mm2 - rss1_mm2) / k as f64) / (rss1_mm2 / dof1 as f64)
        };
        let f_ln_p_value = if f.is_nan() { f64::NAN } else { f_ln_sf(f.max(0.0), k, dof1) };
        Self {
            n,
            p0,
            p1,
            rss0_mm2,
            rss1_mm2,
            f,
            f_ln_p_value,
            delta_aicc: aicc(rss1_mm2, n, p1) - aicc(rss0_mm2, n, p0),
            delta_bic: bic(rss1_mm2, n, p1) - bic(rss0_mm2, n, p0),
        }
    }

    /// The F-test p-value (may underflow to 0; compare `f_ln_p_value` instead).
    pub fn f_p_value(&self) -> f64 {
        self.f_ln_p_value.exp()
    }
}

/// Paired comparison of held-out prediction errors of the same measurements under two models:
/// `d_k = ‖e_before,k‖² − ‖e_after,k‖²`, `z = mean(d) / (sd(d)/√n)`, one-sided (the second
/// model predicts better).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PairedImprovement {
    /// mean reduction of the squared held-out error per measurement \[mm²\]
    pub mean_reduction_mm2: f64,
    /// the z statistic
    pub z: f64,
    /// `ln P(Z > z)` under "no improvement"
    pub ln_p_value: f64,
}

impl PairedImprovement {
    /// Compares held-out errors `before` and `after` (same measurements, same order).
    ///
    /// # Panics
    /// If the lengths differ (a programming error).
    pub fn new(before: &[Vector3<f64>], after: &[Vector3<f64>]) -> Self {
        assert_eq!(before.len(), after.len(), "paired errors must have the same length");
        let d: Vec<f64> =
            before.iter().zip(after).map(|(b, a)| b.norm_squared() - a.norm_squared()).collect();
        let n = d.len() as f64;
        let mean = d.iter().sum::<f64>() / n.max(1.0);
        let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        let se = (var / n.max(1.0)).sqrt();
        let z = if se > 0.0 {
            mean / se
        } else if mean > 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
        Self { mean_reduction_mm2: mean, z, ln_p_value: normal_ln_sf(z) }
    }
}

/// Held-out comparison of two models on the same measurements, each predicted by fits that did
/// not see it: the paired differences `d_k = ‖e_before,k‖² − ‖e_after,k‖²` of the squared
/// prediction errors, their mean and its standard error, and how much the predictions change
/// (`‖e_before,k − e_after,k‖`, the effect's size where it matters). Measurements without a
/// held-out prediction under either model (a skipped fold) are left out and counted.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HeldOutComparison {
    /// measurements compared
    pub points: usize,
    /// measurements without a held-out prediction (skipped folds)
    pub missing: usize,
    /// RMS held-out error norm without the change \[mm\]
    pub rms_before_mm: f64,
    /// RMS held-out error norm with the change \[mm\]
    pub rms_after_mm: f64,
    /// mean reduction of the squared held-out error per measurement \[mm²\] (> 0: better)
    pub mean_reduction_mm2: f64,
    /// standard error of that mean \[mm²\]
    pub std_error_mm2: f64,
    /// `mean_reduction / std_error`
    pub z: f64,
    /// `ln P(Z > z)` under "no improvement" (one-sided)
    pub ln_p_value: f64,
    /// RMS of the change of the predictions `‖e_before,k − e_after,k‖` \[mm\]
    pub change_rms_mm: f64,
}

impl HeldOutComparison {
    /// Compares held-out errors `before` and `after` (same measurements, same order; `None` =
    /// no prediction).
    ///
    /// # Panics
    /// If the lengths differ (a programming error).
    pub fn new(before: &[Option<Vector3<f64>>], after: &[Option<Vector3<f64>>]) -> Self {
        assert_eq!(before.len(), after.len(), "paired errors must have the same length");
        let pairs: Vec<(Vector3<f64>, Vector3<f64>)> =
            before.iter().zip(after).filter_map(|(b, a)| Some(((*b)?, (*a)?))).collect();
        let n = pairs.len();
        let nf = n.max(1) as f64;
        let d: Vec<f64> = pairs.iter().map(|(b, a)| b.norm_squared() - a.norm_squared()).collect();
        let mean = d.iter().sum::<f64>() / nf;
        let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (nf - 1.0).max(1.0);
        let se = (var / nf).sqrt();
        let z = if n < 2 {
            0.0
        } else if se > 0.0 {
            mean / se
        } else if mean > 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
        let rms = |values: &mut dyn Iterator<Item = f64>| (values.map(|v| v * v).sum::<f64>() / nf).sqrt();
        Self {
            points: n,
            missing: before.len() - n,
            rms_before_mm: rms(&mut pairs.iter().map(|p| p.0.norm())),
            rms_after_mm: rms(&mut pairs.iter().map(|p| p.1.norm())),
            mean_reduction_mm2: mean,
            std_error_mm2: se,
            z,
            ln_p_value: normal_ln_sf(z),
            change_rms_mm: rms(&mut pairs.iter().map(|p| (p.0 - p.1).norm())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn criteria_match_hand_computation() {
        let (rss, n, p) = (0.5, 120, 30);
        let base = 120.0 * (0.5f64 / 120.0).ln();
        assert_relative_eq!(bic(rss, n, p), base + 30.0 * 120f64.ln(), epsilon = 1e-12);
        assert_relative_eq!(aicc(rss, n, p), base + 60.0 + 2.0 * 30.0 * 31.0 / 89.0, epsilon = 1e-12);
        assert!(aicc(rss, 31, 30).is_infinite());
    }

    #[test]
    fn paired_improvement_sees_a_consistent_drop_and_not_noise() {
        let before: Vec<Vector3<f64>> =
            (0..100).map(|k| Vector3::new(0.01 + 0.001 * ((k * 7) % 5) as f64, 0.0, 0.0)).collect();
        let better: Vec<Vector3<f64>> = before.iter().map(|e| e * 0.5).collect();
        let p = PairedImprovement::new(&before, &better);
        assert!(p.z > 10.0 && p.ln_p_value < -20.0 && p.mean_reduction_mm2 > 0.0);
        // swapping the roles of alternate measurements: no systematic improvement
        let mixed: Vec<Vector3<f64>> =
            before.iter().enumerate().map(|(k, e)| if k % 2 == 0 { e * 0.5 } else { e * 1.3 }).collect();
        let q = PairedImprovement::new(&before, &mixed);
        assert!(q.z.abs() < 2.0, "{}", q.z);
    }

    #[test]
    fn held_out_comparison_pairs_only_predicted_points_and_measures_the_change() {
        let before: Vec<Option<Vector3<f64>>> =
            (0..60).map(|k| Some(Vector3::new(0.010 + 0.001 * ((k * 7) % 5) as f64, 0.0, 0.0))).collect();
        let mut after: Vec<Option<Vector3<f64>>> = before.iter().map(|e| e.map(|v| v * 0.5)).collect();
        after[3] = None;
        let c = HeldOutComparison::new(&before, &after);
        assert_eq!((c.points, c.missing), (59, 1));
        assert!(c.z > 10.0 && c.mean_reduction_mm2 > 0.0 && c.rms_after_mm < c.rms_before_mm);
        // the predictions moved by half the error: 5..7 µm
        assert!(c.change_rms_mm > 0.005 && c.change_rms_mm < 0.007, "{}", c.change_rms_mm);
        // no change at all: z = 0, change 0
        let same = HeldOutComparison::new(&before, &before);
        assert!(same.z == 0.0 && same.change_rms_mm == 0.0 && same.ln_p_value > -0.7);
        // worse predictions: negative z
        let worse: Vec<Option<Vector3<f64>>> = before.iter().map(|e| e.map(|v| v * 1.2)).collect();
        assert!(HeldOutComparison::new(&before, &worse).z < -5.0);
    }

    #[test]
    fn f_test_of_a_large_drop_is_significant_and_of_no_drop_is_not() {
        let big = NestedComparison::new(540, 34, 0.01, 36, 0.002);
        assert!(big.f > 100.0 && big.f_ln_p_value < -50.0 && big.delta_bic < -10.0 && big.delta_aicc < 0.0);
        let none = NestedComparison::new(540, 34, 0.002, 36, 0.002);
        assert!(
            none.f.abs() < 1e-12 && none.f_p_value() > 0.999 && none.delta_bic > 0.0 && none.delta_aicc > 0.0
        );
    }
}
