//! The weighted (and optionally regularised) least-squares problem: stacked residuals and the
//! stacked Jacobian, assembled without allocation into caller-owned buffers.
//!
//! Rows: measurement k occupies rows `3k..3k+3` (x, y, z), multiplied by `√w_k` (its kind's
//! weight); then one row per parameter with a finite prior. The residual of a measurement is
//! [`Model::residual`] (`target − FK`); the Jacobian row block is
//! [`Model::measurement_jacobian_into`] (`d(FK − target)/dρ`), so that
//! `r(ρ + Δ) ≈ r(ρ) − J Δ` and the Gauss–Newton step solves `J Δ ≈ r`.

use faer::MatMut;
use nalgebra::Vector3;
use vatcal_core::{Measurement, ParamSet, Target};
use vatcal_kinematics::Model;

use crate::{IdentifyError, IdentifyOptions, KindWeights};

/// The fixed data of one fit.
#[derive(Debug)]
pub(crate) struct Problem<'a> {
    pub measurements: &'a [Measurement],
    pub params: &'a ParamSet,
    /// `√w_k` per measurement
    pub row_weight: Vec<f64>,
    /// `(parameter index, σ_meas/σ_j)` for every parameter with a finite prior
    pub priors: Vec<(usize, f64)>,
    /// starting values (prior means)
    pub start: Vec<f64>,
}

impl<'a> Problem<'a> {
    pub fn new(
        measurements: &'a [Measurement],
        params: &'a ParamSet,
        start: Vec<f64>,
        options: &IdentifyOptions,
    ) -> Self {
        let priors = options
            .priors
            .as_ref()
            .map(|p| {
                p.iter()
                    .enumerate()
                    .filter(|(_, s)| s.is_finite())
                    .map(|(j, s)| (j, options.measurement_sigma_mm / s))
                    .collect()
            })
            .unwrap_or_default();
        Self { measurements, params, row_weight: row_weights(measurements, &options.weights), priors, start }
    }

    /// Number of measurement rows (3 per measurement).
    pub fn measurement_rows(&self) -> usize {
        3 * self.measurements.len()
    }

    /// Total rows including prior rows.
    pub fn rows(&self) -> usize {
        self.measurement_rows() + self.priors.len()
    }

    /// Number of unknowns.
    pub fn cols(&self) -> usize {
        self.params.len()
    }

    /// Weighted residual vector `r` (all rows) and the unweighted per-measurement residual
    /// vectors at `model` (whose parameters are `values`).
    pub fn residuals(
        &self,
        model: &Model,
        values: &[f64],
        r: &mut [f64],
        vecs: &mut [Vector3<f64>],
    ) -> Result<(), IdentifyError> {
        for (k, m) in self.measurements.iter().enumerate() {
            let e = model.residual(m).map_err(|source| IdentifyError::Measurement { index: k, source })?;
            vecs[k] = e;
            let w = self.row_weight[k];
            r[3 * k..3 * k + 3].copy_from_slice(&[w * e.x, w * e.y, w * e.z]);
        }
        self.prior_residuals(values, r);
        Ok(())
    }

    fn prior_residuals(&self, values: &[f64], r: &mut [f64]) {
        let base = self.measurement_rows();
        for (row, (j, c)) in self.priors.iter().enumerate() {
            r[base + row] = c * (self.start[*j] - values[*j]);
        }
    }

    /// Weighted Jacobian (all rows, natural units, no column scaling) into `jac`, and the
    /// residuals as [`Problem::residuals`]. `block` is scratch of length `3 · cols`.
    pub fn jacobian(
        &self,
        model: &Model,
        values: &[f64],
        mut jac: MatMut<'_, f64>,
        r: &mut [f64],
        vecs: &mut [Vector3<f64>],
        block: &mut [f64],
    ) -> Result<(), IdentifyError> {
        let l = self.cols();
        for (k, m) in self.measurements.iter().enumerate() {
            let e = model
                .measurement_jacobian_into(m, &self.params.0, block)
                .map_err(|source| IdentifyError::Measurement { index: k, source })?;
            vecs[k] = e;
            let w = self.row_weight[k];
            r[3 * k..3 * k + 3].copy_from_slice(&[w * e.x, w * e.y, w * e.z]);
            for c in 0..l {
                for a in 0..3 {
                    jac[(3 * k + a, c)] = w * block[3 * c + a];
                }
            }
        }
        let base = self.measurement_rows();
        for (row, (j, c)) in self.priors.iter().enumerate() {
            for col in 0..l {
                jac[(base + row, col)] = 0.0;
            }
            jac[(base + row, *j)] = *c;
        }
        self.prior_residuals(values, r);
        Ok(())
    }
}

/// `√w` of every measurement's kind.
pub(crate) fn row_weights(measurements: &[Measurement], weights: &KindWeights) -> Vec<f64> {
    measurements
        .iter()
        .map(|m| match m.target {
            Target::Probe { .. } => weights.probe.sqrt(),
            Target::Tracker { .. } => weights.tracker.sqrt(),
        })
        .collect()
}

/// The stacked, weighted residual vector `√w_k (target_k − FK_k)` of all measurements
/// (3 entries per measurement, x y z) [mm]. The stacked Jacobian with the same row layout is
/// `vatcal_observability::assemble_jacobian` (unweighted: multiply row block k by `√w_k`).
pub fn residual_vector(
    model: &Model,
    measurements: &[Measurement],
    weights: &KindWeights,
) -> Result<Vec<f64>, IdentifyError> {
    let w = row_weights(measurements, weights);
    let mut r = Vec::with_capacity(3 * measurements.len());
    for (k, m) in measurements.iter().enumerate() {
        let e = model.residual(m).map_err(|source| IdentifyError::Measurement { index: k, source })?;
        r.extend(e.iter().map(|v| v * w[k]));
    }
    Ok(r)
}
