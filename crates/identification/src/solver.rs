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
use vatcal_kinematics::Model;

use crate::dense::DenseQr;
use crate::problem::Problem;
use crate::{IdentifyError, IdentifyOptions, IterationLog, Method, Scaling, Termination};

/// Where an iteration ended.
#[derive(Debug)]
pub(crate) struct Outcome {
    pub model: Model,
    pub values: Vec<f64>,
    pub log: Vec<IterationLog>,
    pub termination: Termination,
}

/// λ beyond `STALL_LAMBDA · max diag(J_sᵀJ_s)` without an acceptable step means "stalled".
const STALL_LAMBDA: f64 = 1e16;

pub(crate) fn sum_sq(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum()
}

/// Log line from the unweighted residual vectors.
pub(crate) fn log_entry(iteration: usize, vecs: &[Vector3<f64>], cost: f64, lambda: f64, step_norm: f64) -> IterationLog {
    let n = vecs.len().max(1) as f64;
    let (mut sum, mut sum_sq, mut max) = (0.0, 0.0, 0.0f64);
    for e in vecs {
        let v = e.norm();
        sum += v;
        sum_sq += v * v;
        max = max.max(v);
    }
    IterationLog { iteration, mean_mm: sum / n, rms_mm: (sum_sq / n).sqrt(), max_mm: max, cost, lambda, step_norm }
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
        }
    }

    /// J and r at the current estimate.
    fn evaluate_jacobian(&mut self) -> Result<(), IdentifyError> {
        self.problem.jacobian(
            &self.current,
            &self.values,
            self.jac.as_mut(),
            &mut self.r,
            &mut self.vecs,
            &mut self.block,
        )?;
        self.cost = sum_sq(&self.r);
        Ok(())
    }

    fn update_scale(&mut self) {
        for j in 0..self.problem.cols() {
            self.scale[j] = match self.options.scaling {
                Scaling::None => 1.0,
                Scaling::APriori => self.typical[j],
                Scaling::ColumnNorms => {
                    let norm = self.jac.col(j).norm_l2();
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
            for i in 0..m {
                self.qr.a[(i, j)] = self.jac[(i, j)] * s;
            }
        }
        for i in 0..m {
            self.qr.rhs[(i, 0)] = self.r[i];
        }
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

    /// δ for damping λ (0 = Gauss–Newton) into `self.delta`; returns the predicted cost
    /// reduction `‖Qᵀr‖² − ‖R δ − Qᵀr‖²`.
    fn step(&mut self, lambda: f64) -> f64 {
        let l = self.problem.cols();
        if lambda == 0.0 {
            for i in 0..l {
                self.aug.rhs[(i, 0)] = self.qr.rhs[(i, 0)];
            }
            // reuse the main factor: R δ = Qᵀr
            faer::linalg::triangular_solve::solve_upper_triangular_in_place(
                self.qr.r_view(),
                self.aug.rhs.as_mut().get_mut(..l, ..),
                faer::Par::Seq,
            );
        } else {
            let sqrt_lambda = lambda.sqrt();
            for j in 0..l {
                for i in 0..2 * l {
                    self.aug.a[(i, j)] = if i <= j {
                        self.qr.a[(i, j)]
                    } else if i == l + j {
                        sqrt_lambda
                    } else {
                        0.0
                    };
                }
            }
            for i in 0..2 * l {
                self.aug.rhs[(i, 0)] = if i < l { self.qr.rhs[(i, 0)] } else { 0.0 };
            }
            self.aug.factor_and_apply();
            self.aug.solve_in_place();
        }
        for j in 0..l {
            self.delta[j] = self.aug.rhs[(j, 0)];
        }
        // predicted reduction with the undamped model
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
    }

    fn finish(self, termination: Termination) -> Outcome {
        Outcome { model: self.current, values: self.values, log: self.log, termination }
    }
}

/// Runs Levenberg–Marquardt or Gauss–Newton (per `options.method`) from `start`.
pub(crate) fn least_squares(problem: &Problem<'_>, start: &Model, options: &IdentifyOptions) -> Result<Outcome, IdentifyError> {
    let gauss_newton = options.method == Method::GaussNewton;
    let mut it = Iteration::new(problem, start, options);
    it.evaluate_jacobian()?;
    let start_entry = log_entry(0, &it.vecs, it.cost, 0.0, 0.0);
    let start_mean = start_entry.mean_mm;
    it.log.push(start_entry);
    if !it.cost.is_finite() {
        return Ok(it.finish(Termination::NonFinite));
    }
    let mut lambda = 0.0;
    let mut nu = 2.0;
    for iteration in 1..=options.max_iterations {
        it.update_scale();
        it.factor();
        let (gradient, max_diag) = it.scaled_gradient();
        if it.cost == 0.0 || gradient <= options.gradient_tolerance {
            return Ok(it.finish(Termination::GradientTolerance));
        }
        if iteration == 1 && !gauss_newton {
            lambda = options.initial_lambda * max_diag;
        }
        // inner loop: find an acceptable step
        loop {
            let used_lambda = if gauss_newton { 0.0 } else { lambda };
            let predicted = it.step(used_lambda);
            let Some((trial_cost, step_norm)) = it.evaluate_trial()? else {
                if gauss_newton {
                    return Ok(it.finish(Termination::NonFinite));
                }
                lambda *= nu;
                nu *= 2.0;
                if lambda > STALL_LAMBDA * max_diag {
                    return Ok(it.finish(Termination::Stalled));
                }
                continue;
            };
            let small_step = step_norm <= options.step_tolerance;
            let old_cost = it.cost;
            let actual = old_cost - trial_cost;
            if gauss_newton {
                if !trial_cost.is_finite() {
                    return Ok(it.finish(Termination::NonFinite));
                }
            } else if trial_cost.is_finite() && actual > 0.0 {
                let ratio = if predicted > 0.0 { actual / predicted } else { 1.0 };
                lambda *= (1.0 - (2.0 * ratio - 1.0).powi(3)).max(1.0 / 3.0);
                nu = 2.0;
            } else if small_step {
                // no decrease, and the step is negligible: we are at the minimum (round-off)
                return Ok(it.finish(Termination::StepTolerance));
            } else {
                lambda *= nu;
                nu *= 2.0;
                if lambda > STALL_LAMBDA * max_diag {
                    return Ok(it.finish(Termination::Stalled));
                }
                continue;
            }
            it.accept();
            let entry = log_entry(iteration, &it.vecs, it.cost, used_lambda, step_norm);
            let mean = entry.mean_mm;
            it.log.push(entry);
            if gauss_newton && !(mean <= options.divergence_factor * start_mean) {
                return Ok(it.finish(Termination::Diverged));
            }
            if small_step {
                return Ok(it.finish(Termination::StepTolerance));
            }
            let tol = options.cost_tolerance * old_cost;
            if actual.abs() <= tol && predicted.abs() <= tol {
                return Ok(it.finish(Termination::CostTolerance));
            }
            break;
        }
        it.evaluate_jacobian()?;
        if !it.cost.is_finite() {
            return Ok(it.finish(Termination::NonFinite));
        }
    }
    Ok(it.finish(Termination::MaxIterations))
}
