//! Discovery that asks for the data it needs (issue 21, item 3): when a candidate effect is
//! borderline (significant on the screening data but not confirmed, or confirmed but called
//! negligible) or when two candidates compete for the same residual, [`propose`] selects the
//! `count` measurements of a candidate pool that add the most information **on those effects'
//! parameters given every other fitted parameter** — the Ds-optimal design (`Ds = det M /
//! det M_nn`, `M` the information of all parameters, `M_nn` that of the nuisance parameters:
//! the determinant of the Schur complement, i.e. of the inverse covariance of the focus
//! parameters), with the measurements already made held fixed. Greedy with one exchange pass;
//! each gain is two 3 × 3 determinants by the matrix determinant lemma.
//!
//! The pool is the caller's (discovery does not depend on the planner): `vatcal discover
//! --propose N --out-plan DIR` passes the planner's collision-checked candidates and writes the
//! selection as a plan folder for `vatcal campaign --plan`.

use nalgebra::{DMatrix, Matrix3};
use rayon::prelude::*;
use serde::Serialize;
use vatcal_core::effects::EffectSpec;
use vatcal_core::{Measurement, ParamId, ParamSet};
use vatcal_identification::KindWeights;
use vatcal_kinematics::Model;
use vatcal_observability::assemble_jacobian;

use crate::DiscoveryError;
use crate::workflow::{CandidateStatus, Discovery};

/// What [`propose`] selected and how much it should help.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Proposal {
    /// the effects the selection targets (labels)
    pub focus: Vec<String>,
    /// their parameters that were not fitted yet (names)
    pub focus_params: Vec<String>,
    /// the same as parameter ids (not serialised: `focus_params` names them)
    #[serde(skip)]
    pub focus_ids: Vec<ParamId>,
    /// indices into the pool, in the order they were chosen
    pub selected: Vec<usize>,
    /// `ln det` of the focus parameters' information given the others (internal units, per unit
    /// noise of a weight-1 row), with the data at hand
    pub ln_ds_before: f64,
    /// the same with the proposed measurements added
    pub ln_ds_after: f64,
    /// predicted standard deviation of each focus parameter (internal units) per unit noise σ
    /// of a weight-1 row, with the data at hand (`sqrt(diag(S⁻¹))`)
    pub std_before: Vec<f64>,
    /// the same with the proposed measurements added
    pub std_after: Vec<f64>,
}

impl Proposal {
    /// The largest ratio of the focus parameters' predicted standard deviation after / before.
    pub fn worst_std_ratio(&self) -> f64 {
        self.std_after
            .iter()
            .zip(&self.std_before)
            .map(|(a, b)| a / b.max(f64::MIN_POSITIVE))
            .fold(0.0, f64::max)
    }
}

/// The effects a further campaign should decide, from the last round of a discovery run:
/// candidates refitted but not added (rejected by the held-out test, detected but negligible,
/// passed but not best) and, when none was refitted, the best-scoring candidate of the
/// screening; at most `max` of them, best screening score first. Empty when the last round
/// scored nothing. `measurements` are the data discovery ran on (they decide which candidates
/// exist, e.g. backlash needs `dir` columns).
pub fn focus_effects(d: &Discovery, measurements: &[Measurement], max: usize) -> Vec<EffectSpec> {
    let mut out: Vec<EffectSpec> =
        borderline_effects(d, measurements, max).into_iter().map(|b| b.spec).collect();
    if out.is_empty()
        && let Some(round) = d.rounds.last()
        && let Some(c) =
            round.candidates.iter().find(|c| c.score.is_some() && !matches!(c.status, CandidateStatus::Added))
    {
        let pool = crate::workflow::candidates(&d.model, measurements);
        if let Some(s) = pool.iter().copied().find(|s| s.label() == c.label) {
            out.push(s);
        }
    }
    out.truncate(max);
    out
}

/// A candidate effect the data at hand left undecided (see [`borderline_effects`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Borderline {
    /// the effect
    pub spec: EffectSpec,
    /// why it is undecided, e.g. `rejected: held-out z 1.9 < 2.9` or `rival of tool-frame
    /// (simpler)`
    pub why: String,
}

/// The candidates a discovery run left **undecided**, strictly (no fallback, unlike
/// [`focus_effects`]): the last round's candidates that were refitted (plausible values) but
/// not added — rejected by the held-out test, detected but negligible, passed but not best —
/// best screening score first, then the rivals of ambiguities that the validation rows did not
/// settle (basis `simpler` or `held-out`) and that are not in the final model, latest round
/// first; at most `max`, no effect twice. Empty when nothing is borderline: a further campaign
/// then has nothing to decide.
pub fn borderline_effects(d: &Discovery, measurements: &[Measurement], max: usize) -> Vec<Borderline> {
    let pool = crate::workflow::candidates(&d.model, measurements);
    let spec_of = |label: &str| pool.iter().copied().find(|s| s.label() == label);
    let in_model = |s: &EffectSpec| d.model.effects().contains(s);
    let mut out: Vec<Borderline> = Vec::new();
    let push = |out: &mut Vec<Borderline>, spec: EffectSpec, why: String| {
        if !in_model(&spec) && !out.iter().any(|b| b.spec == spec) {
            out.push(Borderline { spec, why });
        }
    };
    if let Some(round) = d.rounds.last() {
        // candidates are sorted by screening score already
        for c in &round.candidates {
            let why = match &c.status {
                CandidateStatus::Rejected(r) => format!("rejected: {r}"),
                CandidateStatus::DetectedNegligible(r) => r.clone(),
                CandidateStatus::PassedNotBest => "passed, not best".to_string(),
                _ => continue,
            };
            if c.refit.as_ref().is_some_and(|r| r.implausible.is_none())
                && let Some(s) = spec_of(&c.label)
            {
                push(&mut out, s, why);
            }
        }
    }
    for a in d.ambiguities.iter().rev().filter(|a| a.basis != "validation") {
        for r in &a.rivals {
            if let Some(s) = spec_of(r) {
                push(&mut out, s, format!("rival of {} (round {}, chosen: {})", a.chosen, a.round, a.basis));
            }
        }
    }
    out.truncate(max);
    out
}

/// Information-matrix rows (3 per measurement, weighted by `√w` of the kind, columns scaled by
/// `scale`) of `ms`.
fn rows(
    model: &Model,
    ms: &[Measurement],
    params: &ParamSet,
    weights: &KindWeights,
) -> Result<DMatrix<f64>, DiscoveryError> {
    if ms.is_empty() {
        return Ok(DMatrix::zeros(0, params.len()));
    }
    let j = assemble_jacobian(model, ms, params).map_err(DiscoveryError::Jacobian)?;
    Ok(DMatrix::from_fn(j.nrows(), j.ncols(), |r, c| weights.of(&ms[r / 3].target).sqrt() * j[(r, c)]))
}

/// `ln det` of a symmetric positive (semi)definite matrix via Cholesky (−∞ when singular).
fn ln_det(m: &DMatrix<f64>) -> f64 {
    match m.clone().cholesky() {
        Some(c) => 2.0 * c.l().diagonal().iter().map(|x| x.ln()).sum::<f64>(),
        None => f64::NEG_INFINITY,
    }
}

/// The focus block of `M⁻¹`'s square roots of the diagonal: predicted standard deviations of
/// the focus parameters (last `k` columns) per unit σ, in the parameters' own units (the
/// columns were multiplied by `scale`).
fn focus_std(m: &DMatrix<f64>, k: usize, scale: &[f64]) -> Vec<f64> {
    let p = m.nrows();
    match m.clone().try_inverse() {
        Some(inv) => (p - k..p).map(|i| inv[(i, i)].max(0.0).sqrt() * scale[i]).collect(),
        None => vec![f64::INFINITY; k],
    }
}

/// Selects `count` measurements of `pool` that best determine the parameters of `focus` (switched
/// on in `model` at their current values) given `params`, with `existing` measured already
/// (module docs). Rows are weighted by `weights` of their kind.
///
/// # Errors
/// A Jacobian that cannot be assembled (a pool row the model rejects), or a focus effect the
/// model cannot take.
pub fn propose(
    model: &Model,
    params: &ParamSet,
    existing: &[Measurement],
    focus: &[EffectSpec],
    pool: &[Measurement],
    count: usize,
    weights: &KindWeights,
) -> Result<Proposal, DiscoveryError> {
    let mut m = model.clone();
    let mut all: Vec<ParamId> = params.0.clone();
    let mut focus_ids = Vec::new();
    for spec in focus {
        if !m.effects().contains(spec) {
            m.enable_effect(*spec).map_err(|e| DiscoveryError::Numerical(e.to_string()))?;
        }
        for id in spec.params() {
            if !all.contains(&id) && !focus_ids.contains(&id) {
                focus_ids.push(id);
            }
        }
    }
    all.extend(focus_ids.iter().copied());
    let set = ParamSet(all);
    let p = set.len();
    let k = focus_ids.len();
    let nn = p - k;
    let a0 = rows(&m, existing, &set, weights)?;
    let b = rows(&m, pool, &set, weights)?;
    // scale the columns to unit norm over existing + pool (conditioning; Ds is invariant)
    let scale: Vec<f64> = (0..p)
        .map(|c| {
            let s = (a0.column(c).norm_squared() + b.column(c).norm_squared()).sqrt();
            if s > 0.0 { 1.0 / s } else { 1.0 }
        })
        .collect();
    let scaled = |x: &DMatrix<f64>| DMatrix::from_fn(x.nrows(), p, |r, c| x[(r, c)] * scale[c]);
    let (a0, b) = (scaled(&a0), scaled(&b));
    // a tiny ridge keeps M invertible where the data at hand cannot separate directions yet
    let ridge = 1e-10;
    let mut info = a0.transpose() * &a0 + DMatrix::identity(p, p) * ridge;
    // in the parameters' own units: the scaled Ds is the raw one times Π scale² of the focus
    let focus_scale: f64 = scale[nn..].iter().map(|s| 2.0 * s.ln()).sum();
    let ln_ds =
        |info: &DMatrix<f64>| ln_det(info) - ln_det(&info.view((0, 0), (nn, nn)).into_owned()) - focus_scale;
    let ln_ds_before = ln_ds(&info);
    let std_before = focus_std(&info, k, &scale);
    let blocks = Blocks::of(&b);
    let block = |i: usize| b.rows(3 * i, 3).into_owned();
    let n_pool = pool.len();
    let count = count.min(n_pool);
    let mut chosen: Vec<usize> = Vec::with_capacity(count);
    let mut taken = vec![false; n_pool];
    for _ in 0..count {
        let factor = Factor::of(&info)?;
        let Some((i, _)) = best_gain(&blocks, &factor, nn, &taken) else { break };
        taken[i] = true;
        chosen.push(i);
        let bi = block(i);
        info += bi.transpose() * bi;
    }
    // one exchange pass: replace a chosen row by a better unchosen one while Ds grows
    for slot in &mut chosen {
        let out = *slot;
        let bo = block(out);
        let without = &info - bo.transpose() * &bo;
        let factor = Factor::of(&without)?;
        let current = factor.gain(blocks.rows(out), nn);
        if let Some((i, g)) = best_gain(&blocks, &factor, nn, &taken)
            && g > current + 1e-9
        {
            taken[out] = false;
            taken[i] = true;
            *slot = i;
            let bi = block(i);
            info = without + bi.transpose() * bi;
        }
    }
    Ok(Proposal {
        focus: focus.iter().map(EffectSpec::label).collect(),
        focus_params: focus_ids.iter().map(|id| id.name()).collect(),
        focus_ids,
        selected: chosen,
        ln_ds_before,
        ln_ds_after: ln_ds(&info),
        std_before,
        std_after: focus_std(&info, k, &scale),
    })
}

/// The scaled pool rows, row-major and contiguous: candidate `i`'s three rows are
/// `data[3·i·p .. 3·(i+1)·p]`.
struct Blocks {
    data: Vec<f64>,
    p: usize,
}

impl Blocks {
    fn of(b: &DMatrix<f64>) -> Self {
        let p = b.ncols();
        let mut data = Vec::with_capacity(b.nrows() * p);
        for r in 0..b.nrows() {
            data.extend((0..p).map(|c| b[(r, c)]));
        }
        Self { data, p }
    }

    /// Candidate `i`'s three rows, one after the other.
    fn rows(&self, i: usize) -> &[f64] {
        &self.data[3 * i * self.p..3 * (i + 1) * self.p]
    }
}

/// The Cholesky factor `L` of an information matrix `M = L Lᵀ` (lower triangle, row-major).
/// Its leading `nn × nn` block is the factor of `M_nn`, so one forward substitution
/// `Y = L⁻¹ Bᵀ` of a candidate's rows gives both `B M⁻¹ Bᵀ = YᵀY` and
/// `B_n M_nn⁻¹ B_nᵀ = Y_nᵀY_n` (`Y_n` its first `nn` rows).
struct Factor {
    l: Vec<f64>,
    p: usize,
}

impl Factor {
    fn of(info: &DMatrix<f64>) -> Result<Self, DiscoveryError> {
        let p = info.nrows();
        let chol = info
            .clone()
            .cholesky()
            .ok_or_else(|| DiscoveryError::Numerical("singular information matrix".into()))?;
        let lm = chol.l();
        let mut l = Vec::with_capacity(p * p);
        for r in 0..p {
            l.extend((0..p).map(|c| lm[(r, c)]));
        }
        Ok(Self { l, p })
    }

    /// Gain in `ln Ds` of adding the candidate with `rows` (three rows of length p):
    /// `ln det(I + B M⁻¹ Bᵀ) − ln det(I + B_n M_nn⁻¹ B_nᵀ)` (matrix determinant lemma).
    fn gain(&self, rows: &[f64], nn: usize) -> f64 {
        let p = self.p;
        let mut y = [vec![0.0; p], vec![0.0; p], vec![0.0; p]];
        for r in 0..p {
            let lr = &self.l[r * p..r * p + r];
            for (a, ya) in y.iter_mut().enumerate() {
                let dot: f64 = lr.iter().zip(&ya[..r]).map(|(l, v)| l * v).sum();
                ya[r] = (rows[a * p + r] - dot) / self.l[r * p + r];
            }
        }
        let gram = |n: usize| {
            Matrix3::from_fn(|a, b| {
                let d: f64 = y[a][..n].iter().zip(&y[b][..n]).map(|(u, v)| u * v).sum();
                if a == b { 1.0 + d } else { d }
            })
        };
        gram(p).determinant().max(f64::MIN_POSITIVE).ln() - gram(nn).determinant().max(f64::MIN_POSITIVE).ln()
    }
}

/// The untaken candidate with the largest gain (the lowest index among equal gains): the
/// gains are computed in parallel, one per candidate (each the same whatever the thread
/// count), and compared in candidate order.
fn best_gain(blocks: &Blocks, factor: &Factor, nn: usize, taken: &[bool]) -> Option<(usize, f64)> {
    let gains: Vec<f64> = (0..taken.len())
        .into_par_iter()
        .map(|i| if taken[i] { f64::NAN } else { factor.gain(blocks.rows(i), nn) })
        .collect();
    (0..taken.len())
        .filter(|i| !taken[*i])
        .map(|i| (i, gains[i]))
        .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
}

/// `ln Ds` and the focus parameters' predicted standard deviations for `existing` plus the
/// pool rows `extra` (to compare a proposal with another choice, e.g. random rows).
///
/// # Errors
/// As [`propose`].
pub fn design_quality(
    model: &Model,
    params: &ParamSet,
    existing: &[Measurement],
    focus: &[EffectSpec],
    extra: &[Measurement],
    weights: &KindWeights,
) -> Result<(f64, Vec<f64>), DiscoveryError> {
    let all: Vec<Measurement> = existing.iter().chain(extra).copied().collect();
    let p = propose(model, params, &all, focus, &[], 0, weights)?;
    Ok((p.ln_ds_before, p.std_before))
}
