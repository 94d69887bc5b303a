//! Levenberg–Marquardt and Gauss–Newton on the stacked, column-scaled Jacobian.
//!
//! Unknowns are scaled, `ρ = ρ_k + D δ`, `J_s = J D` ([`Scaling`]). Every outer iteration
//! evaluates `J` and `r` at the current estimate — gravity torques are recomputed by the model on
//! its current geometry — and factors `J_s = Q R` once (faer Householder QR). A damped step for
//! any λ then needs only the small `2L × L` problem `[R; √λ I] δ ≈ [Qᵀr; 0]`, which is exactly
//! the least-squares problem of the augmented matrix `[J_s; √λ I]` (never the normal
//! equations). Gauss–Newton solves `R δ = Qᵀ r`. λ follows Nielsen's gain-ratio rule
//! (accept if the cost decreased; `λ ← λ·max(1/3, 1 − (2ϱ − 1)³)` after a success,
//! `λ ← λ·ν, ν ← 2ν` after a failure).

use nalgebra::Vector3;
use vatcal_core::{Measurement, Target};
use vatcal_kinematics::Model;

use crate::dense::DenseQr;
use crate::fit_statistics::Linearisation;
use crate::problem::Problem;
use crate::{IdentifyError, IdentifyOptions, IterationLog, Method, Scaling, Termination};

/// Where an iteration ended.
#[derive(Debug)]
pub(crate) struct Outcome {
    pub model: Model,
    pub values: Vec<f64>,
    pub log: Vec<IterationLog>,
    pub termination: Termination,
    /// the linearisation at `values`, when the iteration has it (saves a re-evaluation)
    pub linearisation: Option<Linearisation>,
}

/// λ beyond `STALL_LAMBDA · max diag(J_sᵀJ_s)` without an acceptable step means "stalled".
const STALL_LAMBDA: f64 = 1e16;

pub(crate) fn sum_sq(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum()
}

/// Log line from the unweighted residual vectors of `measurements`: the position statistics
/// over the point measurements (probe, tracker) in mm, the orientation rows' RMS apart (their
/// residuals are rotation vectors in rad, not mm).
pub(crate) fn log_entry(
    iteration: usize,
    measurements: &[Measurement],
    vecs: &[Vector3<f64>],
    cost: f64,
    lambda: f64,
    step_norm: f64,
) -> IterationLog {
    let (mut n, mut sum, mut sum_sq, mut max) = (0usize, 0.0, 0.0, 0.0f64);
    let (mut n_o, mut sum_sq_o) = (0usize, 0.0);
    for (m, e) in measurements.iter().zip(vecs) {
        let v = e.norm();
        if matches!(m.target, Target::Orientation { .. }) {
            n_o += 1;
            sum_sq_o += v * v;
        } else {
            n += 1;
            sum += v;
            sum_sq += v * v;
            max = max.max(v);
        }
    }
    let n_f = n.max(1) as f64;
    IterationLog {
        iteration,
        mean_mm: sum / n_f,
        rms_mm: (sum_sq / n_f).sqrt(),
        max_mm: max,
        orientation_rms_mrad: (n_o > 0).then(|| 1e3 * (sum_sq_o / n_o as f64).sqrt()),
        cost,
        lambda,
        step_norm,
    }
}

/// Typical a-priori standard deviations of the parameters (step-size yardstick).
pub(crate) fn typical_scales(problem: &Problem<'_>) -> Vec<f64> {
    problem.params.iter().map(|p| p.typical_scale()).collect()
}

/// Largest `|Δρ_j| / typical_j`.
pub(crate) fn step_measure(delta: &[f64], typical: &[f64]) -> f64 {
    delta.iter().zip(typical).map(|(d, t)| (d / t).abs()).fold(0.0, f64::max)
}

/// Mutable state of one Levenberg–Marquardt / Gauss–Newton run.
struct Iteration<'p, 'a> {
    problem: &'p Problem<'a>,
    options: &'p IdentifyOptions,
    typical: Vec<f64>,
    current: Model,
    trial: Model,
    values: Vec<f64>,
    trial_values: Vec<f64>,
    /// weighted Jacobian at `current` (natural units)
    jac: faer::Mat<f64>,
    r: Vec<f64>,
    r_trial: Vec<f64>,
    vecs: Vec<Vector3<f64>>,
    vecs_trial: Vec<Vector3<f64>>,
    block: Vec<f64>,
    /// column scale factors D
    scale: Vec<f64>,
    /// running maximum of the column norms (MINPACK rule)
    col_norm_max: Vec<f64>,
    qr: DenseQr,
    aug: DenseQr,
    delta: Vec<f64>,
    cost: f64,
    log: Vec<IterationLog>,
    /// whether `jac` is the Jacobian at `current`
    jac_current: bool,
}

impl<'p, 'a> Iteration<'p, 'a> {
    fn new(problem: &'p Problem<'a>, start: &Model, options: &'p IdentifyOptions) -> Self {
        let (m, l, n) = (problem.rows(), problem.cols(), problem.measurements.len());
        Self {
            problem,
            options,
            typical: typical_scales(problem),
            current: start.clone(),
            trial: start.clone(),
            values: problem.start.clone(),
            trial_values: problem.start.clone(),
            jac: faer::Mat::zeros(m, l),
            r: vec![0.0; m],
            r_trial: vec![0.0; m],
            vecs: vec![Vector3::zeros(); n],
            vecs_trial: vec![Vector3::zeros(); n],
            block: vec![0.0; 3 * l],
            scale: vec![1.0; l],
            col_norm_max: vec![0.0; l],
            qr: DenseQr::new(m, l),
            aug: DenseQr::new(2 * l, l),
            delta: vec![0.0; l],
            cost: 0.0,
            log: Vec::new(),
            jac_current: false,
        }
    }

    /// Residuals and cost at the current estimate (the same code path as every trial point, so
    /// that cost comparisons are not disturbed by round-off differences between paths).
    fn evaluate_residuals(&mut self) -> Result<(), IdentifyError> {
        self.problem.residuals(&self.current, &self.values, &mut self.r, &mut self.vecs)?;
        self.cost = sum_sq(&self.r);
        Ok(())
    }

    /// J at the current estimate (its residual by-product is discarded, see
    /// [`Self::evaluate_residuals`]).
    fn evaluate_jacobian(&mut self) -> Result<(), IdentifyError> {
        self.problem.jacobian(
            &self.current,
            &self.values,
            self.jac.as_mut(),
            &mut self.r_trial,
            &mut self.vecs_trial,
            &mut self.block,
        )?;
        self.jac_current = true;
        Ok(())
    }

    fn update_scale(&mut self) {
        for j in 0..self.problem.cols() {
            self.scale[j] = match self.options.scaling {
                Scaling::None => 1.0,
                Scaling::APriori => self.typical[j],
                Scaling::ColumnNorms => {
                    let norm = crate::dense::norm(self.jac.col_as_slice(j));
                    self.col_norm_max[j] = self.col_norm_max[j].max(norm);
                    if self.col_norm_max[j] > 0.0 { 1.0 / self.col_norm_max[j] } else { self.typical[j] }
                }
            };
        }
    }

    /// Factors `J_s = Q R`, `Qᵀ r`.
    fn factor(&mut self) {
        let (m, l) = (self.problem.rows(), self.problem.cols());
        for j in 0..l {
            let s = self.scale[j];
            for (a, x) in self.qr.a.col_as_slice_mut(j).iter_mut().zip(self.jac.col_as_slice(j)) {
                *a = x * s;
            }
        }
        self.qr.rhs.col_as_slice_mut(0)[..m].copy_from_slice(&self.r[..m]);
        self.qr.factor_and_apply();
    }

    /// `max_j |(J_sᵀ r)_j| / (‖J_s,j‖ ‖r‖)` from the factors (`J_sᵀ r = Rᵀ Qᵀr`,
    /// `‖J_s,j‖ = ‖R_j‖`), and `max_j ‖J_s,j‖²`.
    fn scaled_gradient(&self) -> (f64, f64) {
        let l = self.problem.cols();
        let r_norm = self.cost.sqrt();
        let (mut worst, mut max_diag) = (0.0f64, 0.0f64);
        for j in 0..l {
            let (mut g, mut n2) = (0.0, 0.0);
            for i in 0..=j {
                let rij = self.qr.a[(i, j)];
                g += rij * self.qr.rhs[(i, 0)];
                n2 += rij * rij;
            }
            max_diag = max_diag.max(n2);
            if n2 > 0.0 && r_norm > 0.0 {
                worst = worst.max(g.abs() / (n2.sqrt() * r_norm));
            }
        }
        (worst, max_diag)
    }

    /// Gauss–Newton step `R δ = Qᵀr` into `self.delta`. Returns `(‖Qᵀr‖², step_norm)`:
    /// the largest cost reduction the linearised model allows, and the step measure.
    fn gauss_newton_step(&mut self) -> (f64, f64) {
        let l = self.problem.cols();
        for i in 0..l {
            self.aug.rhs[(i, 0)] = self.qr.rhs[(i, 0)];
        }
        faer::linalg::triangular_solve::solve_upper_triangular_in_place(
            self.qr.r_view(),
            self.aug.rhs.as_mut().get_mut(..l, ..),
            faer::Par::Seq,
        );
        let mut step_norm = 0.0f64;
        for j in 0..l {
            self.delta[j] = self.aug.rhs[(j, 0)];
            step_norm = step_norm.max((self.scale[j] * self.delta[j] / self.typical[j]).abs());
        }
        let qtr_sq = (0..l).map(|i| self.qr.rhs[(i, 0)].powi(2)).sum::<f64>();
        (qtr_sq, if step_norm.is_nan() { f64::INFINITY } else { step_norm })
    }

    /// Damped step for λ > 0 into `self.delta`: least squares of `[R; √λ I] δ ≈ [Qᵀr; 0]`
    /// (QR of the 2L × L augmented factor). Returns the predicted cost reduction of the
    /// undamped linear model, `‖Qᵀr‖² − ‖R δ − Qᵀr‖²`.
    fn damped_step(&mut self, lambda: f64) -> f64 {
        let l = self.problem.cols();
        let sqrt_lambda = lambda.sqrt();
        for j in 0..l {
            let col = self.aug.a.col_as_slice_mut(j);
            col.fill(0.0);
            col[..=j].copy_from_slice(&self.qr.a.col_as_slice(j)[..=j]);
            col[l + j] = sqrt_lambda;
        }
        let rhs = self.aug.rhs.col_as_slice_mut(0);
        rhs[..l].copy_from_slice(&self.qr.rhs.col_as_slice(0)[..l]);
        rhs[l..].fill(0.0);
        self.aug.factor_and_apply();
        self.aug.solve_in_place();
        for j in 0..l {
            self.delta[j] = self.aug.rhs[(j, 0)];
        }
        let (mut qtr_sq, mut misfit_sq) = (0.0, 0.0);
        for i in 0..l {
            let mut rd = 0.0;
            for j in i..l {
                rd += self.qr.a[(i, j)] * self.delta[j];
            }
            let q = self.qr.rhs[(i, 0)];
            qtr_sq += q * q;
            misfit_sq += (rd - q) * (rd - q);
        }
        qtr_sq - misfit_sq
    }

    /// Evaluates the trial point `values + D δ`. Returns `(cost, step_norm)`, or `None` when the
    /// step or the trial parameters are not finite.
    fn evaluate_trial(&mut self) -> Result<Option<(f64, f64)>, IdentifyError> {
        let l = self.problem.cols();
        let mut step_norm = 0.0f64;
        for j in 0..l {
            let d = self.scale[j] * self.delta[j];
            if !d.is_finite() {
                return Ok(None);
            }
            step_norm = step_norm.max((d / self.typical[j]).abs());
            self.trial_values[j] = self.values[j] + d;
        }
        if self.trial.set_params(self.problem.params, &self.trial_values).is_err() {
            return Ok(None);
        }
        self.problem.residuals(&self.trial, &self.trial_values, &mut self.r_trial, &mut self.vecs_trial)?;
        Ok(Some((sum_sq(&self.r_trial), step_norm)))
    }

    fn accept(&mut self) {
        std::mem::swap(&mut self.current, &mut self.trial);
        std::mem::swap(&mut self.values, &mut self.trial_values);
        std::mem::swap(&mut self.r, &mut self.r_trial);
        std::mem::swap(&mut self.vecs, &mut self.vecs_trial);
        self.cost = sum_sq(&self.r);
        self.jac_current = false;
    }

    fn finish(self, termination: Termination) -> Outcome {
        let linearisation =
            self.jac_current.then(|| Linearisation { jac: self.jac, r: self.r, residuals: self.vecs });
        Outcome { model: self.current, values: self.values, log: self.log, termination, linearisation }
    }
}

/// Runs Levenberg–Marquardt or Gauss–Newton (per `options.method`) from `start`.
///
/// Convergence is judged at the top of every iteration on the undamped (Gauss–Newton) step of
/// the current linearisation, so a step that is small only because λ is large never counts:
/// the scaled gradient, the Gauss–Newton step size and the largest relative cost reduction the
/// linear model allows (`‖Qᵀr‖² / ‖r‖²`).
///
/// `rank_check`: when given, the numerical rank of the first factor `R` (whose singular values
/// are those of the stacked Jacobian at the start) is computed with
/// `vatcal_observability::indices::normalized_rank`; only if it is deficient, or a column has
/// no effect (`vatcal_observability::identifiability::negligible_columns`), is `rank_check`
/// called, which runs the full identifiability analysis and returns the error naming the
/// parameters. (Only valid without prior rows.)
pub(crate) fn least_squares(
    problem: &Problem<'_>,
    start: &Model,
    options: &IdentifyOptions,
    rank_check: Option<&dyn Fn() -> Result<(), IdentifyError>>,
) -> Result<Outcome, IdentifyError> {
    let gauss_newton = options.method == Method::GaussNewton;
    let mut it = Iteration::new(problem, start, options);
    it.evaluate_residuals()?;
    let start_entry = log_entry(0, problem.measurements, &it.vecs, it.cost, 0.0, 0.0);
    let start_mean = start_entry.mean_mm;
    it.log.push(start_entry);
    if !it.cost.is_finite() {
        return Ok(it.finish(Termination::NonFinite));
    }
    it.evaluate_jacobian()?;
    let mut lambda = 0.0;
    let mut nu = 2.0;
    for iteration in 1..=options.max_iterations {
        it.update_scale();
        it.factor();
        if iteration == 1
            && let Some(check) = rank_check
        {
            let r = it.qr.r_owned();
            let rank = vatcal_observability::indices::normalized_rank(r.as_ref())?;
            // a column that is round-off (e.g. the compliance of a vertical joint) passes the
            // unit-normalised rank test but has no effect: the full analysis names it
            let norms: Vec<f64> = (0..problem.cols()).map(|j| it.jac.col(j).norm_l2()).collect();
            let negligible =
                vatcal_observability::identifiability::negligible_columns(&norms, &problem.params.0);
            if rank < problem.cols() || !negligible.is_empty() {
                check()?;
            }
        }
        let (gradient, max_diag) = it.scaled_gradient();
        if it.cost == 0.0 || gradient <= options.gradient_tolerance {
            return Ok(it.finish(Termination::GradientTolerance));
        }
        let (gn_reduction, gn_step) = it.gauss_newton_step();
        if gn_step <= options.step_tolerance {
            return Ok(it.finish(Termination::StepTolerance));
        }
        if gn_reduction <= options.cost_tolerance * it.cost {
            return Ok(it.finish(Termination::CostTolerance));
        }
        if iteration == 1 && !gauss_newton {
            lambda = options.initial_lambda * max_diag;
        }
        // inner loop: find an acceptable step
        loop {
            let used_lambda = if gauss_newton { 0.0 } else { lambda };
            let predicted = if gauss_newton { gn_reduction } else { it.damped_step(lambda) };
            let trial = it.evaluate_trial()?;
            let old_cost = it.cost;
            let decreased = trial.is_some_and(|(c, _)| c.is_finite() && c < old_cost);
            match trial {
                Some((trial_cost, _)) if gauss_newton && trial_cost.is_finite() => {}
                _ if gauss_newton => return Ok(it.finish(Termination::NonFinite)),
                Some((trial_cost, _)) if decreased => {
                    let ratio = if predicted > 0.0 { (old_cost - trial_cost) / predicted } else { 1.0 };
                    lambda *= (1.0 - (2.0 * ratio - 1.0).powi(3)).max(1.0 / 3.0);
                    nu = 2.0;
                }
                Some((_, step_norm)) if step_norm <= options.step_tolerance => {
                    // no decrease and a negligible step: at the minimum to round-off
                    return Ok(it.finish(Termination::StepTolerance));
                }
                _ => {
                    lambda *= nu;
                    nu *= 2.0;
                    if lambda > STALL_LAMBDA * max_diag {
                        return Ok(it.finish(Termination::Stalled));
                    }
                    continue;
                }
            }
            let step_norm = trial.map_or(0.0, |t| t.1);
            it.accept();
            let entry =
                log_entry(iteration, it.problem.measurements, &it.vecs, it.cost, used_lambda, step_norm);
            let mean = entry.mean_mm;
            it.log.push(entry);
            if gauss_newton && (mean.is_nan() || mean > options.divergence_factor * start_mean) {
                return Ok(it.finish(Termination::Diverged));
            }
            break;
        }
        it.evaluate_jacobian()?;
    }
    Ok(it.finish(Termination::MaxIterations))
}
