//! Summary statistics of 3-D position errors, shared by identification, validation, discovery
//! and the demo.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Statistics of a set of 3-D position errors \[mm\].
///
/// `mean`, `rms`, `median`, `p95` and `max` are statistics of the error *magnitudes*
/// `‖e_k‖`; `axis_mean` / `axis_rms` are the signed mean and the RMS of each world coordinate
/// (x, y, z) — a non-zero `axis_mean` is a bias. Percentiles interpolate linearly between order
/// statistics (the "type 7" definition of R / NumPy). JSON keys carry the unit (`mean_mm`, ...).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ErrorStats {
    /// number of errors
    pub n: usize,
    /// mean magnitude \[mm\]
    #[serde(rename = "mean_mm")]
    pub mean: f64,
    /// root mean square magnitude \[mm\]
    #[serde(rename = "rms_mm")]
    pub rms: f64,
    /// median magnitude \[mm\]
    #[serde(rename = "median_mm")]
    pub median: f64,
    /// 95th percentile of the magnitude \[mm\]
    #[serde(rename = "p95_mm")]
    pub p95: f64,
    /// largest magnitude \[mm\]
    #[serde(rename = "max_mm")]
    pub max: f64,
    /// signed mean of the x, y, z components \[mm\]
    #[serde(rename = "axis_mean_mm")]
    pub axis_mean: [f64; 3],
    /// RMS of the x, y, z components \[mm\]
    #[serde(rename = "axis_rms_mm")]
    pub axis_rms: [f64; 3],
}

impl ErrorStats {
    /// Statistics of `errors` \[mm\]. An empty slice gives all zeros with `n = 0`.
    pub fn from_errors(errors: &[Vector3<f64>]) -> Self {
        let n = errors.len();
        if n == 0 {
            return Self::default();
        }
        let nf = n as f64;
        let mut norms: Vec<f64> = errors.iter().map(|e| e.norm()).collect();
        let mean = norms.iter().sum::<f64>() / nf;
        let rms = (norms.iter().map(|v| v * v).sum::<f64>() / nf).sqrt();
        norms.sort_by(f64::total_cmp);
        let mut axis_mean = [0.0; 3];
        let mut axis_rms = [0.0; 3];
        for e in errors {
            for a in 0..3 {
                axis_mean[a] += e[a];
                axis_rms[a] += e[a] * e[a];
            }
        }
        for a in 0..3 {
            axis_mean[a] /= nf;
            axis_rms[a] = (axis_rms[a] / nf).sqrt();
        }
        Self {
            n,
            mean,
            rms,
            median: quantile_sorted(&norms, 0.5),
            p95: quantile_sorted(&norms, 0.95),
            max: norms[n - 1],
            axis_mean,
            axis_rms,
        }
    }

    /// One line: `mean … RMS … median … p95 … max … mm`, in µm-resolution fixed point.
    pub fn one_line(&self) -> String {
        format!(
            "mean {:.4} mm, RMS {:.4} mm, median {:.4} mm, 95% {:.4} mm, max {:.4} mm (n = {})",
            self.mean, self.rms, self.median, self.p95, self.max, self.n
        )
    }
}

/// Quantile `p` (0..=1) of ascending `sorted` values, linear interpolation between order
/// statistics. Empty input gives 0.
pub fn quantile_sorted(sorted: &[f64], p: f64) -> f64 {
    match sorted.len() {
        0 => 0.0,
        1 => sorted[0],
        n => {
            let h = p.clamp(0.0, 1.0) * (n - 1) as f64;
            let lo = h.floor() as usize;
            let hi = (lo + 1).min(n - 1);
            sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn order_relations_hold_for_any_errors(
            raw in proptest::collection::vec((-5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0), 1..60)
        ) {
            let errors: Vec<Vector3<f64>> = raw.iter().map(|(x, y, z)| Vector3::new(*x, *y, *z)).collect();
            let s = ErrorStats::from_errors(&errors);
            let eps = 1e-12;
            prop_assert!(s.median <= s.p95 + eps && s.p95 <= s.max + eps);
            prop_assert!(s.mean <= s.rms + eps && s.rms <= s.max + eps);
            for a in 0..3 {
                prop_assert!(s.axis_mean[a].abs() <= s.axis_rms[a] + eps);
            }
            // |e|² = x² + y² + z², averaged
            let sum_axes: f64 = s.axis_rms.iter().map(|v| v * v).sum();
            prop_assert!((sum_axes - s.rms * s.rms).abs() <= 1e-9 * (1.0 + sum_axes));
            // order does not matter
            let mut reversed = errors.clone();
            reversed.reverse();
            let r = ErrorStats::from_errors(&reversed);
            prop_assert!((r.median - s.median).abs() < eps && (r.p95 - s.p95).abs() < eps && r.max == s.max);
        }
    }

    #[test]
    fn stats_of_known_errors() {
        let e = [Vector3::new(3.0, 4.0, 0.0), Vector3::new(0.0, 0.0, -1.0), Vector3::new(0.0, 2.0, 0.0)];
        let s = ErrorStats::from_errors(&e);
        assert_eq!(s.n, 3);
        assert!((s.mean - 8.0 / 3.0).abs() < 1e-15);
        assert!((s.rms - (30.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(s.median, 2.0);
        assert_eq!(s.max, 5.0);
        assert!((s.p95 - (2.0 + 0.9 * 3.0)).abs() < 1e-12);
        assert!((s.axis_mean[0] - 1.0).abs() < 1e-15);
        assert!((s.axis_mean[2] + 1.0 / 3.0).abs() < 1e-15);
        assert!((s.axis_rms[1] - (20.0f64 / 3.0).sqrt()).abs() < 1e-15);
    }

    #[test]
    fn empty_and_single() {
        assert_eq!(ErrorStats::from_errors(&[]).n, 0);
        let s = ErrorStats::from_errors(&[Vector3::new(0.0, 0.0, 2.0)]);
        assert_eq!((s.median, s.p95, s.max, s.mean), (2.0, 2.0, 2.0, 2.0));
    }

    #[test]
    fn json_keys_carry_the_unit() {
        let s = ErrorStats::from_errors(&[Vector3::new(1.0, 0.0, 0.0)]);
        let j = serde_json::to_string(&s).expect("json");
        assert!(
            j.contains("\"mean_mm\"") && j.contains("\"p95_mm\"") && j.contains("\"axis_rms_mm\""),
            "{j}"
        );
        let back: ErrorStats = serde_json::from_str(&j).expect("back");
        assert_eq!(back, s);
    }
}
