//! The paper's Table 7 / Eqs. (10)–(13) taken literally — for comparison only.
//!
//! Eq. (10) writes `Δρ_k = (J_kᵀ J_k)⁻¹ J_kᵀ Δx_k` for the 3 × L Jacobian of a *single* pose.
//! That L × L matrix has rank ≤ 3 and no inverse, so the only literal reading that can be
//! executed uses the minimum-norm pseudo-inverse `J_k⁺` (from the SVD of the 3 × L block, in
//! natural units), and Eqs. (12)–(13) add the per-pose corrections of all poses:
//!
//! ```text
//! ρ_{i+1} = ρ_i + Σ_k J_k⁺(ρ_i) r_k(ρ_i)
//! ```
//!
//! Each term alone would zero its own pose's residual, but their sum over-corrects in every
//! direction that several poses share (roughly n-fold for the common ones) and misses the
//! directions none of the minimum-norm solutions contains. This is not a least-squares
//! method, and on realistic data it diverges (background.md §6.2). Stop rule: the paper's
//! `|ε_{i+1} − ε_i|` on the mean residual, read as `< 1e-6 mm`; divergence when the mean
//! residual exceeds `divergence_factor` × its starting value; the iteration cap.

use faer::Mat;
use nalgebra::Vector3;
use vatcal_kinematics::Model;

use crate::problem::Problem;
use crate::solver::{Outcome, log_entry, step_measure, sum_sq, typical_scales};
use crate::{IdentifyError, IdentifyOptions, Termination};

/// The paper's stop rule threshold on the change of the mean residual \[mm\].
pub const PAPER_ERROR_CHANGE_MM: f64 = 1e-6;

/// Relative cut-off below which singular values of a per-pose block are treated as zero.
const PINV_RELATIVE_CUTOFF: f64 = 1e-12;

/// Adds `J⁺ e` of one 3 × L block (column-major in `block`) to `sum`.
fn add_pseudo_inverse_correction(
    block: &[f64],
    e: &Vector3<f64>,
    sum: &mut [f64],
) -> Result<(), IdentifyError> {
    let l = sum.len();
    let j = Mat::from_fn(3, l, |a, c| block[3 * c + a]);
    let svd = j.thin_svd().map_err(|e| IdentifyError::Numerical(format!("per-pose SVD failed: {e:?}")))?;
    let (u, s, v) = (svd.U(), svd.S().column_vector(), svd.V());
    let s_max = (0..s.nrows()).map(|i| s[i]).fold(0.0, f64::max);
    for i in 0..s.nrows() {
        if s[i] <= PINV_RELATIVE_CUTOFF * s_max {
            continue;
        }
        let ute = (0..3).map(|a| u[(a, i)] * e[a]).sum::<f64>() / s[i];
        for (c, out) in sum.iter_mut().enumerate() {
            *out += v[(c, i)] * ute;
        }
    }
    Ok(())
}

/// Runs the literal scheme from `start`.
pub(crate) fn paper_literal(
    problem: &Problem<'_>,
    start: &Model,
    options: &IdentifyOptions,
) -> Result<Outcome, IdentifyError> {
    let (m, l, n) = (problem.rows(), problem.cols(), problem.measurements.len());
    let typical = typical_scales(problem);
    let mut model = start.clone();
    let mut values = problem.start.clone();
    let mut r = vec![0.0; m];
    let mut vecs = vec![Vector3::zeros(); n];
    let mut block = vec![0.0; 3 * l];
    let mut delta = vec![0.0; l];
    problem.residuals(&model, &values, &mut r, &mut vecs)?;
    let mut log = vec![log_entry(0, problem.measurements, &vecs, sum_sq(&r), 0.0, 0.0)];
    let start_mean = log[0].mean_mm;
    let finish = |model, values, log, termination| {
        Ok(Outcome { model, values, log, termination, linearisation: None })
    };
    for iteration in 1..=options.max_iterations {
        delta.fill(0.0);
        for (k, meas) in problem.measurements.iter().enumerate() {
            let e = model
                .measurement_jacobian_into(meas, &problem.params.0, &mut block)
                .map_err(|source| IdentifyError::Measurement { index: k, source })?
                + meas.target_offset_mm();
            add_pseudo_inverse_correction(&block, &e, &mut delta)?;
        }
        if delta.iter().any(|d| !d.is_finite()) {
            return finish(model, values, log, Termination::NonFinite);
        }
        let next: Vec<f64> = values.iter().zip(&delta).map(|(v, d)| v + d).collect();
        let mut next_model = model.clone();
        if next_model.set_params(problem.params, &next).is_err() {
            return finish(model, values, log, Termination::NonFinite);
        }
        problem.residuals(&next_model, &next, &mut r, &mut vecs)?;
        let entry = log_entry(
            iteration,
            problem.measurements,
            &vecs,
            sum_sq(&r),
            0.0,
            step_measure(&delta, &typical),
        );
        let (mean, previous) = (entry.mean_mm, log[log.len() - 1].mean_mm);
        log.push(entry);
        if !mean.is_finite() {
            return finish(model, values, log, Termination::NonFinite);
        }
        model = next_model;
        values = next;
        if mean > options.divergence_factor * start_mean {
            return finish(model, values, log, Termination::Diverged);
        }
        if (mean - previous).abs() < PAPER_ERROR_CHANGE_MM {
            return finish(model, values, log, Termination::ErrorChange);
        }
    }
    finish(model, values, log, Termination::MaxIterations)
}
