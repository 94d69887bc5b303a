//! Statistics of a fit at its solution (background.md §6.4).
//!
//! With `J_w` the weighted measurement Jacobian (3n × L) at the solution and `N` the diagonal
//! of its column norms:
//!
//! * `σ̂² = RSS / (3n − L)`, RSS the weighted residual sum of squares of the measurements;
//! * `A = J_w N⁻¹` (unit columns) is factored `A = Q R` (faer QR), so
//!   `Cov(ρ̂) = σ̂² N⁻¹ R⁻¹ R⁻ᵀ N⁻¹` with `R⁻¹` from a triangular solve — the normal matrix
//!   `JᵀJ` is never formed. With priors, the prior rows are appended to `A` before the QR
//!   (posterior covariance);
//! * the singular values of `A` (measurement rows only) are those of the small L × L factor
//!   `R`; the condition number is `σ_max / σ_min`, independent of the parameter units;
//! * correlations `Cov_ij / √(Cov_ii Cov_jj)`.

use faer::Mat;
use nalgebra::{DMatrix, Vector3};
use vatcal_core::ParamId;
use vatcal_kinematics::Model;

use crate::dense::DenseQr;
use crate::problem::Problem;
use crate::{ErrorStats, IdentifyError};

/// Everything [`statistics`] computes.
#[derive(Debug)]
pub(crate) struct Statistics {
    pub covariance: DMatrix<f64>,
    pub sigma: Vec<f64>,
    pub correlation: DMatrix<f64>,
    pub strong_correlations: Vec<(ParamId, ParamId, f64)>,
    pub rss: f64,
    pub sigma_hat_mm: f64,
    pub dof: usize,
    pub condition_number: f64,
    pub singular_values: Vec<f64>,
    pub residuals: Vec<Vector3<f64>>,
    pub residual_stats: ErrorStats,
}

/// `R` of the QR factorisation of `jac[..rows] · diag(inv_norm)`.
fn unit_column_r(jac: &Mat<f64>, rows: usize, inv_norm: &[f64]) -> Mat<f64> {
    let l = jac.ncols();
    let mut qr = DenseQr::new(rows, l);
    for j in 0..l {
        for i in 0..rows {
            qr.a[(i, j)] = jac[(i, j)] * inv_norm[j];
        }
    }
    qr.factor_and_apply();
    qr.r_owned()
}

fn numerical(e: impl std::fmt::Debug) -> IdentifyError {
    IdentifyError::Numerical(format!("SVD failed: {e:?}"))
}

/// The weighted Jacobian (all rows, natural units), the weighted residual vector and the
/// unweighted residual vectors of one point.
#[derive(Debug)]
pub(crate) struct Linearisation {
    pub jac: Mat<f64>,
    pub r: Vec<f64>,
    pub residuals: Vec<Vector3<f64>>,
}

impl Linearisation {
    /// Evaluates the linearisation of `problem` at `model` (parameter values `values`).
    pub fn evaluate(problem: &Problem<'_>, model: &Model, values: &[f64]) -> Result<Self, IdentifyError> {
        let (rows, l) = (problem.rows(), problem.cols());
        let mut jac = Mat::<f64>::zeros(rows, l);
        let mut r = vec![0.0; rows];
        let mut residuals = vec![Vector3::zeros(); problem.measurements.len()];
        let mut block = vec![0.0; 3 * l];
        problem.jacobian(model, values, jac.as_mut(), &mut r, &mut residuals, &mut block)?;
        Ok(Self { jac, r, residuals })
    }
}

/// Computes the statistics of a fit of `problem` from its linearisation at the solution.
pub(crate) fn statistics(
    problem: &Problem<'_>,
    lin: Linearisation,
    correlation_threshold: f64,
) -> Result<Statistics, IdentifyError> {
    let (rows, m_rows, l) = (problem.rows(), problem.measurement_rows(), problem.cols());
    let Linearisation { jac, r, residuals } = lin;
    let inv_norm: Vec<f64> = (0..l)
        .map(|j| {
            let n = jac.as_ref().get(..m_rows, j).norm_l2();
            if n > 0.0 { 1.0 / n } else { 1.0 }
        })
        .collect();
    let r_meas = unit_column_r(&jac, m_rows, &inv_norm);
    let mut singular_values = r_meas.singular_values().map_err(numerical)?;
    singular_values.sort_by(|a, b| b.total_cmp(a));
    let s_max = singular_values.first().copied().unwrap_or(0.0);
    let s_min = singular_values.last().copied().unwrap_or(0.0);
    let condition_number = if s_min > 0.0 { s_max / s_min } else { f64::INFINITY };

    let r_post = if problem.priors.is_empty() {
        if s_min.is_nan() || s_min <= f64::EPSILON * s_max * l as f64 {
            return Err(IdentifyError::Numerical(format!(
                "the information matrix is singular at the solution (singular values {s_max:.3e} .. {s_min:.3e} of the column-normalised Jacobian)"
            )));
        }
        r_meas
    } else {
        unit_column_r(&jac, rows, &inv_norm)
    };
    // R⁻¹ by a triangular solve against the identity
    let mut r_inv = Mat::<f64>::identity(l, l);
    faer::linalg::triangular_solve::solve_upper_triangular_in_place(
        r_post.as_ref(),
        r_inv.as_mut(),
        faer::Par::Seq,
    );
    if r_inv.col_iter().any(|c| c.iter().any(|x| !x.is_finite())) {
        return Err(IdentifyError::Numerical("the information matrix is singular at the solution".into()));
    }

    let rss = r[..m_rows].iter().map(|x| x * x).sum::<f64>();
    let dof = problem.informative_rows().saturating_sub(l).max(1);
    let sigma2 = rss / dof as f64;
    // W = N⁻¹ R⁻¹, Cov = σ̂² W Wᵀ
    let w = DMatrix::from_fn(l, l, |i, k| inv_norm[i] * r_inv[(i, k)]);
    let covariance = (&w * w.transpose()) * sigma2;
    let sigma: Vec<f64> = (0..l).map(|i| covariance[(i, i)].max(0.0).sqrt()).collect();
    let correlation = DMatrix::from_fn(l, l, |i, k| {
        let d = sigma[i] * sigma[k];
        if i == k {
            1.0
        } else if d > 0.0 {
            (covariance[(i, k)] / d).clamp(-1.0, 1.0)
        } else {
            0.0
        }
    });
    let mut strong_correlations = Vec::new();
    for i in 0..l {
        for k in i + 1..l {
            let c = correlation[(i, k)];
            if c.abs() > correlation_threshold {
                strong_correlations.push((problem.params.0[i], problem.params.0[k], c));
            }
        }
    }
    strong_correlations.sort_by(|a, b| b.2.abs().total_cmp(&a.2.abs()));
    let residual_stats = ErrorStats::from_errors(&residuals);
    Ok(Statistics {
        covariance,
        sigma,
        correlation,
        strong_correlations,
        rss,
        sigma_hat_mm: sigma2.sqrt(),
        dof,
        condition_number,
        singular_values,
        residuals,
        residual_stats,
    })
}
