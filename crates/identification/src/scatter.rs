//! Weighing pose rows by their own fitted scatter (issue 31): the orientation half of a pose
//! row is in radians, the positions in millimetres, so their relative weight is the ratio of
//! their noise variances. Unless the user states it, the weight is fitted: fit, estimate σ per
//! kind from the residuals ([`KindSigmas`]), re-weight, refit, until the weight settles.

use serde::{Deserialize, Serialize};
use vatcal_core::Measurement;

use crate::{Identification, IdentifyOptions, KindSigmas, KindWeights};

/// Relative change of the orientation weight below which it has settled.
pub const SCATTER_SETTLED: f64 = 0.1;

/// Fits at most this many times while the orientation weight settles.
pub const SCATTER_MAX_FITS: usize = 3;

/// The fitted scatter of each measurement kind and the orientation weight of the final fit.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FittedScatter {
    /// σ per axis of the probe residuals \[mm\] (`None` without probe rows)
    pub probe_mm: Option<f64>,
    /// σ per axis of the tracker residuals \[mm\] (`None` without tracker rows)
    pub tracker_mm: Option<f64>,
    /// σ per axis of the orientation residuals \[rad\] (`None` without orientation rows)
    pub orientation_rad: Option<f64>,
    /// the orientation weight of the final fit \[mm²/rad²\]
    pub orientation_weight: f64,
    /// whether the weight was stated by the user (not fitted)
    pub stated: bool,
    /// fits run while the weight settled
    pub fits: usize,
    /// whether the weight settled (its last change below [`SCATTER_SETTLED`])
    pub settled: bool,
}

impl FittedScatter {
    /// The scatter of `fit`'s residuals on `rows` (the rows of the fit, in its order), fitted
    /// with `weights`.
    pub fn of(rows: &[Measurement], fit: &Identification, weights: &KindWeights) -> Self {
        let n = fit.params.len();
        let sigmas = KindSigmas::estimate(rows, &fit.residuals, n);
        Self {
            probe_mm: sigmas.probe_mm,
            tracker_mm: sigmas.tracker_mm,
            orientation_rad: KindSigmas::orientation_rad(rows, &fit.residuals, n),
            orientation_weight: weights.orientation,
            stated: false,
            fits: 1,
            settled: true,
        }
    }

    /// The orientation weight these σ call for, relative to `weights` (probe weight 1):
    /// `w_ref · (σ_ref / σ_o)²` with the probe rows as reference, or the tracker rows without
    /// probe rows. `None` when a σ is missing or zero.
    pub fn orientation_weight_for(&self, weights: &KindWeights) -> Option<f64> {
        let ok = |s: Option<f64>| s.filter(|v| *v > 0.0 && v.is_finite());
        let (w_ref, s_ref) = match (ok(self.probe_mm), ok(self.tracker_mm)) {
            (Some(p), _) => (weights.probe, p),
            (None, Some(t)) => (weights.tracker, t),
            (None, None) => return None,
        };
        let s_o = ok(self.orientation_rad)?;
        Some(w_ref * (s_ref / s_o).powi(2)).filter(|w| w.is_finite() && *w > 0.0)
    }

    /// One line for the terminal: σ per kind in µm and mrad, and the orientation weight.
    pub fn one_line(&self) -> String {
        let mut kinds = Vec::new();
        if let Some(p) = self.probe_mm {
            kinds.push(format!("probe {:.2} µm", 1e3 * p));
        }
        if let Some(t) = self.tracker_mm {
            kinds.push(format!("tracker {:.2} µm", 1e3 * t));
        }
        if let Some(o) = self.orientation_rad {
            kinds.push(format!("orientation {:.3} mrad", 1e3 * o));
        }
        let how = if self.stated {
            "stated (--orientation-weight)".to_string()
        } else {
            format!(
                "from the fitted scatter, {} fit(s), {}",
                self.fits,
                if self.settled { "settled" } else { "still changing at the fit cap" }
            )
        };
        format!(
            "fitted scatter per axis: {}; orientation weight {:.4} mm²/rad² ({how})",
            kinds.join(", "),
            self.orientation_weight
        )
    }
}

/// Runs `fit` with `options`, then, while the orientation weight the fitted scatter calls for
/// differs from the one used by [`SCATTER_SETTLED`] or more, again with that weight (at most
/// [`SCATTER_MAX_FITS`] fits). `scatter` reads the fitted scatter of a fit's output made with
/// the given weights. Without orientation rows (no weight called for) `fit` runs once.
///
/// # Errors
/// The first error of `fit`.
pub fn fit_with_fitted_scatter<T, E>(
    options: &IdentifyOptions,
    mut fit: impl FnMut(&IdentifyOptions) -> Result<T, E>,
    scatter: impl Fn(&T, &KindWeights) -> FittedScatter,
) -> Result<(T, FittedScatter), E> {
    let mut options = options.clone();
    let mut fits = 0;
    loop {
        let out = fit(&options)?;
        fits += 1;
        let mut s = scatter(&out, &options.weights);
        s.fits = fits;
        let Some(next) = s.orientation_weight_for(&options.weights) else {
            return Ok((out, s));
        };
        let change = (next / options.weights.orientation - 1.0).abs();
        s.settled = change < SCATTER_SETTLED;
        if s.settled || fits >= SCATTER_MAX_FITS {
            return Ok((out, s));
        }
        options.weights.orientation = next;
    }
}
