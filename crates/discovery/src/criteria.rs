//! Comparison of nested least-squares fits: F-test and information criteria
//! (background.md §8.2, Gaussian least squares, constants dropped).

use serde::Serialize;

use crate::distributions::f_ln_sf;

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
    /// residual sum of squares of model 0 [mm²]
    pub rss0_mm2: f64,
    /// residual sum of squares of model 1 [mm²]
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
    fn f_test_of_a_large_drop_is_significant_and_of_no_drop_is_not() {
        let big = NestedComparison::new(540, 34, 0.01, 36, 0.002);
        assert!(big.f > 100.0 && big.f_ln_p_value < -50.0 && big.delta_bic < -10.0 && big.delta_aicc < 0.0);
        let none = NestedComparison::new(540, 34, 0.002, 36, 0.002);
        assert!(none.f.abs() < 1e-12 && none.f_p_value() > 0.999 && none.delta_bic > 0.0 && none.delta_aicc > 0.0);
    }
}
