//! Weakly excited directions of the parameter space, found from the design (issue 29).
//!
//! A parameter seen only through a short lever arm (the tilt of the last joint axis when the
//! marker lies near that axis) or over a narrow joint range is fitted to whatever the noise
//! says: harmless on postures like the training ones, ruinous away from them. Which
//! *combinations* of parameters the data see weakly follows from the Jacobian alone, compared
//! with what is known before the data — the prior widths:
//!
//! * `J` the data Jacobian at the solution, rows weighted by `√w_k / σ̂` (information per row);
//! * the free parameters (instrument frame, markers, fixed points: no prior) are profiled out —
//!   `J_h ← (I − Q_f Q_fᵀ) J_h` with `Q_f` an orthonormal basis of their columns;
//! * in prior-whitened coordinates `A = J_h diag(σ_prior)` the eigenpairs `(λ, v)` of `AᵀA` say
//!   how much the data inform each direction **relative to the prior**: λ = 1 is as much as the
//!   prior, the posterior σ along `v` is `1/√(1 + λ)` of the prior's.
//!
//! Directions with λ < 1 ([`WEAK_INFORMATION`]) are held by their prior (with priors) or
//! fitted to noise (without): the report names them, their main parameters, and what would
//! excite them — a marker off an axis the measured point lies near, orientation data, postures
//! over a wider range of a joint, postures that load a joint harder.

use faer::Mat;
use nalgebra::{DMatrix, SymmetricEigen, Vector3};
use serde::{Deserialize, Serialize};
use vatcal_core::{Measurement, ParamId, ParamSet};
use vatcal_kinematics::Model;

use crate::{IdentifyError, KindWeights};

/// Information from the data relative to the prior below which a direction is weak.
pub const WEAK_INFORMATION: f64 = 1.0;
/// Whitened loading from which a parameter is named as part of a direction.
pub const NAMED_LOADING: f64 = 0.3;
/// A measured point closer than this to a joint axis (RMS over the rows) sees that joint's
/// angle and the tilts of its axis only through a short lever arm \[mm\].
pub const SHORT_LEVER_MM: f64 = 60.0;
/// A revolute joint whose training range spans less than this is narrow \[deg\].
pub const NARROW_RANGE_DEG: f64 = 90.0;

/// One weakly excited direction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeakDirection {
    /// information from the data along the direction relative to the prior's (λ)
    pub data_over_prior_information: f64,
    /// posterior σ over prior σ along the direction, `1/√(1 + λ)`
    pub posterior_over_prior_sigma: f64,
    /// the main parameters: name and whitened loading (components of the unit direction in
    /// units of each parameter's prior σ), largest first
    pub parameters: Vec<(String, f64)>,
    /// what would excite the direction
    pub advice: Vec<String>,
}

impl WeakDirection {
    /// One line: `λ = 0.12 (posterior σ 94 % of the prior): theta_offset_7 (+0.98), ... — advice`.
    pub fn sentence(&self) -> String {
        let params: Vec<String> = self.parameters.iter().map(|(n, v)| format!("{n} ({v:+.2})")).collect();
        format!(
            "data/prior information {:.3} (posterior sigma {:.0} % of the prior): {} -- {}",
            self.data_over_prior_information,
            100.0 * self.posterior_over_prior_sigma,
            params.join(", "),
            self.advice.join("; ")
        )
    }
}

/// What the data show of one joint: its range, the lever arm of the measured points about its
/// axis and its largest gravity torque.
#[derive(Debug, Clone, Copy)]
struct JointExposure {
    min: f64,
    max: f64,
    rms_lever_mm: f64,
    largest_torque_n_m: f64,
}

/// The weak directions of a fit of `params` at `model` on `measurements`, against the prior
/// standard deviations `prior_sigmas` (internal units, same order; infinite: free, profiled
/// out). `sigma_data_mm` is the data's σ̂ of one coordinate of a weight-1 row. Sorted from the
/// weakest.
///
/// # Errors
/// A measurement the model cannot evaluate; mismatched lengths.
pub fn weak_directions(
    model: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
    prior_sigmas: &[f64],
    weights: &KindWeights,
    sigma_data_mm: f64,
) -> Result<Vec<WeakDirection>, IdentifyError> {
    if prior_sigmas.len() != params.len() {
        return Err(IdentifyError::InvalidOptions(format!(
            "weak directions: {} prior widths for {} parameters",
            prior_sigmas.len(),
            params.len()
        )));
    }
    let held: Vec<usize> = (0..params.len()).filter(|j| prior_sigmas[*j].is_finite()).collect();
    let free: Vec<usize> = (0..params.len()).filter(|j| !prior_sigmas[*j].is_finite()).collect();
    if held.is_empty() || measurements.is_empty() || !(sigma_data_mm.is_finite() && sigma_data_mm > 0.0) {
        return Ok(Vec::new());
    }
    let j: Mat<f64> = vatcal_observability::identifiability::assemble_jacobian(model, measurements, params)
        .map_err(IdentifyError::from)?;
    let rows = j.nrows();
    let row_scale: Vec<f64> = measurements
        .iter()
        .flat_map(|m| {
            let w = weights.of(&m.target);
            [w.sqrt() / sigma_data_mm; 3]
        })
        .collect();
    let take = |cols: &[usize], scale: &dyn Fn(usize) -> f64| {
        DMatrix::from_fn(rows, cols.len(), |r, c| j[(r, cols[c])] * row_scale[r] * scale(cols[c]))
    };
    let mut a = take(&held, &|c| prior_sigmas[c]);
    if !free.is_empty() {
        let jf = take(&free, &|_| 1.0);
        let q = jf.qr().q();
        let proj = &q * (q.transpose() * &a);
        a -= proj;
    }
    let eig = SymmetricEigen::new(a.transpose() * &a);
    let exposure = joint_exposure(model, measurements);
    let mut out: Vec<WeakDirection> = Vec::new();
    for (k, lambda) in eig.eigenvalues.iter().enumerate() {
        let lambda = lambda.max(0.0);
        if lambda >= WEAK_INFORMATION {
            continue;
        }
        let v = eig.eigenvectors.column(k);
        let sign = if v.iter().copied().fold(0.0f64, |m, x| if x.abs() > m.abs() { x } else { m }) < 0.0 {
            -1.0
        } else {
            1.0
        };
        let mut named: Vec<(ParamId, f64)> =
            held.iter().zip(v.iter()).map(|(c, x)| (params.0[*c], sign * x)).collect();
        named.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        let top = named.first().map_or(0.0, |x| x.1.abs());
        named.retain(|(_, x)| x.abs() >= NAMED_LOADING.min(0.9 * top));
        let advice = advise(model, &named, &exposure);
        out.push(WeakDirection {
            data_over_prior_information: lambda,
            posterior_over_prior_sigma: 1.0 / (1.0 + lambda).sqrt(),
            parameters: named.iter().map(|(p, x)| (p.name(), *x)).collect(),
            advice,
        });
    }
    out.sort_by(|a, b| a.data_over_prior_information.total_cmp(&b.data_over_prior_information));
    Ok(out)
}

/// Range, lever arm and torque of every joint over the rows (index i − 1 for joint i).
fn joint_exposure(model: &Model, measurements: &[Measurement]) -> Vec<JointExposure> {
    let n = model.joint_count();
    let mut e = vec![
        JointExposure {
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            rms_lever_mm: 0.0,
            largest_torque_n_m: 0.0
        };
        n
    ];
    let mut counted = 0usize;
    for m in measurements {
        if m.q.len() != n {
            continue;
        }
        let chain = model.chain(&m.q);
        let point = model.tcp(m.tcp).map(|t| chain.tool_point(&t));
        let torques = model.gravity_torques(&m.q);
        for (i, x) in e.iter_mut().enumerate() {
            let q = m.q.get(i + 1);
            x.min = x.min.min(q);
            x.max = x.max.max(q);
            x.largest_torque_n_m = x.largest_torque_n_m.max(torques[i].abs());
            if let Some(p) = point {
                let f = &chain.frames[i + 1];
                let axis: Vector3<f64> = f.r.column(2).into_owned();
                let d = p - f.p;
                x.rms_lever_mm += (d - axis * axis.dot(&d)).norm_squared();
            }
        }
        counted += 1;
    }
    for x in &mut e {
        x.rms_lever_mm = (x.rms_lever_mm / counted.max(1) as f64).sqrt();
    }
    e
}

/// The joint a parameter belongs to (MDH row i moves axis i; offsets and compliances are joint
/// i's); `None` for frames, markers, points and effects.
fn joint_of(p: ParamId) -> Option<usize> {
    match p {
        ParamId::Alpha(i)
        | ParamId::A(i)
        | ParamId::Beta(i)
        | ParamId::ThetaOffset(i)
        | ParamId::D(i)
        | ParamId::Compliance(i) => Some(i as usize),
        _ => None,
    }
}

/// What would excite a direction whose main parameters are `named`.
fn advise(model: &Model, named: &[(ParamId, f64)], exposure: &[JointExposure]) -> Vec<String> {
    let mut advice: Vec<String> = Vec::new();
    let mut push = |s: String| {
        if !advice.contains(&s) {
            advice.push(s);
        }
    };
    for (p, _) in named.iter().take(3) {
        let Some(i) = joint_of(*p) else { continue };
        let Some(x) = exposure.get(i - 1) else { continue };
        let revolute = model.is_revolute(i);
        if let ParamId::Compliance(_) = p {
            push(format!(
                "postures that load joint {i} harder (largest gravity torque in the data {:.1} N·m)",
                x.largest_torque_n_m
            ));
        } else if x.rms_lever_mm < SHORT_LEVER_MM && revolute {
            push(format!(
                "a second marker off the axis of joint {i} (the measured point lies {:.0} mm from it, RMS) or orientation data",
                x.rms_lever_mm
            ));
        } else if revolute && (x.max - x.min).to_degrees() < NARROW_RANGE_DEG {
            push(format!(
                "postures over a wider range of joint {i} (the data span {:.0} .. {:.0} deg)",
                x.min.to_degrees(),
                x.max.to_degrees()
            ));
        } else if !revolute {
            push(format!(
                "postures over a wider travel of joint {i} (the data span {:.0} .. {:.0} mm)",
                x.min, x.max
            ));
        } else {
            push(format!(
                "more postures, or postures that combine joint {i} with the others differently (its range {:.0} .. {:.0} deg is already wide)",
                x.min.to_degrees(),
                x.max.to_degrees()
            ));
        }
    }
    if advice.is_empty() {
        advice.push("more postures spread over the joint ranges".into());
    }
    advice
}
