//! Observability indices O1..O5 (background.md §3), always reported together with the rank,
//! the condition number and σ_min, because O1 alone does not detect rank deficiency.
//!
//! With σ₁ ≥ … ≥ σ_L the singular values of the stacked Jacobian (3m rows for m poses, L
//! columns, after the chosen [`ColumnScaling`]):
//!
//! | index | formula |
//! |---|---|
//! | O1 | `exp(mean ln σ_i) / √m` = (σ₁⋯σ_L)^{1/L}/√m, m = number of **poses** |
//! | O2 | σ_L / σ₁ |
//! | O3 | σ_L |
//! | O4 | σ_L² / σ₁ |
//! | O5 | 1 / Σ 1/σ_i |
//!
//! O1 is computed through logarithms (never as a raw product). If there are fewer rows than
//! columns the missing singular values are zeros, so O1..O5 are 0 and the condition number is
//! ∞. The rank is always counted on the *unit-column-normalised* Jacobian with the tolerance of
//! [`crate::identifiability`], so it does not depend on the scaling used for the indices.

use std::fmt;

use faer::{Mat, MatRef};
use vatcal_core::{Measurement, ParamSet};
use vatcal_kinematics::Model;

use crate::error::ObservabilityError;
use crate::identifiability::{
    ColumnScaling, DEFAULT_RELATIVE_TOLERANCE, assemble_jacobian, column_scale_factors, scale_columns,
};

/// O1..O5 with the figures that must accompany them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObservabilityIndices {
    /// (Π σ_i)^{1/L} / √m
    pub o1: f64,
    /// σ_L / σ₁
    pub o2: f64,
    /// σ_L
    pub o3: f64,
    /// σ_L² / σ₁
    pub o4: f64,
    /// 1 / Σ 1/σ_i
    pub o5: f64,
    /// numerical rank of the unit-column-normalised Jacobian
    pub rank: usize,
    /// σ₁ / σ_L of the scaled Jacobian (∞ when σ_L = 0)
    pub condition_number: f64,
    /// σ_L of the scaled Jacobian (= O3)
    pub sigma_min: f64,
    /// σ₁ of the scaled Jacobian
    pub sigma_max: f64,
    /// m, the number of poses
    pub pose_count: usize,
    /// L, the number of parameters
    pub parameter_count: usize,
    /// the column scaling the indices were computed with
    pub scaling: ColumnScaling,
}

impl ObservabilityIndices {
    /// The indices from the L singular values of the scaled Jacobian (any order; fewer than
    /// `parameter_count` values are padded with zeros) of a design with `pose_count` poses.
    /// `rank` is filled in by the caller (see [`observability_indices`]); here it is the
    /// count of values above `1e-8 · σ₁`.
    pub fn from_singular_values(
        singular_values: &[f64],
        parameter_count: usize,
        pose_count: usize,
        scaling: ColumnScaling,
    ) -> Self {
        let mut s: Vec<f64> = singular_values.iter().map(|x| x.max(0.0)).collect();
        s.resize(parameter_count.max(s.len()), 0.0);
        s.sort_by(|a, b| b.total_cmp(a));
        let l = s.len().max(1) as f64;
        let sigma_max = s.first().copied().unwrap_or(0.0);
        let sigma_min = s.last().copied().unwrap_or(0.0);
        let mean_ln = s.iter().map(|x| x.ln()).sum::<f64>() / l;
        let o1 = mean_ln.exp() / (pose_count.max(1) as f64).sqrt();
        let ratio = |num: f64| if sigma_max > 0.0 { num / sigma_max } else { 0.0 };
        let inv_sum: f64 = s.iter().map(|x| 1.0 / x).sum();
        Self {
            o1,
            o2: ratio(sigma_min),
            o3: sigma_min,
            o4: ratio(sigma_min * sigma_min),
            o5: if inv_sum.is_finite() && inv_sum > 0.0 { 1.0 / inv_sum } else { 0.0 },
            rank: s.iter().filter(|x| **x > DEFAULT_RELATIVE_TOLERANCE * sigma_max).count(),
            condition_number: if sigma_min > 0.0 { sigma_max / sigma_min } else { f64::INFINITY },
            sigma_min,
            sigma_max,
            pose_count,
            parameter_count,
            scaling,
        }
    }

    /// True when the design identifies all parameters.
    pub fn is_full_rank(&self) -> bool {
        self.rank == self.parameter_count
    }
}

impl fmt::Display for ObservabilityIndices {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "O1 {:.4}  O2 {:.4e}  O3 {:.4e}  O4 {:.4e}  O5 {:.4e}  rank {}/{}  cond {:.4e}  σ_min {:.4e}  ({} poses, {} columns)",
            self.o1,
            self.o2,
            self.o3,
            self.o4,
            self.o5,
            self.rank,
            self.parameter_count,
            self.condition_number,
            self.sigma_min,
            self.pose_count,
            self.scaling
        )
    }
}

/// Singular values of `a` (descending). Errors only if the SVD fails to converge.
pub fn singular_values(a: MatRef<'_, f64>) -> Result<Vec<f64>, ObservabilityError> {
    let mut s = a.singular_values().map_err(|e| ObservabilityError::Numerical(format!("SVD: {e:?}")))?;
    s.sort_by(|x, y| y.total_cmp(x));
    Ok(s)
}

/// Numerical rank of the unit-column-normalised `a` (tolerance as in
/// [`crate::identifiability`]).
pub fn normalized_rank(a: MatRef<'_, f64>) -> Result<usize, ObservabilityError> {
    let mut n = a.to_owned();
    scale_columns(&mut n, &column_scale_factors(a, &[], ColumnScaling::UnitNorm));
    let s = singular_values(n.as_ref())?;
    let tol = DEFAULT_RELATIVE_TOLERANCE.max(a.nrows().max(a.ncols()) as f64 * f64::EPSILON);
    let threshold = tol * s.first().copied().unwrap_or(0.0);
    Ok(s.iter().filter(|x| **x > threshold).count())
}

/// O1..O5, rank, condition number and σ_min of a natural-unit Jacobian `j` (3 rows per pose,
/// columns = `params`) after `scaling`. The number of poses is `j.nrows() / 3`.
///
/// # Errors
/// [`ObservabilityError::InvalidInput`] when `j` does not have one column per parameter;
/// [`ObservabilityError::Numerical`] when the SVD does not converge.
pub fn observability_indices(
    j: MatRef<'_, f64>,
    params: &ParamSet,
    scaling: ColumnScaling,
) -> Result<ObservabilityIndices, ObservabilityError> {
    observability_indices_for(j, params, scaling, j.nrows() / 3)
}

/// [`observability_indices`] with the number of poses `m` of O1 given: a Jacobian with rows
/// beyond the measurement blocks (known distances,
/// [`crate::sets::assemble_design_jacobian`]) still has `m` = the number of measurements. A
/// plane contact counts as one pose, whether it gives 1 or 3 informative rows (its zero rows
/// add nothing to `JᵀJ`), so O1 compares designs of equal size as the paper does.
///
/// # Errors
/// As [`observability_indices`].
pub fn observability_indices_for(
    j: MatRef<'_, f64>,
    params: &ParamSet,
    scaling: ColumnScaling,
    pose_count: usize,
) -> Result<ObservabilityIndices, ObservabilityError> {
    if j.ncols() != params.len() {
        return Err(ObservabilityError::InvalidInput(format!(
            "Jacobian has {} columns for {} parameters",
            j.ncols(),
            params.len()
        )));
    }
    let mut scaled: Mat<f64> = j.to_owned();
    scale_columns(&mut scaled, &column_scale_factors(j, &params.0, scaling));
    let s = singular_values(scaled.as_ref())?;
    let mut idx = ObservabilityIndices::from_singular_values(&s, params.len(), pose_count, scaling);
    idx.rank = normalized_rank(j)?;
    Ok(idx)
}

/// [`observability_indices`] of a measurement set.
pub fn indices_of(
    model: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
    scaling: ColumnScaling,
) -> Result<ObservabilityIndices, ObservabilityError> {
    if measurements.is_empty() {
        return Err(ObservabilityError::NoMeasurements);
    }
    observability_indices(assemble_jacobian(model, measurements, params)?.as_ref(), params, scaling)
}
