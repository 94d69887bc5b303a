//! Options of [`identify`](crate::identify).

use serde::{Deserialize, Serialize};
use vatcal_core::{ParamSet, PlaneDistance, PointDistance};

use crate::{IdentifyError, Method};

/// Relative weights of the measurement kinds in the weighted least-squares cost
/// `Σ_k w_k ‖r_k‖²`: an inverse-variance ratio. With probe noise σ_p and tracker noise σ_t,
/// `tracker = (σ_p / σ_t)²` (probe = 1) gives the statistically efficient combination.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KindWeights {
    /// weight of probe measurements (> 0)
    pub probe: f64,
    /// weight of tracker measurements (> 0)
    pub tracker: f64,
    /// weight of orientation measurements (> 0) \[mm²/rad²\]: `(σ_p / σ_o)²` with σ_o the
    /// orientation noise \[rad\] (default 100: 0.01 mm ≙ 1 mrad)
    #[serde(default = "default_orientation_weight")]
    pub orientation: f64,
    /// weight of plane contacts (> 0; default 1: contact heights in mm like the points)
    #[serde(default = "default_plane_weight")]
    pub plane: f64,
}

fn default_plane_weight() -> f64 {
    1.0
}

fn default_orientation_weight() -> f64 {
    KindWeights::DEFAULT_ORIENTATION
}

impl KindWeights {
    /// Default orientation weight \[mm²/rad²\]: a probe σ of 0.01 mm against 1 mrad.
    pub const DEFAULT_ORIENTATION: f64 = 100.0;

    /// The weight of a measurement's kind.
    pub fn of(&self, target: &vatcal_core::Target) -> f64 {
        match target {
            vatcal_core::Target::Probe { .. } => self.probe,
            vatcal_core::Target::Tracker { .. } => self.tracker,
            vatcal_core::Target::Orientation { .. } => self.orientation,
            vatcal_core::Target::Plane { .. } => self.plane,
        }
    }
}

impl Default for KindWeights {
    fn default() -> Self {
        Self { probe: 1.0, tracker: 1.0, orientation: Self::DEFAULT_ORIENTATION, plane: 1.0 }
    }
}

/// How the unknowns are scaled for the damped step (`ρ = ρ_ref + D δ`, `J_s = J D`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Scaling {
    /// `D = diag(1/‖J_j‖)`, updated as the running maximum of the column norms (Moré's
    /// MINPACK rule): damping is then invariant to the parameter units. Default.
    #[default]
    ColumnNorms,
    /// `D = diag(typical a-priori standard deviation)` ([`vatcal_core::ParamId::typical_scale`]).
    APriori,
    /// No scaling (natural units: mm, rad, rad/(N·m)); damping then favours the parameters with
    /// the largest columns. For experiments only.
    None,
}

/// Options of [`identify`](crate::identify). `Default` is Levenberg–Marquardt with the
/// tolerances below.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifyOptions {
    /// estimation method
    pub method: Method,
    /// iteration cap (Jacobian evaluations)
    pub max_iterations: usize,
    /// stop when the largest parameter change of the Gauss–Newton step of the current
    /// linearisation, in units of the parameter's typical a-priori standard deviation
    /// ([`vatcal_core::ParamId::typical_scale`]), is below this (default 1e-10: 1e-11 mm for a
    /// length, 1e-13 rad for an angle)
    pub step_tolerance: f64,
    /// stop when every column of the weighted Jacobian is orthogonal to the residual up to this
    /// cosine: `max_j |J_jᵀ r| / (‖J_j‖ ‖r‖)` (default 1e-10)
    pub gradient_tolerance: f64,
    /// stop when even the undamped linearised model cannot reduce the cost by more than this
    /// fraction: `‖Q₁ᵀ r‖² ≤ cost_tolerance · ‖r‖²` (default 1e-16)
    pub cost_tolerance: f64,
    /// weights of probe and tracker measurements
    pub weights: KindWeights,
    /// optional priors: per-parameter standard deviations (internal units, same order as the
    /// parameter set) of a Gaussian prior centred on the **starting** values; the fit is then
    /// the maximum a-posteriori estimate (ridge regression toward the start). `f64::INFINITY`
    /// leaves a parameter free. With finite priors on every unidentifiable parameter a
    /// rank-deficient problem is accepted.
    pub priors: Option<Vec<f64>>,
    /// standard deviation \[mm\] of one coordinate of a weight-1 measurement; used only to
    /// balance priors against the data (the prior row of parameter j is
    /// `(σ_meas / σ_j)(ρ_j − ρ_start,j)`). Default 0.003 mm.
    pub measurement_sigma_mm: f64,
    /// scaling of the unknowns for the damped step
    pub scaling: Scaling,
    /// initial damping λ₀ = `initial_lambda · max diag(J_sᵀ J_s)` (default 1e-6: the nominal model is a good start; the gain-ratio control raises λ within a few trial steps when it is not)
    pub initial_lambda: f64,
    /// |correlation| above which a parameter pair is reported as strongly correlated (0.9)
    pub correlation_threshold: f64,
    /// refuse rank-deficient data before solving (vatcal-observability's check). Default true.
    pub check_identifiability: bool,
    /// refuse a fit whose weighted, column-normalised Jacobian at the solution has a larger
    /// condition number (default 1e3; healthy designs of this cell are ~30, Schröer's rule of
    /// thumb asks for < 100). Catches degeneracies the rank check at the start cannot see
    /// (e.g. one or two calibration positions with a start model that misses them by ~1 mm).
    /// Not applied when finite priors are given. `f64::INFINITY` switches it off.
    pub max_condition_number: f64,
    /// return `Ok` with `converged = false` when the iteration cap is reached (default false:
    /// the cap is a failure reported with its log)
    pub accept_iteration_cap: bool,
    /// Gauss–Newton and the paper-literal method: the fit has diverged when the mean residual
    /// exceeds this factor times the starting mean residual (default 100)
    pub divergence_factor: f64,
    /// known distances between fixed points (calibration positions): one residual row each,
    /// `distance − |p_a − p_b|` weighted by `σ_data / sigma_mm` (see
    /// `distance_sigma_from_fit`), so that the
    /// positions identified as parameters keep the scale (default none)
    pub point_distances: Vec<PointDistance>,
    /// known distances between parallel contact planes: three residual rows each
    /// (`vatcal_observability::sets::plane_distance_rows`), weighted like the point distances
    /// (default none)
    pub plane_distances: Vec<PlaneDistance>,
    /// weigh the known distances against the data's own scatter (default true): a distance
    /// row is weighted `σ_data / σ_d`, where `σ_data` is first `measurement_sigma_mm` and then,
    /// refit by refit, σ̂ of the data rows of the previous fit (`√(Σ w_k‖e_k‖² / (3n − L))`),
    /// until it changes by less than 5 % (at most 5 refits, each from the start). The σ of a
    /// distance is a property of the fixture (`PointDistance::sigma_mm`); how much one distance
    /// row counts against hundreds of data rows then follows from how well the data rows
    /// actually fit — not from the a-priori σ of an instrument the data may not come from.
    /// Without distances it changes nothing. `false`: `σ_data = measurement_sigma_mm`
    pub distance_sigma_from_fit: bool,
    /// weigh the priors against the data's own scatter as the distances
    /// (`distance_sigma_from_fit`): the prior row of parameter j is `(σ_data / σ_j)(ρ_j −
    /// ρ_start,j)` with `σ_data` the data σ̂ of the previous fit, so that a prior of σ_j means
    /// σ_j whatever the instrument's noise. Default false (`σ_data = measurement_sigma_mm`);
    /// the cross-validated path ([`CvOptions::fit_options`](crate::CvOptions::fit_options))
    /// sets it
    pub prior_sigma_from_fit: bool,
    /// the `σ_data` of the distance rows (and, with `prior_sigma_from_fit`, of the prior rows)
    /// when set (what [`identify`](crate::identify)'s re-weighting sets; `None`:
    /// `measurement_sigma_mm`)
    pub distance_data_sigma_mm: Option<f64>,
    /// optional weight of every measurement row (same order and length as the measurements;
    /// finite, > 0): multiplies the weight of the row's kind (`weights`), so row k counts
    /// `weights.kind · row_weights[k]` in the cost and in σ̂ (the σ̂ that weighs known
    /// distances and priors against the data, `distance_sigma_from_fit` and
    /// `prior_sigma_from_fit`, is then the robust one, [`crate::robust_sigma_mm`]: a
    /// down-weighted bad row would still dominate `Σ w‖e‖²`). What the robust fit
    /// ([`crate::irls`]: iteratively reweighted least squares) sets; `None` (default): every
    /// row has its kind's weight. A vector belongs to one set of rows: the cross-validated
    /// choice's fold fits cannot use it (give it to [`identify`](crate::identify))
    pub row_weights: Option<Vec<f64>>,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        Self {
            method: Method::LevenbergMarquardt,
            max_iterations: 50,
            step_tolerance: 1e-10,
            gradient_tolerance: 1e-10,
            cost_tolerance: 1e-16,
            weights: KindWeights::default(),
            priors: None,
            measurement_sigma_mm: 0.003,
            scaling: Scaling::ColumnNorms,
            initial_lambda: 1e-6,
            correlation_threshold: 0.9,
            check_identifiability: true,
            max_condition_number: 1e3,
            accept_iteration_cap: false,
            divergence_factor: 100.0,
            point_distances: Vec::new(),
            plane_distances: Vec::new(),
            distance_sigma_from_fit: true,
            prior_sigma_from_fit: false,
            distance_data_sigma_mm: None,
            row_weights: None,
        }
    }
}

impl IdentifyOptions {
    /// Default options with another method.
    pub fn with_method(method: Method) -> Self {
        Self { method, ..Self::default() }
    }

    /// Checks every option; errors name the field.
    pub fn check(&self, params: &ParamSet) -> Result<(), IdentifyError> {
        let bad = |m: String| Err(IdentifyError::InvalidOptions(m));
        if self.max_iterations == 0 {
            return bad("max_iterations must be at least 1".into());
        }
        let nonneg = [
            ("step_tolerance", self.step_tolerance),
            ("gradient_tolerance", self.gradient_tolerance),
            ("cost_tolerance", self.cost_tolerance),
        ];
        for (name, v) in nonneg {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} must be finite and >= 0, got {v}"));
            }
        }
        let positive = [
            ("weights.probe", self.weights.probe),
            ("weights.tracker", self.weights.tracker),
            ("measurement_sigma_mm", self.measurement_sigma_mm),
            ("initial_lambda", self.initial_lambda),
            ("divergence_factor", self.divergence_factor),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{name} must be finite and > 0, got {v}"));
            }
        }
        if self.max_condition_number.is_nan() || self.max_condition_number < 1.0 {
            return bad(format!("max_condition_number must be >= 1, got {}", self.max_condition_number));
        }
        if !(0.0..=1.0).contains(&self.correlation_threshold) {
            return bad(format!(
                "correlation_threshold must be in [0, 1], got {}",
                self.correlation_threshold
            ));
        }
        let distances = self.point_distances.iter().map(|d| (d.a, d.b, d.distance_mm, d.sigma_mm));
        let planes = self.plane_distances.iter().map(|d| (d.a, d.b, d.distance_mm, d.sigma_mm));
        for (a, b, distance_mm, sigma_mm) in distances.chain(planes) {
            if !(distance_mm.is_finite() && distance_mm > 0.0 && sigma_mm.is_finite() && sigma_mm > 0.0) {
                return bad(format!(
                    "point/plane distances: {a},{b}: distance {distance_mm} mm and sigma {sigma_mm} mm must be finite and > 0"
                ));
            }
        }
        if let Some(v) = self.distance_data_sigma_mm
            && !(v.is_finite() && v > 0.0)
        {
            return bad(format!("distance_data_sigma_mm must be finite and > 0, got {v}"));
        }
        if let Some(w) = &self.row_weights
            && let Some((k, v)) = w.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v > 0.0))
        {
            return bad(format!("row_weights: the weight of row {k} must be finite and > 0, got {v}"));
        }
        if self.method == Method::PaperLiteral
            && !(self.point_distances.is_empty() && self.plane_distances.is_empty())
        {
            return bad("point distances are not supported by the paper-literal method".into());
        }
        if let Some(p) = &self.priors {
            if p.len() != params.len() {
                return bad(format!(
                    "priors: {} standard deviations for {} parameters",
                    p.len(),
                    params.len()
                ));
            }
            if let Some((k, v)) = p.iter().enumerate().find(|(_, v)| v.is_nan() || **v <= 0.0) {
                return bad(format!(
                    "priors: standard deviation of `{}` must be > 0 (or inf), got {v}",
                    params.0[k]
                ));
            }
            if self.method == Method::PaperLiteral && p.iter().any(|v| v.is_finite()) {
                return bad("priors are not supported by the paper-literal method".into());
            }
        }
        Ok(())
    }
}
