//! The exchange itself: add the best candidate, remove the least useful member
//! (Wynn–Mitchell), excursions, and the best-improvement swaps of the non-determinant
//! objectives with exact evaluation.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par, Side};
use nalgebra::Matrix3;
use rayon::prelude::*;

use super::bookkeeping::{State, Term, gain_of, is_above, loss_of, sym_of};
use super::candidates::Candidates;
use super::options::{DetmaxOptions, Objective};

/// Minimum improvement of ln det for an exchange or excursion to count.
pub(super) const MIN_IMPROVEMENT: f64 = 1e-12;

enum Step {
    Swapped,
    Converged,
}

impl State<'_> {
    /// Non-member with the largest gain `ln det(I + G_k)` (ties: lowest index).
    pub(super) fn best_addition(&self) -> Option<(usize, f64)> {
        self.best.filter(|b| b.1 > 0.0).map(|(k, d)| (k, d.ln()))
    }

    /// The `count` non-members with the largest gains (descending, ties by index).
    fn top_additions(&self, count: usize) -> Vec<usize> {
        let mut v: Vec<(usize, f64)> =
            (0..self.w.len()).filter(|k| !self.member[*k]).map(|k| (k, gain_of(&self.g_of(k)))).collect();
        v.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        v.truncate(count);
        v.into_iter().map(|x| x.0).collect()
    }

    pub(super) fn add(&mut self, k: usize) -> bool {
        let z = self.z_of(k);
        let g = self.bz(k, &z);
        let i_plus = Matrix3::identity() + g;
        let (Some(c), d) = (i_plus.try_inverse(), i_plus.determinant()) else { return false };
        if !is_above(d, 0.0) {
            return false;
        }
        self.design.push(k);
        self.member[k] = true;
        if !self.apply(&[Term { z, c, sign: -1.0 }]) {
            self.design.pop();
            self.member[k] = false;
            return false;
        }
        self.log_det += d.ln();
        self.maybe_refactor();
        true
    }

    /// Removable members in ascending order.
    fn removable(&self) -> Vec<usize> {
        let mut members: Vec<usize> = self.design.iter().copied().filter(|k| !self.fixed[*k]).collect();
        members.sort_unstable();
        members
    }

    /// Removable member with the smallest loss (ties: lowest index); None when removing any
    /// member would make M singular.
    fn best_removal(&self) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        for k in self.removable() {
            let v = loss_of(&sym_of(&self.exact_g(k)));
            if best.is_none_or(|(_, b)| v < b) {
                best = Some((k, v));
            }
        }
        best.filter(|b| b.1.is_finite())
    }

    fn remove(&mut self, k: usize) -> bool {
        let z = self.z_of(k);
        let g = self.bz(k, &z);
        let i_minus = Matrix3::identity() - g;
        let d = i_minus.determinant();
        let Some(c) = i_minus.try_inverse() else { return false };
        if !is_above(d, 0.0) {
            return false;
        }
        self.member[k] = false;
        if !self.apply(&[Term { z, c, sign: 1.0 }]) {
            self.member[k] = true;
            return false;
        }
        self.design.retain(|x| *x != k);
        self.log_det += d.ln();
        self.maybe_refactor();
        true
    }

    /// One Wynn–Mitchell step: add the best candidate, remove the member with the smallest
    /// loss, both applied as a single rank-6 update.
    fn exchange(&mut self) -> Step {
        let Some((k_in, _)) = self.best_addition() else { return Step::Converged };
        let z_in = self.z_of(k_in);
        let g_in = self.bz(k_in, &z_in);
        let i_plus = Matrix3::identity() + g_in;
        let (Some(c_in), det_in) = (i_plus.try_inverse(), i_plus.determinant()) else {
            return Step::Converged;
        };
        if !is_above(det_in, 0.0) {
            return Step::Converged;
        }
        let gain = det_in.ln();
        // losses w.r.t. M1 = M + b_inᵀ b_in: G1_k = G_k − P_k C_in P_kᵀ, P_k = B_k Z_in
        let g1_of = |p: Matrix3<f64>, g: Matrix3<f64>| sym_of(&(g - p * c_in * p.transpose()));
        let loss_in = loss_of(&g1_of(g_in, g_in));
        let mut best_out: Option<(usize, f64)> = None;
        for k in self.removable() {
            let v = loss_of(&g1_of(self.bz(k, &z_in), self.exact_g(k)));
            if best_out.is_none_or(|(_, b)| v < b) {
                best_out = Some((k, v));
            }
        }
        // stop when removing k_in is at least as good (ties favour stopping)
        let Some((k_out, loss_out)) = best_out else { return Step::Converged };
        if !is_above(loss_in, loss_out) || gain - loss_out <= MIN_IMPROVEMENT {
            return Step::Converged;
        }
        // Z_out = M1⁻¹ b_outᵀ = M⁻¹b_outᵀ − Z_in C_in (b_in M⁻¹ b_outᵀ)
        let z_out_m = self.z_of(k_out);
        let cx = c_in * self.bz(k_in, &z_out_m);
        let mut z_out = z_out_m;
        let cx_f = Mat::from_fn(3, 3, |r, col| cx[(r, col)]);
        matmul(z_out.as_mut(), Accum::Add, z_in.as_ref(), cx_f.as_ref(), -1.0, Par::Seq);
        let g_out = self.bz(k_out, &z_out);
        let i_minus = Matrix3::identity() - g_out;
        let (Some(c_out), det_out) = (i_minus.try_inverse(), i_minus.determinant()) else {
            return Step::Converged;
        };
        if !is_above(det_out, 0.0) {
            return Step::Converged;
        }
        self.member[k_out] = false;
        self.member[k_in] = true;
        if !self.apply(&[Term { z: z_in, c: c_in, sign: -1.0 }, Term { z: z_out, c: c_out, sign: 1.0 }]) {
            self.member[k_out] = true;
            self.member[k_in] = false;
            return Step::Converged;
        }
        self.design.retain(|k| *k != k_out);
        self.design.push(k_in);
        self.log_det += gain + det_out.ln();
        self.maybe_refactor();
        Step::Swapped
    }

    /// Exchanges until converged or `cap` steps; returns the number of steps.
    pub(super) fn exchange_until_converged(&mut self, cap: usize) -> usize {
        let mut steps = 0;
        while steps < cap {
            match self.exchange() {
                Step::Swapped => steps += 1,
                Step::Converged => break,
            }
        }
        steps
    }

    /// Adds `d` best then removes `d` (up) or the reverse (down). False if a step failed.
    pub(super) fn excursion(&mut self, depth: usize, up: bool) -> bool {
        for phase in 0..2 {
            for _ in 0..depth {
                let adding = (phase == 0) == up;
                let ok = if adding {
                    self.best_addition().is_some_and(|(k, _)| self.add(k))
                } else {
                    self.best_removal().is_some_and(|(k, _)| self.remove(k))
                };
                if !ok {
                    return false;
                }
            }
        }
        true
    }

    pub(super) fn sorted_design(&self) -> Vec<usize> {
        let mut d = self.design.clone();
        d.sort_unstable();
        d
    }
}

pub(super) fn exact_objective_value(c: &Candidates, design: &[usize], objective: Objective) -> f64 {
    let m = c.information(design);
    objective_of_information(&m, c.parameter_count(), design.len(), objective)
}

fn objective_of_information(m: &Mat<f64>, l: usize, poses: usize, objective: Objective) -> f64 {
    match m.self_adjoint_eigenvalues(Side::Lower) {
        Ok(ev) => {
            let s: Vec<f64> = ev.iter().map(|x| x.max(0.0).sqrt()).collect();
            objective.evaluate(&s, l, poses)
        }
        Err(_) => f64::NEG_INFINITY,
    }
}

/// Best-improvement swaps with exact evaluation of `objective` on the caller's candidates
/// `c` (module docs).
pub(super) fn refine_exact(s: &mut State<'_>, c: &Candidates, o: &DetmaxOptions) -> usize {
    let (l, n) = (c.parameter_count(), o.count);
    let mut current = exact_objective_value(c, &s.design, o.objective);
    let mut swaps = 0;
    while swaps < o.max_exchanges {
        let m = c.information(&s.design);
        let shortlist = s.top_additions(o.shortlist);
        let outer: Vec<(f64, usize, usize)> = s
            .removable()
            .par_iter()
            .filter_map(|&out| {
                let mut m_out = m.clone();
                let b_out = c.block(out);
                matmul(m_out.as_mut(), Accum::Add, b_out.transpose(), b_out, -1.0, Par::Seq);
                let mut best: Option<(f64, usize, usize)> = None;
                for &inn in &shortlist {
                    let mut mt = m_out.clone();
                    let b_in = c.block(inn);
                    matmul(mt.as_mut(), Accum::Add, b_in.transpose(), b_in, 1.0, Par::Seq);
                    let v = objective_of_information(&mt, l, n, o.objective);
                    if best.is_none_or(|b| v > b.0) {
                        best = Some((v, out, inn));
                    }
                }
                best
            })
            .collect();
        let best = outer.into_iter().fold(None, |acc: Option<(f64, usize, usize)>, x| match acc {
            Some(a) if a.0 >= x.0 => Some(a),
            _ => Some(x),
        });
        match best {
            Some((v, out, inn)) if v > current * (1.0 + 1e-12) && v.is_finite() => {
                if !(s.add(inn) && s.remove(out)) {
                    break;
                }
                current = v;
                swaps += 1;
            }
            _ => break,
        }
    }
    swaps
}
