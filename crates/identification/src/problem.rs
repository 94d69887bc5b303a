//! The weighted (and optionally regularised) least-squares problem: stacked residuals and the
//! stacked Jacobian, assembled without allocation into caller-owned buffers.
//!
//! Rows: measurement k occupies rows `3k..3k+3` (x, y, z), multiplied by `√w_k` (its kind's
//! weight, times its own row weight when `IdentifyOptions::row_weights` is given); then one
//! row per parameter with a finite prior. The residual of a measurement is
//! [`Model::residual`] (`target − FK`) plus the recorded centring offset of a probe measurement
//! ([`Measurement::target_offset_mm`]: the observed target is `position + offset`); the Jacobian row block is
//! [`Model::measurement_jacobian_into`] (`d(FK − target)/dρ`), so that
//! `r(ρ + Δ) ≈ r(ρ) − J Δ` and the Gauss–Newton step solves `J Δ ≈ r`.

use faer::MatMut;
use nalgebra::Vector3;
use vatcal_core::{Measurement, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::sets::DataDesign;

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
    /// known distances between fixed points (one row each) and between parallel planes
    /// (three rows each) after the measurement rows
    pub design: DataDesign,
    /// `σ_data / σ_d` of every constraint row
    pub distance_weight: Vec<f64>,
}

impl<'a> Problem<'a> {
    pub fn new(
        measurements: &'a [Measurement],
        params: &'a ParamSet,
        start: Vec<f64>,
        options: &IdentifyOptions,
    ) -> Self {
        let prior_data_sigma_mm = if options.prior_sigma_from_fit {
            options.distance_data_sigma_mm.unwrap_or(options.measurement_sigma_mm)
        } else {
            options.measurement_sigma_mm
        };
        let priors = options
            .priors
            .as_ref()
            .map(|p| {
                p.iter()
                    .enumerate()
                    .filter(|(_, s)| s.is_finite())
                    .map(|(j, s)| (j, prior_data_sigma_mm / s))
                    .collect()
            })
            .unwrap_or_default();
        Self {
            measurements,
            params,
            row_weight: match &options.row_weights {
                None => row_weights(measurements, &options.weights),
                Some(per_row) => row_weights_times(measurements, &options.weights, per_row),
            },
            priors,
            start,
            design: DataDesign {
                distances: options.point_distances.clone(),
                plane_distances: options.plane_distances.clone(),
                ..DataDesign::default()
            },
            distance_weight: {
                let data = options.distance_data_sigma_mm.unwrap_or(options.measurement_sigma_mm);
                let points = options.point_distances.iter().map(|d| data / d.sigma_mm);
                let planes = options.plane_distances.iter().flat_map(|d| [data / d.sigma_mm; 3]);
                points.chain(planes).collect()
            },
        }
    }

    /// Number of data rows: 3 per measurement, then the known distances' rows (the prior rows
    /// follow).
    pub fn measurement_rows(&self) -> usize {
        3 * self.measurements.len() + self.design.constraint_rows()
    }

    /// The distance rows: residuals into `r[3n..]` and, when `jac` is given, their Jacobian
    /// rows (weighted).
    fn distance_rows(
        &self,
        model: &Model,
        r: &mut [f64],
        mut jac: Option<&mut MatMut<'_, f64>>,
    ) -> Result<(), IdentifyError> {
        let base = 3 * self.measurements.len();
        self.design.for_each_constraint_row(model, &self.params.0, |k, e, row| {
            let w = self.distance_weight[k];
            r[base + k] = w * e;
            if let Some(j) = jac.as_deref_mut() {
                for (c, v) in row.iter().enumerate() {
                    j[(base + k, c)] = w * v;
                }
            }
        })?;
        Ok(())
    }

    /// The data rows that carry information: [`Problem::measurement_rows`] less the two zero
    /// rows of every plane contact without the tool axis held normal (the degrees of freedom
    /// count these).
    pub fn informative_rows(&self) -> usize {
        vatcal_core::informative_rows(self.measurements) + self.design.constraint_rows()
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
            let e = model.residual(m).map_err(|source| IdentifyError::Measurement { index: k, source })?
                + m.target_offset_mm();
            vecs[k] = e;
            let w = self.row_weight[k];
            r[3 * k..3 * k + 3].copy_from_slice(&[w * e.x, w * e.y, w * e.z]);
        }
        if self.design.constraint_rows() > 0 {
            self.distance_rows(model, r, None)?;
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
                .map_err(|source| IdentifyError::Measurement { index: k, source })?
                + m.target_offset_mm();
            vecs[k] = e;
            let w = self.row_weight[k];
            r[3 * k..3 * k + 3].copy_from_slice(&[w * e.x, w * e.y, w * e.z]);
            for c in 0..l {
                for a in 0..3 {
                    jac[(3 * k + a, c)] = w * block[3 * c + a];
                }
            }
        }
        if self.design.constraint_rows() > 0 {
            self.distance_rows(model, r, Some(&mut jac))?;
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
    measurements.iter().map(|m| weights.of(&m.target).sqrt()).collect()
}

/// `√(w_kind · w_k)` of every measurement: its kind's weight times its own row weight
/// ([`IdentifyOptions::row_weights`]; a missing entry counts 1).
pub(crate) fn row_weights_times(
    measurements: &[Measurement],
    weights: &KindWeights,
    per_row: &[f64],
) -> Vec<f64> {
    measurements
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let kind = weights.of(&m.target);
            (kind * per_row.get(k).copied().unwrap_or(1.0)).sqrt()
        })
        .collect()
}

/// The stacked, weighted residual vector `√w_k (target_k − FK_k)` of all measurements
/// (3 entries per measurement, x y z) \[mm\]. The stacked Jacobian with the same row layout is
/// `vatcal_observability::assemble_jacobian` (unweighted: multiply row block k by `√w_k`).
pub fn residual_vector(
    model: &Model,
    measurements: &[Measurement],
    weights: &KindWeights,
) -> Result<Vec<f64>, IdentifyError> {
    let w = row_weights(measurements, weights);
    let mut r = Vec::with_capacity(3 * measurements.len());
    for (k, m) in measurements.iter().enumerate() {
        let e = model.residual(m).map_err(|source| IdentifyError::Measurement { index: k, source })?
            + m.target_offset_mm();
        r.extend(e.iter().map(|v| v * w[k]));
    }
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;
    use vatcal_core::CellFile;
    use vatcal_sim::truth::{
        ErrorBudget, perturbed_truth, probe_start_poses, synthetic_tracker_measurements,
    };

    /// The assembled Jacobian (weights and prior rows included) is minus the derivative of the
    /// assembled residual vector (central differences). At a model with zero compliances the
    /// held-fixed gravity torques make no difference, so the match is to round-off.
    #[test]
    fn stacked_jacobian_matches_central_differences() {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("fixture");
        let model = Model::from_cell(&cell).expect("model");
        let truth = perturbed_truth(&model, 5, &ErrorBudget::realistic());
        let mut measurements = probe_start_poses(&model, 6, 9);
        measurements.extend(synthetic_tracker_measurements(&truth, 3, 0.01, 4));
        let params = ParamSet::paper34();
        let mut priors = vec![f64::INFINITY; params.len()];
        priors[3] = 0.01;
        priors[30] = 0.5;
        let options = IdentifyOptions {
            weights: KindWeights { probe: 4.0, tracker: 0.25, ..KindWeights::default() },
            priors: Some(priors),
            ..IdentifyOptions::default()
        };
        let values = model.params(&params).expect("values");
        let problem = Problem::new(&measurements, &params, values.clone(), &options);
        let (m, l, n) = (problem.rows(), problem.cols(), measurements.len());
        assert_eq!(m, 3 * n + 2);
        let mut jac = Mat::<f64>::zeros(m, l);
        let mut r = vec![0.0; m];
        let mut vecs = vec![Vector3::zeros(); n];
        let mut block = vec![0.0; 3 * l];
        problem.jacobian(&model, &values, jac.as_mut(), &mut r, &mut vecs, &mut block).expect("jacobian");
        let residual_at = |v: &[f64]| {
            let mut md = model.clone();
            md.set_params(&params, v).expect("set");
            let mut out = vec![0.0; m];
            let mut vv = vec![Vector3::zeros(); n];
            problem.residuals(&md, v, &mut out, &mut vv).expect("residuals");
            out
        };
        let r0 = residual_at(&values);
        for i in 0..m {
            assert!((r0[i] - r[i]).abs() < 1e-10, "residual row {i}");
        }
        for (j, p) in params.iter().enumerate() {
            let h = p.typical_scale() * 1e-3;
            let (mut plus, mut minus) = (values.clone(), values.clone());
            plus[j] += h;
            minus[j] -= h;
            let (rp, rm) = (residual_at(&plus), residual_at(&minus));
            for i in 0..m {
                let fd = -(rp[i] - rm[i]) / (2.0 * h);
                let scale = jac.col(j).norm_l2().max(1e-12);
                assert!((fd - jac[(i, j)]).abs() <= 1e-6 * scale, "{p} row {i}: fd {fd} vs {}", jac[(i, j)]);
            }
        }
    }
}
