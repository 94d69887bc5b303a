//! Noise per measurement kind and systematic CMM errors in the predicted uncertainty.
//!
//! * [`KindSigmas`] — σ of probe and of tracker residuals estimated separately from one fit
//!   (each group's RSS over its share of the degrees of freedom); [`KindSigmas::weights`] turns
//!   them into the inverse-variance [`KindWeights`] of a refit.
//! * [`CmmUncertainty`] — the coordinates of the TCPs (balls) and calibration positions come
//!   from a CMM and are held fixed in the fit; their errors (σ_c per coordinate, ~1–2 µm) are
//!   systematic: the fit absorbs them into the identified parameters (`δρ = −J⁺ J_c δc`), and
//!   the wrong TCP coordinates enter every prediction directly. At a pose with TCP Jacobians
//!   `P_ρ`, `P_c` the prediction error is `A δc` with `A = P_c − P_ρ J⁺ J_c`, so the
//!   systematic covariance is `σ_c² A Aᵀ`; it is added to the statistical `P_ρ Cov P_ρᵀ`.

use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::Serialize;
use vatcal_core::params::Axis;
use vatcal_core::{JointVector, Measurement, ParamId, ParamSet, Target};
use vatcal_observability::assemble_jacobian;

use crate::{Identification, IdentifyError, KindWeights};

/// σ per axis of probe and tracker residuals \[mm\] (`None` for a kind without measurements).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct KindSigmas {
    /// probe residuals, per axis \[mm\]
    pub probe_mm: Option<f64>,
    /// tracker residuals, per axis \[mm\]
    pub tracker_mm: Option<f64>,
}

impl KindSigmas {
    /// Estimates each kind's σ from the residuals of a fit of `fitted_params` parameters:
    /// `σ_g² = RSS_g / (3 n_g) · N / (N − L)` (the degrees of freedom shared in proportion to
    /// the residual counts). Orientation rows count in `N` but form a group of their own
    /// ([`KindSigmas::orientation_rad`]).
    pub fn estimate(measurements: &[Measurement], residuals: &[Vector3<f64>], fitted_params: usize) -> Self {
        Self {
            probe_mm: group_sigma(measurements, residuals, fitted_params, |t| {
                matches!(t, Target::Probe { .. })
            }),
            tracker_mm: group_sigma(measurements, residuals, fitted_params, |t| {
                matches!(t, Target::Tracker { .. })
            }),
        }
    }

    /// σ per axis of the orientation residuals \[rad\] of the same fit (`None` without
    /// orientation rows), estimated as [`KindSigmas::estimate`] does for the other kinds.
    pub fn orientation_rad(
        measurements: &[Measurement],
        residuals: &[Vector3<f64>],
        fitted_params: usize,
    ) -> Option<f64> {
        group_sigma(measurements, residuals, fitted_params, Target::is_orientation)
    }

    /// [`KindSigmas::weights`] with the orientation weight `(σ_p / σ_o)²` (or `(σ_t / σ_o)²`
    /// without probe rows, tracker then weighing 1) from the orientation σ `orientation_rad`;
    /// the default orientation weight when it or the reference σ is missing or zero.
    pub fn weights_with_orientation(&self, orientation_rad: Option<f64>) -> KindWeights {
        let mut w = self.weights();
        let ok = |s: Option<f64>| s.filter(|v| *v > 0.0 && v.is_finite());
        let reference = match (ok(self.probe_mm), ok(self.tracker_mm)) {
            (Some(p), _) => Some(p),
            (None, Some(t)) => Some(t),
            (None, None) => None,
        };
        if let (Some(r), Some(o)) = (reference, ok(orientation_rad)) {
            w.orientation = (r / o).powi(2);
        }
        w
    }

    /// Inverse-variance weights (probe = 1, tracker = (σ_p/σ_t)²); the default weights when a
    /// kind is missing or a σ is zero.
    pub fn weights(&self) -> KindWeights {
        match (self.probe_mm, self.tracker_mm) {
            (Some(p), Some(t)) if p > 0.0 && t > 0.0 && p.is_finite() && t.is_finite() => {
                KindWeights { probe: 1.0, tracker: (p / t).powi(2), ..KindWeights::default() }
            }
            _ => KindWeights::default(),
        }
    }
}

/// σ per axis of the residuals of the rows whose target passes `kind` (see
/// [`KindSigmas::estimate`]).
fn group_sigma(
    measurements: &[Measurement],
    residuals: &[Vector3<f64>],
    fitted_params: usize,
    kind: impl Fn(&Target) -> bool,
) -> Option<f64> {
    let n = vatcal_core::informative_rows(&measurements[..measurements.len().min(residuals.len())]);
    let dof_factor = if n > fitted_params { n as f64 / (n - fitted_params) as f64 } else { f64::NAN };
    let (mut rss, mut count) = (0.0, 0usize);
    for (m, r) in measurements.iter().zip(residuals) {
        if kind(&m.target) {
            rss += r.norm_squared();
            count += m.target.residual_rows();
        }
    }
    (count > 0 && dof_factor.is_finite()).then(|| (rss / count as f64 * dof_factor).sqrt())
}

/// Propagation of systematic CMM errors of the TCP and calibration-position coordinates into
/// the predictions of a fitted model (module docs).
#[derive(Debug, Clone)]
pub struct CmmUncertainty {
    /// σ of every CMM coordinate \[mm\]
    pub sigma_mm: f64,
    /// the CMM coordinates that were not fitted
    pub coordinates: ParamSet,
    /// `J⁺ J_c` (fitted parameters × CMM coordinates)
    transfer: DMatrix<f64>,
}

fn to_dmatrix(m: &faer::Mat<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(m.nrows(), m.ncols(), |r, c| m[(r, c)])
}

impl CmmUncertainty {
    /// Builds the propagation for `fit` (identified from `measurements` with kind `weights`);
    /// `sigma_mm` is the CMM standard deviation per coordinate.
    ///
    /// # Errors
    /// A measurement the model rejects, or `sigma_mm` negative / not finite.
    pub fn new(
        fit: &Identification,
        measurements: &[Measurement],
        weights: &KindWeights,
        sigma_mm: f64,
    ) -> Result<Self, IdentifyError> {
        if !(sigma_mm.is_finite() && sigma_mm >= 0.0) {
            return Err(IdentifyError::InvalidOptions(format!("CMM sigma must be >= 0, got {sigma_mm}")));
        }
        let model = &fit.model;
        let mut coords = Vec::new();
        for id in model.tcp_ids() {
            for axis in [Axis::X, Axis::Y, Axis::Z] {
                coords.push(ParamId::Tcp { id, axis });
            }
        }
        for id in model.position_ids() {
            for axis in [Axis::X, Axis::Y, Axis::Z] {
                coords.push(ParamId::Position { id, axis });
            }
        }
        coords.retain(|p| fit.params.index_of(*p).is_none());
        let coordinates = ParamSet(coords);
        let mut j = to_dmatrix(&assemble_jacobian(model, measurements, &fit.params)?);
        let mut jc = to_dmatrix(&assemble_jacobian(model, measurements, &coordinates)?);
        for (k, m) in measurements.iter().enumerate() {
            let s = weights.of(&m.target).sqrt();
            for row in 3 * k..3 * k + 3 {
                j.row_mut(row).scale_mut(s);
                jc.row_mut(row).scale_mut(s);
            }
        }
        let transfer = j
            .svd(true, true)
            .solve(&jc, 1e-12)
            .map_err(|e| IdentifyError::Numerical(format!("CMM error propagation: {e}")))?;
        Ok(Self { sigma_mm, coordinates, transfer })
    }

    /// `A = P_c − P_ρ J⁺ J_c` (3 × CMM coordinates, columns in the order of
    /// [`CmmUncertainty::coordinates`]): the error of the predicted world position of TCP `tcp`
    /// at `q` per unit error `c_file − c_true` of each CMM coordinate, after the fit has
    /// absorbed what it can.
    pub fn sensitivity(
        &self,
        fit: &Identification,
        q: &JointVector,
        tcp: u32,
    ) -> Result<DMatrix<f64>, IdentifyError> {
        let p_rho = fit.model.jacobian(q, tcp, &fit.params.0)?;
        let p_c = fit.model.jacobian(q, tcp, &self.coordinates.0)?;
        let p_rho = DMatrix::from_column_slice(3, p_rho.ncols(), p_rho.as_slice());
        let p_c = DMatrix::from_column_slice(3, p_c.ncols(), p_c.as_slice());
        Ok(&p_c - &p_rho * &self.transfer)
    }

    /// Systematic covariance \[mm²\] of the predicted world position of TCP `tcp` at `q`.
    pub fn covariance(
        &self,
        fit: &Identification,
        q: &JointVector,
        tcp: u32,
    ) -> Result<Matrix3<f64>, IdentifyError> {
        let a = self.sensitivity(fit, q, tcp)?;
        let c = &a * a.transpose() * (self.sigma_mm * self.sigma_mm);
        Ok(Matrix3::from_fn(|r, k| c[(r, k)]))
    }

    /// Standard deviation \[mm\] of each world coordinate of the predicted position, statistical
    /// ([`Identification::predicted_position_covariance`]) plus systematic.
    pub fn total_sigma(
        &self,
        fit: &Identification,
        q: &JointVector,
        tcp: u32,
    ) -> Result<Vector3<f64>, IdentifyError> {
        let c = fit.predicted_position_covariance(q, tcp)? + self.covariance(fit, q, tcp)?;
        Ok(Vector3::new(c[(0, 0)].max(0.0).sqrt(), c[(1, 1)].max(0.0).sqrt(), c[(2, 2)].max(0.0).sqrt()))
    }
}
