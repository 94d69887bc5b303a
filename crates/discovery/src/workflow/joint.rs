//! **The joint search, selection** (issue 30 item 3): which of the round's scored candidates to
//! try together, decided with every candidate in view instead of one at a time.
//!
//! With few measurements and many missing effects, each effect's held-out gain alone is
//! masked by the misfit of the others still missing, so the one-at-a-time search stops early.
//! Here, on the linearisation at the current model and on the **screening** part of the data
//! only:
//! 1. every candidate's new parameters are columns of one regularised linear model: the
//!    current parameters free, each candidate parameter with a Gaussian prior of its typical
//!    scale ([`vatcal_core::ParamId::typical_scale`]) toward zero (the maximum a-posteriori fit
//!    the true-structure fit of the simulated cell uses, measurement σ
//!    [`vatcal_identification::IdentifyOptions::measurement_sigma_mm`]);
//! 2. a **forward path**: each step adds the candidate whose parameters, added to those already
//!    on the path, lower the cross-validated squared error (the screening part's folds of the
//!    all-data folds) the most — every candidate is re-examined against the current set at
//!    every step, so a look-alike is taken only if it predicts the held-out rows better than
//!    its rivals given everything else (one Cholesky factor per fold, extended by a block
//!    update per trial);
//! 3. the **number kept** is the smallest whose held-out error the cross-validation cannot tell
//!    from the lowest on the path ([`one_standard_error`]).
//!
//! The confirmation part has not been looked at: the chosen candidates are then refitted with
//! the nonlinear model and confirmed there together ([`super::joint_add`]).
//!
//! Measured alternative (demo seed 7, 15 min budget): ranking the candidates once by the
//! prediction change they carry in the ridge fit of all of them gave a held-out error that
//! rose and fell along the path (generic link tilts and look-alikes first) and 30–38 % of the
//! 34-parameter model's error; the forward path replaced it.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use vatcal_core::{ParamId, ParamSet};
use vatcal_observability::assemble_jacobian;

use super::candidate::Candidate;
use super::context::{Context, weigh_rows, weighted_residual};
use super::report::CandidateStatus;
use crate::DiscoveryError;
use crate::fit::Fit;

/// The forward path of one joint search.
pub(super) struct JointPath {
    /// the live candidates (indices into the round's candidates) in the order the path added
    /// them
    pub(super) order: Vec<usize>,
    /// held-out RMS error per measurement over the screening part \[mm\] of the nested
    /// models with the first k = 0..=`order.len()` candidates
    pub(super) heldout_rms_mm: Vec<f64>,
    /// the k chosen ([`one_standard_error`])
    pub(super) chosen: usize,
    /// the live candidates
    pub(super) live: usize,
    /// the screening measurements the path was cross-validated on
    pub(super) measurements: usize,
}

impl JointPath {
    /// The chosen candidates (indices into the round's candidates), in path order.
    pub(super) fn members(&self) -> &[usize] {
        &self.order[..self.chosen]
    }
}

/// Ridge of the current model's (column-normalised, free) parameters: tiny, for the numerics.
const FREE_RIDGE: f64 = 1e-10;

/// The path stops after this many steps without a lower held-out error than its best.
pub(super) const PATIENCE: usize = 6;

/// Whether candidate `c` takes part in the joint search: scored, with new parameters, not
/// added this round.
fn live(c: &Candidate) -> bool {
    c.score.is_some() && !c.new_params.is_empty() && c.status != CandidateStatus::Added
}

/// The joint search's selection (module docs). `j0` is the current model's weighted Jacobian
/// on all data. `None` when no candidate is live or a factorisation fails.
pub(super) fn joint_path(
    candidates: &[Candidate],
    current: &Fit,
    j0: &faer::Mat<f64>,
    ctx: &Context<'_>,
) -> Result<Option<JointPath>, DiscoveryError> {
    let live: Vec<usize> = (0..candidates.len()).filter(|i| live(&candidates[*i])).collect();
    if live.is_empty() {
        return Ok(None);
    }
    let mut all: Vec<ParamId> = Vec::new();
    for i in &live {
        for p in &candidates[*i].new_params {
            if !all.contains(p) {
                all.push(*p);
            }
        }
    }
    let ms = ctx.measurements;
    let w = &ctx.options.identify.weights;
    let mut z =
        assemble_jacobian(&current.model, ms, &ParamSet(all.clone())).map_err(DiscoveryError::Jacobian)?;
    weigh_rows(&mut z, ms, w);
    let r_all = weighted_residual(current, ms, w);
    // the screening rows and their folds
    let screen: Vec<usize> = (0..ms.len()).filter(|i| ctx.confirm_folds[*i].is_none()).collect();
    let fold: Vec<usize> = screen.iter().map(|i| ctx.all_folds[*i].unwrap_or(0)).collect();
    let rows: Vec<usize> = screen.iter().flat_map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let p0 = j0.ncols();
    // columns: the current parameters normalised to unit length (free), then every candidate
    // parameter in units of its typical scale (prior N(0, 1))
    let j0_norms: Vec<f64> =
        (0..p0).map(|c| rows.iter().map(|r| j0[(*r, c)].powi(2)).sum::<f64>().sqrt().max(1e-300)).collect();
    let scales: Vec<f64> = all.iter().map(|p| p.typical_scale()).collect();
    let a = DMatrix::from_fn(rows.len(), p0 + all.len(), |r, c| {
        if c < p0 { j0[(rows[r], c)] / j0_norms[c] } else { z[(rows[r], c - p0)] * scales[c - p0] }
    });
    let b = DVector::from_fn(rows.len(), |r, _| r_all[rows[r]]);
    let sigma = ctx.options.identify.measurement_sigma_mm;
    let d = DVector::from_fn(a.ncols(), |c, _| if c < p0 { FREE_RIDGE } else { sigma * sigma });
    let groups: Vec<Vec<usize>> = live
        .iter()
        .map(|i| {
            let own = &candidates[*i].new_params;
            own.iter().filter_map(|p| all.iter().position(|q| q == p)).map(|c| p0 + c).collect()
        })
        .collect();
    let Some((steps, per)) = forward_path(&a, &b, &d, &fold, p0, &groups) else { return Ok(None) };
    let n_meas = screen.len().max(1) as f64;
    Ok(Some(JointPath {
        order: steps.iter().map(|g| live[*g]).collect(),
        heldout_rms_mm: per.iter().map(|e| (e.iter().sum::<f64>() / n_meas).sqrt()).collect(),
        chosen: one_standard_error(&per),
        live: live.len(),
        measurements: screen.len(),
    }))
}

/// The forward path: from the first `p0` columns of `a`, each step adds the group (a set of
/// column indices) whose columns lower the cross-validated squared error most, until
/// [`PATIENCE`] steps pass without a new lowest error or no group is left. Returns the groups
/// in the order added and the per-measurement held-out squared errors after each step (the
/// first entry: no group). `fold` gives the fold of each measurement (three rows of `a`).
fn forward_path(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    d: &DVector<f64>,
    fold: &[usize],
    p0: usize,
    groups: &[Vec<usize>],
) -> Option<(Vec<usize>, Vec<Vec<f64>>)> {
    let k = fold.iter().copied().max().map_or(0, |m| m + 1);
    let mut active: Vec<usize> = (0..p0).collect();
    let mut systems: Vec<FoldSystem> = Vec::new();
    for f in 0..k {
        systems.extend(FoldSystem::new(a, b, d, fold, f, &active)?);
    }
    let mut per = vec![errors_of(&systems, &active, fold.len(), None)?];
    let mut steps: Vec<usize> = Vec::new();
    let total = |e: &Vec<f64>| e.iter().sum::<f64>();
    let mut best = total(&per[0]);
    let mut since_best = 0;
    while since_best < PATIENCE {
        let left: Vec<usize> = (0..groups.len()).filter(|g| !steps.contains(g)).collect();
        let trials: Vec<Option<(Vec<Factor>, Vec<f64>)>> = left
            .par_iter()
            .map(|&g| {
                let new: Vec<usize> = groups[g].iter().copied().filter(|c| !active.contains(c)).collect();
                let factors: Vec<Factor> =
                    systems.iter().map(|s| s.extend(&active, &new)).collect::<Option<Vec<_>>>()?;
                let cols: Vec<usize> = active.iter().chain(&new).copied().collect();
                let e = errors_of(&systems, &cols, fold.len(), Some(&factors))?;
                Some((factors, e))
            })
            .collect();
        let Some((pick, (factors, e))) = left
            .iter()
            .zip(trials)
            .filter_map(|(g, t)| t.map(|t| (*g, t)))
            .min_by(|x, y| total(&x.1.1).total_cmp(&total(&y.1.1)))
        else {
            break;
        };
        let new: Vec<usize> = groups[pick].iter().copied().filter(|c| !active.contains(c)).collect();
        active.extend(new);
        for (s, f) in systems.iter_mut().zip(factors) {
            s.factor = f;
        }
        if total(&e) < best {
            best = total(&e);
            since_best = 0;
        } else {
            since_best += 1;
        }
        steps.push(pick);
        per.push(e);
    }
    Some((steps, per))
}

/// A Cholesky factor of a fold's Gram restricted to some columns, and `L⁻¹ rhs`.
#[derive(Clone)]
struct Factor {
    l: DMatrix<f64>,
    y: DVector<f64>,
}

/// One fold of the path's cross-validation: the Gram of its training rows (ridge on the
/// diagonal) and their right-hand side over every column, its held-out rows, and the factor of
/// the active columns.
struct FoldSystem {
    gram: DMatrix<f64>,
    rhs: DVector<f64>,
    test_a: DMatrix<f64>,
    test_b: DVector<f64>,
    /// measurement (index into the fold list) of each held-out row
    test_meas: Vec<usize>,
    factor: Factor,
}

impl FoldSystem {
    /// Fold `f`'s system with the factor of the columns `active`: `Some(None)` when it has no
    /// held-out or no training rows (left out), `None` when the factorisation fails.
    fn new(
        a: &DMatrix<f64>,
        b: &DVector<f64>,
        d: &DVector<f64>,
        fold: &[usize],
        f: usize,
        active: &[usize],
    ) -> Option<Option<Self>> {
        let train: Vec<usize> = (0..a.nrows()).filter(|r| fold[r / 3] != f).collect();
        let test: Vec<usize> = (0..a.nrows()).filter(|r| fold[r / 3] == f).collect();
        if test.is_empty() || train.is_empty() {
            return Some(None);
        }
        let at = a.select_rows(&train);
        let mut gram = at.tr_mul(&at);
        for c in 0..gram.ncols() {
            gram[(c, c)] += d[c];
        }
        let rhs = at.tr_mul(&b.select_rows(&train));
        let sub = gram.select_rows(active).select_columns(active);
        let l = nalgebra::Cholesky::new(sub)?.l();
        let y = l.solve_lower_triangular(&rhs.select_rows(active))?;
        Some(Some(Self {
            gram,
            rhs,
            test_a: a.select_rows(&test),
            test_b: b.select_rows(&test),
            test_meas: test.iter().map(|r| r / 3).collect(),
            factor: Factor { l, y },
        }))
    }

    /// The factor of `active` + `new` from that of `active` (block update; `None` when the
    /// new columns are numerically dependent on the active ones).
    fn extend(&self, active: &[usize], new: &[usize]) -> Option<Factor> {
        let (n, m) = (active.len(), new.len());
        if m == 0 {
            return Some(self.factor.clone());
        }
        let cross = self.gram.select_rows(active).select_columns(new);
        let w = self.factor.l.solve_lower_triangular(&cross)?;
        let schur = self.gram.select_rows(new).select_columns(new) - w.tr_mul(&w);
        let l22 = nalgebra::Cholesky::new(schur)?.l();
        let y2 = l22.solve_lower_triangular(&(self.rhs.select_rows(new) - w.tr_mul(&self.factor.y)))?;
        let mut l = DMatrix::zeros(n + m, n + m);
        l.view_mut((0, 0), (n, n)).copy_from(&self.factor.l);
        l.view_mut((n, 0), (m, n)).copy_from(&w.transpose());
        l.view_mut((n, n), (m, m)).copy_from(&l22);
        let mut y = DVector::zeros(n + m);
        y.rows_mut(0, n).copy_from(&self.factor.y);
        y.rows_mut(n, m).copy_from(&y2);
        Some(Factor { l, y })
    }
}

/// Held-out squared error of every measurement (the sum of its three rows) of the ridge fits
/// on the columns `cols`, fold by fold (with `factors`, else each fold's own factor).
fn errors_of(
    systems: &[FoldSystem],
    cols: &[usize],
    n_meas: usize,
    factors: Option<&[Factor]>,
) -> Option<Vec<f64>> {
    let mut e = vec![0.0; n_meas];
    for (i, s) in systems.iter().enumerate() {
        let f = factors.map_or(&s.factor, |fs| &fs[i]);
        let x = f.l.tr_solve_lower_triangular(&f.y)?;
        let pred = s.test_a.select_columns(cols) * x;
        for (r, m) in s.test_meas.iter().enumerate() {
            e[*m] += (s.test_b[r] - pred[r]).powi(2);
        }
    }
    Some(e)
}

/// The smallest k whose held-out squared error exceeds the lowest one by at most one standard
/// error of the paired per-measurement differences (the one-standard-error rule: the
/// simplest model the cross-validation cannot tell from the best). `per[k][i]`: held-out
/// squared error of measurement i with the first k candidates of the path.
pub(super) fn one_standard_error(per: &[Vec<f64>]) -> usize {
    let total = |e: &Vec<f64>| e.iter().sum::<f64>();
    let Some(best) = (0..per.len()).min_by(|x, y| total(&per[*x]).total_cmp(&total(&per[*y]))) else {
        return 0;
    };
    let n = per[best].len();
    (0..=best)
        .find(|&k| {
            let d: Vec<f64> = per[k].iter().zip(&per[best]).map(|(a, b)| a - b).collect();
            let mean = d.iter().sum::<f64>() / n.max(1) as f64;
            let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n.max(2) - 1) as f64;
            mean <= (var / n.max(1) as f64).sqrt()
        })
        .unwrap_or(best)
}

#[cfg(test)]
mod tests {
    use nalgebra::{DMatrix, DVector};

    /// The forward path takes the generating columns (groups 2 and 0) before the idle one, and
    /// the one-standard-error rule keeps exactly those two.
    #[test]
    fn forward_path_takes_the_generating_groups_first() {
        let n = 90;
        let a = DMatrix::from_fn(n, 4, |r, c| ((r * (c + 2)) as f64 * 0.37).sin() + 0.1 * c as f64);
        let b = DVector::from_fn(n, |r, _| 2.0 * a[(r, 3)] - 0.5 * a[(r, 1)] + 1e-3 * ((r * 7) as f64).cos());
        let fold: Vec<usize> = (0..n / 3).map(|i| i % 5).collect();
        let d = DVector::from_element(4, 1e-8);
        let groups = vec![vec![1], vec![2], vec![3]];
        let (steps, per) = super::forward_path(&a, &b, &d, &fold, 1, &groups).expect("factorises");
        assert_eq!(&steps[..2], &[2, 0], "{steps:?}");
        let total = |e: &Vec<f64>| e.iter().sum::<f64>();
        assert!(total(&per[2]) < 1e-3 * total(&per[0]), "{per:?}");
        assert_eq!(super::one_standard_error(&per), 2);
    }

    /// The block update of the factor gives the factor of the extended Gram.
    #[test]
    fn extended_factor_equals_the_direct_one() {
        let a = DMatrix::from_fn(30, 4, |r, c| ((r + 3 * c) as f64 * 0.71).cos() + 0.2 * c as f64);
        let b = DVector::from_fn(30, |r, _| (r as f64 * 0.3).sin());
        let d = DVector::from_element(4, 1e-3);
        let fold = vec![0, 1, 0, 1, 0, 1, 0, 1, 0, 1];
        let s = super::FoldSystem::new(&a, &b, &d, &fold, 0, &[0, 1]).expect("factorises").expect("has rows");
        let ext = s.extend(&[0, 1], &[3, 2]).expect("extends");
        let direct = super::FoldSystem::new(&a, &b, &d, &fold, 0, &[0, 1, 3, 2]).expect("ok").expect("rows");
        assert!((ext.l - direct.factor.l).amax() < 1e-10);
        assert!((ext.y - direct.factor.y).amax() < 1e-10);
    }
}
