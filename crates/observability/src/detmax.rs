//! D-optimal pose selection: Detmax exchange with rank-3 updates (background.md §4).
//!
//! # Problem
//! Choose `n` of `N` candidate poses maximising `ln det M(S)`, `M(S) = Σ_{k∈S} B_kᵀ B_k (+ R)`,
//! where `B_k` is the 3 × L Jacobian block of candidate k ([`Candidates`]) and R an optional
//! ridge. At fixed `n` this is the same as maximising O1 (O1^{2L} = det M / n^L), and the
//! choice does not depend on the column scaling.
//!
//! # Fast path (O1)
//! The exchange keeps, at all times,
//! * `M⁻¹` (L × L) and `ln det M`,
//! * for **every** candidate the symmetric 3 × 3 matrix `G_k = B_k M⁻¹ B_kᵀ`.
//!
//! The gain of adding k is `ln det(I₃ + G_k)` and the loss of removing a member is
//! `−ln det(I₃ − G_k)` (matrix determinant lemma). One exchange step (add the best candidate,
//! remove the member with the smallest loss, Wynn–Mitchell) changes `M` by a rank-6 term
//! `b_inᵀ b_in − b_outᵀ b_out`; by Sherman–Morrison–Woodbury
//!
//! ```text
//! M'⁻¹ = M⁻¹ − Z_in C_in Z_inᵀ + Z_out C_out Z_outᵀ,
//! Z_in = M⁻¹ b_inᵀ,  C_in = (I + b_in Z_in)⁻¹,
//! Z_out = M₁⁻¹ b_outᵀ (M₁ = M + b_inᵀ b_in),  C_out = (I − b_out Z_out)⁻¹,
//! G_k' = G_k − P_k C_in P_kᵀ + Q_k C_out Q_kᵀ,  [P_k Q_k] = B_k [Z_in Z_out].
//! ```
//!
//! With `C = L Lᵀ` (3 × 3 Cholesky) each term is `Q Qᵀ`, `Q = B_k Z L`, so a step costs one
//! tall product `B · [Z_in L_in, Z_out L_out]` (3N × L times L × 6, batched with faer matmul
//! over fixed-size chunks of candidates, chunks in parallel with rayon) plus 36 multiply-adds
//! per candidate — no determinant or factorisation per candidate. The add and the remove are
//! applied in that single pass. `M⁻¹`, `ln det M` and all `G_k` are recomputed from a
//! Cholesky factorisation every [`DetmaxOptions::refactor_every`] steps to stop drift.
//!
//! Numerics. The exchange works on the candidates with every column divided by its norm over
//! the whole set (the criterion is scale-invariant; unit columns keep all inner products well
//! conditioned). The bulk pass over all N candidates is memory-bound, so it reads an f32 copy
//! of the blocks (half the bytes; G_k accumulated in f64): the stored `G_k` of non-members
//! are therefore f32-accurate (~1e-7 relative) and serve only to *rank* the candidates to add.
//! Everything that enters `ln det` — the gain of the candidate actually added, the losses of
//! the members (their `G_k` recomputed exactly from `M⁻¹` at every step), `M⁻¹` itself — is
//! f64. The reported `log_det` is recomputed from scratch in natural units.
//!
//! # Algorithm
//! 1. Start: `fixed` poses plus a random subset (ChaCha8, seed per restart). If that design is
//!    singular (a Cholesky pivot loses all but 1e-13 of its column's information), check that
//!    the candidate set as a whole has full rank (otherwise fail with
//!    [`ObservabilityError::RankDeficient`] naming the parameters; a non-singular start already
//!    proves full rank, so the common case skips this O(N L²) check), then start greedily:
//!    from the fixed poses plus a tiny ridge, add the best candidate until `n` (Dykstra), then
//!    drop the ridge. [`Initialisation::Greedy`] always starts greedily.
//! 2. Exchange until the member removed is the one just added (ties are resolved in favour of
//!    stopping, then the lowest candidate index), or the gain of a step is below 1e-12, or
//!    `max_exchanges` steps.
//! 3. Optional excursions ([`DetmaxOptions::excursions`], a simplified form of Mitchell's
//!    DETMAX): at depth d = 1, 2, … try "add the d best, then remove the d least useful" and
//!    "remove d, then add d"; an improvement is polished by step 2 and resets d to 1; the walk
//!    stops when d exceeds the maximum depth. (Mitchell's failure set is not kept: the
//!    excursions here are deterministic, so revisiting a design cannot happen without an
//!    improvement in between.)
//! 4. Restarts run in parallel; each has its own seed derived from `seed` and its index. Inside
//!    a restart every candidate chunk is computed the same way whichever thread runs it, and
//!    chunk results are combined in chunk order, so the result does not depend on the number
//!    of threads. The best restart wins (ties: lowest
//!    restart index).
//!
//! # Other objectives
//! O2..O5 ([`Objective`]) are not determinant-based, so they have no cheap update. They run
//! the O1 Detmax first, then a best-improvement swap search with *exact* evaluation: every
//! member × each of the `shortlist` non-members with the largest D-gain, objective from the
//! eigenvalues of the updated L × L information matrix (σ_i = √λ_i). Slower (≈ n × shortlist
//! eigen-decompositions per swap) and dependent on the column scaling of the candidates.
//!
//! # Reference
//! [`naive_detmax`] runs the same exchange with every gain and loss computed from scratch from
//! the singular values of the stacked design Jacobian — for tests and the benchmark.

use std::cmp::Ordering;

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::DenseSolveCore;
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};
use nalgebra::Matrix3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;
use vatcal_core::{Measurement, ParamSet};
use vatcal_kinematics::Model;

use crate::error::ObservabilityError;
use crate::identifiability::ColumnScaling;
#[cfg(doc)]
use crate::identifiability::assemble_jacobian;
use crate::identifiability::{
    AnalysisOptions, analyze_jacobian, measurement_block, rank_deficient_error, reindex,
};
use crate::indices::ObservabilityIndices;

/// Candidates per chunk of the batched updates. Fixed, so results do not depend on the
/// number of threads.
const CHUNK: usize = 1024;
/// Measurements per parallel task when the candidate Jacobians are evaluated.
const JACOBIAN_CHUNK: usize = 256;
/// A Cholesky pivot `L_ii²` below this fraction of `M_ii` counts as singular.
const PIVOT_FRACTION: f64 = 1e-13;
/// Relative ridge used by the greedy start before it is removed again.
const GREEDY_RIDGE: f64 = 1e-6;
/// Minimum improvement of ln det for an exchange or excursion to count.
const MIN_IMPROVEMENT: f64 = 1e-12;

/// The candidate poses as stacked 3 × L Jacobian blocks (candidate k = rows `3k..3k+3`),
/// stored row-major so that each candidate's block is contiguous.
#[derive(Debug, Clone)]
pub struct Candidates {
    /// row-major 3N × L
    rows: Vec<f64>,
    l: usize,
    params: ParamSet,
}

impl Candidates {
    /// From a stacked natural-unit Jacobian (3 rows per candidate) and its parameters.
    pub fn from_stacked(blocks: Mat<f64>, params: ParamSet) -> Result<Self, ObservabilityError> {
        if params.is_empty() {
            return Err(ObservabilityError::NoParameters);
        }
        if blocks.ncols() != params.len() || !blocks.nrows().is_multiple_of(3) {
            return Err(ObservabilityError::InvalidInput(format!(
                "candidate blocks are {} × {}; expected 3 rows per candidate and {} columns",
                blocks.nrows(),
                blocks.ncols(),
                params.len()
            )));
        }
        for c in 0..blocks.ncols() {
            if let Some(r) = blocks.col(c).iter().position(|x| !x.is_finite()) {
                return Err(ObservabilityError::NonFinite { index: r / 3, param: params.0[c] });
            }
        }
        let l = blocks.ncols();
        let mut rows = Vec::with_capacity(blocks.nrows() * l);
        for r in 0..blocks.nrows() {
            rows.extend((0..l).map(|c| blocks[(r, c)]));
        }
        Ok(Self { rows, l, params })
    }

    /// The Jacobian blocks of probe/tracker measurements (the blocks of [`assemble_jacobian`],
    /// bit for bit). Evaluated in parallel over fixed chunks of measurements, written straight
    /// into the row-major storage; an error names the lowest failing measurement index.
    pub fn from_measurements(
        model: &Model,
        measurements: &[Measurement],
        params: &ParamSet,
    ) -> Result<Self, ObservabilityError> {
        if params.is_empty() {
            return Err(ObservabilityError::NoParameters);
        }
        let l = params.len();
        let mut rows = vec![0.0; 3 * l * measurements.len()];
        let errors: Vec<ObservabilityError> = rows
            .par_chunks_mut(3 * l * JACOBIAN_CHUNK)
            .zip(measurements.par_chunks(JACOBIAN_CHUNK))
            .enumerate()
            .filter_map(|(ci, (out, chunk))| {
                let mut block = vec![0.0; 3 * l];
                for (i, (m, dst)) in chunk.iter().zip(out.chunks_mut(3 * l)).enumerate() {
                    if let Err(e) = measurement_block(model, m, &params.0, &mut block) {
                        return Some(reindex(e, ci * JACOBIAN_CHUNK + i));
                    }
                    // column-major 3 × L block -> three row-major rows
                    for (c, col) in block.chunks_exact(3).enumerate() {
                        for (r, v) in col.iter().enumerate() {
                            dst[r * l + c] = *v;
                        }
                    }
                }
                None
            })
            .collect();
        // chunks are collected in order: the first error is the lowest index
        if let Some(e) = errors.into_iter().next() {
            return Err(e);
        }
        Ok(Self { rows, l, params: params.clone() })
    }

    /// Number of candidates N.
    pub fn len(&self) -> usize {
        self.rows.len() / (3 * self.l)
    }

    /// True when there are no candidates.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of parameters L.
    pub fn parameter_count(&self) -> usize {
        self.l
    }

    /// The parameters (columns).
    pub fn params(&self) -> &ParamSet {
        &self.params
    }

    /// The 3 × L block of candidate `k`.
    ///
    /// # Panics
    /// If `k >= len()`.
    #[track_caller]
    pub fn block(&self, k: usize) -> MatRef<'_, f64> {
        self.stacked().subrows(3 * k, 3)
    }

    /// Row `a` (0..3) of candidate `k`'s block.
    fn row(&self, k: usize, a: usize) -> &[f64] {
        let start = (3 * k + a) * self.l;
        &self.rows[start..start + self.l]
    }

    /// All blocks stacked (3N × L, a row-major view).
    pub fn stacked(&self) -> MatRef<'_, f64> {
        MatRef::from_row_major_slice(&self.rows, self.rows.len() / self.l, self.l)
    }

    /// The stacked Jacobian (3n × L) of a design.
    pub fn design_jacobian(&self, design: &[usize]) -> Mat<f64> {
        Mat::from_fn(3 * design.len(), self.l, |r, c| self.row(design[r / 3], r % 3)[c])
    }

    /// The candidates `indices` (in that order).
    pub fn subset(&self, indices: &[usize]) -> Self {
        let mut rows = Vec::with_capacity(indices.len() * 3 * self.l);
        for &k in indices {
            for a in 0..3 {
                rows.extend_from_slice(self.row(k, a));
            }
        }
        Self { rows, l: self.l, params: self.params.clone() }
    }

    /// The same candidates with column j multiplied by `factors[j]` (e.g. unit-norm factors
    /// computed over the whole candidate set, for O2..O5).
    ///
    /// # Panics
    /// If `factors.len()` is not the number of parameters.
    #[track_caller]
    pub fn scaled(&self, factors: &[f64]) -> Self {
        assert_eq!(factors.len(), self.l, "one factor per parameter");
        let rows = self.rows.chunks(self.l).flat_map(|r| r.iter().zip(factors).map(|(x, f)| x * f)).collect();
        Self { rows, l: self.l, params: self.params.clone() }
    }

    /// Information matrix `Σ_{k∈design} B_kᵀ B_k`.
    pub fn information(&self, design: &[usize]) -> Mat<f64> {
        let j = self.design_jacobian(design);
        let mut m = Mat::<f64>::zeros(self.l, self.l);
        matmul(m.as_mut(), Accum::Replace, j.transpose(), j.as_ref(), 1.0, Par::Seq);
        m
    }

    /// `Σ_k B_kᵀ B_k` over all candidates (chunked, deterministic summation order).
    fn total_information(&self) -> Mat<f64> {
        let l = self.parameter_count();
        let n = self.len();
        let parts: Vec<Mat<f64>> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|ci| {
                let start = ci * CHUNK;
                let len = CHUNK.min(n - start);
                let b = self.stacked().subrows(3 * start, 3 * len);
                let mut m = Mat::<f64>::zeros(l, l);
                matmul(m.as_mut(), Accum::Replace, b.transpose(), b, 1.0, Par::Seq);
                m
            })
            .collect();
        let mut total = Mat::<f64>::zeros(l, l);
        for p in parts {
            total += p;
        }
        total
    }
}

/// The objective a selection maximises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Objective {
    /// O1 — D-optimality (fast rank-3 path; scale-invariant)
    #[default]
    O1,
    /// O2 = σ_min/σ_max (exact evaluation)
    O2,
    /// O3 = σ_min (exact evaluation)
    O3,
    /// O4 = σ_min²/σ_max (exact evaluation)
    O4,
    /// O5 = 1/Σ 1/σ_i (exact evaluation)
    O5,
}

impl Objective {
    /// Parses `o1`..`o5` (case-insensitive).
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "o1" => Some(Self::O1),
            "o2" => Some(Self::O2),
            "o3" => Some(Self::O3),
            "o4" => Some(Self::O4),
            "o5" => Some(Self::O5),
            _ => None,
        }
    }

    /// The objective's value for a design with these singular values and `poses` poses.
    pub fn evaluate(self, singular_values: &[f64], parameter_count: usize, poses: usize) -> f64 {
        let i = ObservabilityIndices::from_singular_values(
            singular_values,
            parameter_count,
            poses,
            ColumnScaling::None,
        );
        match self {
            Self::O1 => i.o1,
            Self::O2 => i.o2,
            Self::O3 => i.o3,
            Self::O4 => i.o4,
            Self::O5 => i.o5,
        }
    }
}

/// How each restart starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Initialisation {
    /// `fixed` plus a random subset (greedy if that is singular)
    #[default]
    Random,
    /// greedy (Dykstra) from `fixed` — deterministic, so all restarts coincide
    Greedy,
}

/// Options of [`detmax`].
#[derive(Debug, Clone, PartialEq)]
pub struct DetmaxOptions {
    /// design size n
    pub count: usize,
    /// number of restarts (≥ 1), run in parallel
    pub restarts: usize,
    /// master seed; restart r uses a seed derived from (seed, r)
    pub seed: u64,
    /// cap on exchange steps per restart (and on exact-objective swaps)
    pub max_exchanges: usize,
    /// maximum excursion depth (None = plain exchange)
    pub excursions: Option<usize>,
    /// candidate indices that must be in the design
    pub fixed: Vec<usize>,
    /// the objective
    pub objective: Objective,
    /// relative ridge: `R = ridge · diag(Σ_all B_kᵀB_k) / N` is added to every design's
    /// information matrix (0 = none). Needed only to select from a candidate set that cannot
    /// identify all parameters (e.g. the one-position ablation).
    pub ridge: f64,
    /// refactor `M⁻¹` and all `G_k` from scratch after this many updates
    pub refactor_every: usize,
    /// non-members (largest D-gain) tried per swap by the exact objectives O2..O5
    pub shortlist: usize,
    /// how restarts start
    pub init: Initialisation,
}

impl DetmaxOptions {
    /// Defaults for a design of `count` poses: 8 restarts, seed 0, no excursions, O1.
    pub fn new(count: usize) -> Self {
        Self {
            count,
            restarts: 8,
            seed: 0,
            max_exchanges: 10_000,
            excursions: None,
            fixed: Vec::new(),
            objective: Objective::O1,
            ridge: 0.0,
            refactor_every: 50,
            shortlist: 32,
            init: Initialisation::Random,
        }
    }
}

/// What one restart did.
#[derive(Debug, Clone, PartialEq)]
pub struct RestartOutcome {
    /// the restart's own seed
    pub seed: u64,
    /// ln det of its final design (from scratch, ridge included)
    pub log_det: f64,
    /// objective value of its final design
    pub objective_value: f64,
    /// exchange steps taken (excursion steps included)
    pub exchanges: usize,
    /// excursions that improved the design
    pub excursions_accepted: usize,
    /// true when the start was greedy (requested, or the random start was singular)
    pub greedy_start: bool,
}

/// Result of a selection.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// selected candidate indices, ascending
    pub selected: Vec<usize>,
    /// ln det(M + R) of the selection, computed from scratch (Cholesky)
    pub log_det: f64,
    /// ln det as tracked incrementally by the winning restart (equals `log_det` up to
    /// round-off)
    pub tracked_log_det: f64,
    /// objective value of the selection
    pub objective_value: f64,
    /// index of the winning restart
    pub best_restart: usize,
    /// every restart, in order
    pub restarts: Vec<RestartOutcome>,
}

impl Selection {
    /// O1 of the selection from its log-determinant (exact when there is no ridge):
    /// `exp(ln det / 2L) / √n`, in the units of the candidate blocks.
    pub fn o1(&self, parameter_count: usize) -> f64 {
        o1_from_log_det(self.log_det, parameter_count, self.selected.len())
    }
}

/// `exp(ln det M / 2L) / √n`.
pub fn o1_from_log_det(log_det: f64, parameter_count: usize, poses: usize) -> f64 {
    (log_det / (2.0 * parameter_count as f64)).exp() / (poses.max(1) as f64).sqrt()
}

/// `ln det(Σ_{k∈design} B_kᵀB_k + R)` from scratch (Cholesky), `R = ridge · diag(Σ_all)/N`;
/// `None` when singular.
pub fn log_det(candidates: &Candidates, design: &[usize], ridge: f64) -> Option<f64> {
    let r = ridge_diagonal(candidates, ridge);
    factor(&with_ridge(candidates.information(design), &r)).map(|f| f.1)
}

// ------------------------------------------------------------------------------------------
// small symmetric 3×3 helpers

type Sym3 = [f64; 6];

fn sym_of(m: &Matrix3<f64>) -> Sym3 {
    [
        m[(0, 0)],
        0.5 * (m[(0, 1)] + m[(1, 0)]),
        0.5 * (m[(0, 2)] + m[(2, 0)]),
        m[(1, 1)],
        0.5 * (m[(1, 2)] + m[(2, 1)]),
        m[(2, 2)],
    ]
}

fn det_i_plus(g: &Sym3, s: f64) -> f64 {
    let (a, b, c, d, e, f) = (1.0 + s * g[0], s * g[1], s * g[2], 1.0 + s * g[3], s * g[4], 1.0 + s * g[5]);
    a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
}

/// `ln det(I + G)`
fn gain_of(g: &Sym3) -> f64 {
    let d = det_i_plus(g, 1.0);
    if d > 0.0 { d.ln() } else { f64::NEG_INFINITY }
}

/// `−ln det(I − G)` (∞ when removing makes M singular)
fn loss_of(g: &Sym3) -> f64 {
    let d = det_i_plus(g, -1.0);
    if d > 0.0 { -d.ln() } else { f64::INFINITY }
}

// ------------------------------------------------------------------------------------------
// factorisation helpers

/// Euclidean norm of every column over all candidates.
fn column_norms(c: &Candidates) -> Vec<f64> {
    // per chunk of CHUNK candidates in parallel, the partial sums added in chunk order: the
    // result does not depend on the number of threads
    let partial: Vec<Vec<f64>> = c
        .rows
        .par_chunks(3 * CHUNK * c.l)
        .map(|rows| {
            let mut sq = vec![0.0; c.l];
            for row in rows.chunks(c.l) {
                for (s, x) in sq.iter_mut().zip(row) {
                    *s += x * x;
                }
            }
            sq
        })
        .collect();
    let mut sq = vec![0.0; c.l];
    for p in partial {
        for (s, x) in sq.iter_mut().zip(p) {
            *s += x;
        }
    }
    sq.into_iter().map(f64::sqrt).collect()
}

/// Natural-unit ridge `R_j = ridge · ‖column j‖² / N` (empty when `ridge == 0`).
fn ridge_diagonal(c: &Candidates, ridge: f64) -> Vec<f64> {
    if ridge <= 0.0 {
        return Vec::new();
    }
    let n = c.len().max(1) as f64;
    column_norms(c).into_iter().map(|x| ridge * x * x / n).collect()
}

fn with_ridge(mut m: Mat<f64>, r: &[f64]) -> Mat<f64> {
    for (j, v) in r.iter().enumerate() {
        m[(j, j)] += v;
    }
    m
}

/// `(M⁻¹, ln det M)`, or None if M is (numerically) singular.
fn factor(m: &Mat<f64>) -> Option<(Mat<f64>, f64)> {
    let llt = m.llt(Side::Lower).ok()?;
    let l = llt.L();
    let mut log_det = 0.0;
    for i in 0..m.nrows() {
        let p = l[(i, i)] * l[(i, i)];
        if !is_above(p, PIVOT_FRACTION * m[(i, i)]) || !p.is_finite() {
            return None;
        }
        log_det += p.ln();
    }
    let mut inv = llt.inverse();
    symmetrize(&mut inv);
    Some((inv, log_det))
}

/// `a > b`, false when either is NaN.
fn is_above(a: f64, b: f64) -> bool {
    a.partial_cmp(&b) == Some(Ordering::Greater)
}

fn symmetrize(m: &mut Mat<f64>) {
    for i in 0..m.nrows() {
        for j in 0..i {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

// ------------------------------------------------------------------------------------------
// the working copy of the candidates

/// The candidates as the exchange sees them (module docs, "Numerics"): the caller's blocks
/// with column factors `1/‖col_j‖`, plus an f32 copy of the normalised blocks for the bulk
/// passes, stored per chunk of [`CHUNK`] candidates, column-major, in *planar* row order (all
/// x rows of the chunk, then all y rows, then all z rows), so that every product with it
/// yields, for each (row, column), a contiguous vector over the chunk's candidates and the
/// 3 × 3 updates vectorise across candidates.
struct Work<'a> {
    /// the caller's candidates (natural units)
    orig: &'a Candidates,
    /// column factors `1/‖col_j‖` (1 for an all-zero column)
    factors: Vec<f64>,
    rows32: Vec<f32>,
    /// `2 Σ ln(1/‖col_j‖)`: ln det of the normalised M = natural ln det + this
    log_scale: f64,
    /// ridge on the normalised columns (`ridge / N`, 0 for an all-zero column)
    ridge: Vec<f64>,
}

/// `(start, len)` of chunk `ci` of `n` candidates.
fn chunk_range(ci: usize, n: usize) -> (usize, usize) {
    let start = ci * CHUNK;
    (start, CHUNK.min(n - start))
}

impl<'a> Work<'a> {
    fn new(orig: &'a Candidates, ridge: f64) -> Self {
        let norms = column_norms(orig);
        let factors: Vec<f64> = norms.iter().map(|x| if *x > 0.0 { 1.0 / x } else { 1.0 }).collect();
        let (n, l) = (orig.len(), orig.l);
        // per chunk: read the candidates' rows in order, write the planar column-major layout
        // (the chunk stays in cache while it is transposed)
        let mut rows32 = vec![0.0f32; orig.rows.len()];
        rows32.par_chunks_mut(3 * CHUNK * l).enumerate().for_each(|(ci, out)| {
            let (start, len) = chunk_range(ci, n);
            // blocks of 16 candidates: 48 source rows stay in L1, each store run fills a line
            const BLOCK: usize = 16;
            let src_chunk = &orig.rows[3 * start * l..3 * (start + len) * l];
            for i0 in (0..len).step_by(BLOCK) {
                let width = BLOCK.min(len - i0);
                let src = &src_chunk[3 * i0 * l..3 * (i0 + width) * l];
                for a in 0..3 {
                    for (j, f) in factors.iter().enumerate() {
                        let dst = &mut out[j * 3 * len + a * len + i0..][..width];
                        for (d, row) in dst.iter_mut().zip(src.chunks_exact(3 * l)) {
                            *d = (row[a * l + j] * f) as f32;
                        }
                    }
                }
            }
        });
        let log_scale = 2.0 * factors.iter().map(|f| f.ln()).sum::<f64>();
        let nf = n.max(1) as f64;
        let ridge = if ridge > 0.0 {
            norms.iter().map(|x| if *x > 0.0 { ridge / nf } else { 0.0 }).collect()
        } else {
            Vec::new()
        };
        Self { orig, factors, rows32, log_scale, ridge }
    }

    fn len(&self) -> usize {
        self.orig.len()
    }

    fn l(&self) -> usize {
        self.orig.l
    }

    /// Normalised row `a` of candidate `k`, element `j`.
    fn at(&self, k: usize, a: usize, j: usize) -> f64 {
        self.orig.row(k, a)[j] * self.factors[j]
    }

    /// Normalised information matrix `D (Σ_design B_kᵀB_k) D`.
    fn information(&self, design: &[usize]) -> Mat<f64> {
        let m = self.orig.information(design);
        Mat::from_fn(self.l(), self.l(), |r, c| m[(r, c)] * self.factors[r] * self.factors[c])
    }

    /// Chunk `ci` of the f32 copy: 3len × L, column-major, planar rows (row `a·len + i` is row
    /// `a` of candidate `start + i`), so faer's matmul reads it without repacking.
    fn chunk32(&self, ci: usize) -> MatRef<'_, f32> {
        let l = self.l();
        let (start, len) = chunk_range(ci, self.len());
        MatRef::from_column_major_slice(&self.rows32[3 * start * l..3 * (start + len) * l], 3 * len, l)
    }
}

/// The six entries of a symmetric 3 × 3 matrix: (row, column) of g₀..g₅.
const SYM: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// `G += sign · Q Qᵀ` for every candidate of a chunk: `g` holds the six planes of G (see
/// [`SYM`]), `r[a][j]` the plane of `Q[a][j]`. One sweep over the candidates, vectorisable.
fn add_outer_products(g: &mut [f64], r: &[[&[f32]; 3]; 3], sign: f32, len: usize) {
    let (g0, rest) = g.split_at_mut(len);
    let (g1, rest) = rest.split_at_mut(len);
    let (g2, rest) = rest.split_at_mut(len);
    let (g3, rest) = rest.split_at_mut(len);
    let (g4, g5) = rest.split_at_mut(len);
    let g5 = &mut g5[..len];
    let [[x0, x1, x2], [y0, y1, y2], [z0, z1, z2]] = r.map(|row| row.map(|p| &p[..len]));
    for i in 0..len {
        let (a0, a1, a2) = (x0[i], x1[i], x2[i]);
        let (b0, b1, b2) = (y0[i], y1[i], y2[i]);
        let (c0, c1, c2) = (z0[i], z1[i], z2[i]);
        g0[i] += f64::from(sign * (a0 * a0 + a1 * a1 + a2 * a2));
        g1[i] += f64::from(sign * (a0 * b0 + a1 * b1 + a2 * b2));
        g2[i] += f64::from(sign * (a0 * c0 + a1 * c1 + a2 * c2));
        g3[i] += f64::from(sign * (b0 * b0 + b1 * b1 + b2 * b2));
        g4[i] += f64::from(sign * (b0 * c0 + b1 * c1 + b2 * c2));
        g5[i] += f64::from(sign * (c0 * c0 + c1 * c1 + c2 * c2));
    }
}

/// `det(I + G)` for every candidate of a chunk from the six planes of G.
fn det_planes(g: &[f64], len: usize, out: &mut Vec<f64>) {
    let p = |e: usize| &g[e * len..(e + 1) * len];
    let (g0, g1, g2, g3, g4, g5) = (p(0), p(1), p(2), p(3), p(4), p(5));
    out.clear();
    out.extend((0..len).map(|i| det_i_plus(&[g0[i], g1[i], g2[i], g3[i], g4[i], g5[i]], 1.0)));
}

/// Best non-member of chunk `(start, len)` by `det(I + G)` (ties: lowest index).
fn chunk_best(
    g: &[f64],
    start: usize,
    len: usize,
    member: &[bool],
    dets: &mut Vec<f64>,
) -> Option<(usize, f64)> {
    det_planes(g, len, dets);
    let mut best = None;
    for (i, d) in dets.iter().enumerate() {
        if !member[start + i] {
            best = better(best, Some((start + i, *d)));
        }
    }
    best
}

// ------------------------------------------------------------------------------------------
// the exchange state

/// One rank-3 term `sign · Z C Zᵀ` of an inverse update.
struct Term {
    z: Mat<f64>,
    c: Matrix3<f64>,
    sign: f64,
}

#[derive(Clone)]
struct State<'a> {
    w: &'a Work<'a>,
    ridge: Vec<f64>,
    design: Vec<usize>,
    member: Vec<bool>,
    fixed: Vec<bool>,
    minv: Mat<f64>,
    log_det: f64,
    /// `G_k` of all candidates, per chunk six planes (g₀..g₅ of [`SYM`]) over its candidates
    g: Vec<f64>,
    /// best non-member `(k, det(I + G_k))`, refreshed by every pass over `g`
    best: Option<(usize, f64)>,
    since_refactor: usize,
    refactor_every: usize,
}

enum Step {
    Swapped,
    Converged,
}

/// Keeps the larger `det(I + G)`; ties keep the lower index.
fn better(a: Option<(usize, f64)>, b: Option<(usize, f64)>) -> Option<(usize, f64)> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if y.1 > x.1 || (y.1 == x.1 && y.0 < x.0) { y } else { x }),
        (x, None) => x,
        (None, y) => y,
    }
}

impl<'a> State<'a> {
    /// Builds the state of `design` with the ridge `ridge` (normalised units); None if
    /// singular.
    fn new(
        w: &'a Work<'a>,
        design: Vec<usize>,
        fixed: &[bool],
        ridge: Vec<f64>,
        refactor_every: usize,
    ) -> Option<Self> {
        let mut member = vec![false; w.len()];
        for &k in &design {
            member[k] = true;
        }
        let mut s = Self {
            w,
            ridge,
            design,
            member,
            fixed: fixed.to_vec(),
            minv: Mat::zeros(0, 0),
            log_det: 0.0,
            g: vec![0.0; 6 * w.len()],
            best: None,
            since_refactor: 0,
            refactor_every: refactor_every.max(1),
        };
        s.refactor().then_some(s)
    }

    /// Recomputes M⁻¹, ln det M and every G_k from scratch. False if M is singular.
    fn refactor(&mut self) -> bool {
        let m = with_ridge(self.w.information(&self.design), &self.ridge);
        let Some((minv, log_det)) = factor(&m) else { return false };
        self.minv = minv;
        self.log_det = log_det;
        self.since_refactor = 0;
        self.recompute_g()
    }

    /// `G_k = B_k M⁻¹ B_kᵀ` for all k: with `M⁻¹ = U Uᵀ` (Cholesky), per chunk `V = B_ch U`
    /// (faer matmul, f32) and `G_k[a][b] = Σ_j V[a][j] V[b][j]`, vectorised across the chunk's
    /// candidates. False if `M⁻¹` is not positive definite.
    fn recompute_g(&mut self) -> bool {
        let (w, member) = (self.w, &self.member);
        let (n, l) = (w.len(), w.l());
        let Ok(llt) = self.minv.llt(Side::Lower) else { return false };
        let u = llt.L();
        let u32 = Mat::from_fn(l, l, |r, c| u[(r, c)] as f32);
        let parts: Vec<Option<(usize, f64)>> = self
            .g
            .par_chunks_mut(6 * CHUNK)
            .enumerate()
            .map_init(
                || (vec![0.0f32; 3 * CHUNK * l], vec![0.0f32; CHUNK], Vec::with_capacity(CHUNK)),
                |(buf, acc, dets), (ci, gch)| {
                    let (start, len) = chunk_range(ci, n);
                    let v = &mut buf[..3 * len * l];
                    matmul(
                        MatMut::from_column_major_slice_mut(v, 3 * len, l),
                        Accum::Replace,
                        w.chunk32(ci),
                        u32.as_ref(),
                        1.0,
                        Par::Seq,
                    );
                    let v = &*v;
                    let acc = &mut acc[..len];
                    for (e, (a, b)) in SYM.iter().enumerate() {
                        acc.fill(0.0);
                        for j in 0..l {
                            let col = &v[j * 3 * len..(j + 1) * 3 * len];
                            let (va, vb) = (&col[a * len..(a + 1) * len], &col[b * len..(b + 1) * len]);
                            for ((s, x), y) in acc.iter_mut().zip(va).zip(vb) {
                                *s += x * y;
                            }
                        }
                        for (gi, s) in gch[e * len..(e + 1) * len].iter_mut().zip(acc.iter()) {
                            *gi = f64::from(*s);
                        }
                    }
                    chunk_best(gch, start, len, member, dets)
                },
            )
            .collect();
        self.best = parts.into_iter().fold(None, better);
        true
    }

    /// `G_k` of candidate `k` as stored (f32-accurate).
    fn g_of(&self, k: usize) -> Sym3 {
        let ci = k / CHUNK;
        let (start, len) = chunk_range(ci, self.w.len());
        let base = 6 * start + (k - start);
        std::array::from_fn(|e| self.g[base + e * len])
    }

    /// `M⁻¹ bᵀ` (L × 3) for candidate k (f64).
    fn z_of(&self, k: usize) -> Mat<f64> {
        let bt = Mat::from_fn(self.w.l(), 3, |j, a| self.w.at(k, a, j));
        let mut z = Mat::<f64>::zeros(self.w.l(), 3);
        matmul(z.as_mut(), Accum::Replace, self.minv.as_ref(), bt.as_ref(), 1.0, Par::Seq);
        z
    }

    /// `B_k Z` (3 × 3, f64).
    fn bz(&self, k: usize, z: &Mat<f64>) -> Matrix3<f64> {
        Matrix3::from_fn(|a, b| {
            let row = self.w.orig.row(k, a);
            (0..row.len()).map(|j| row[j] * self.w.factors[j] * z[(j, b)]).sum()
        })
    }

    /// Exact `G_k = B_k M⁻¹ B_kᵀ` (f64), for the members whose losses decide removals.
    fn exact_g(&self, k: usize) -> Matrix3<f64> {
        self.bz(k, &self.z_of(k))
    }

    /// Applies `M⁻¹ += Σ sign Z C Zᵀ` and the matching `G_k` update for all candidates, and
    /// refreshes the best non-member. With `C_t = L_t L_tᵀ` (3 × 3 Cholesky; C is positive
    /// definite for additions and for removals that keep M non-singular) the update is
    /// `G_k += Σ_t sign_t Q_t Q_tᵀ`, `Q_t = B_k Z_t L_t`. One pass over the candidates: per
    /// chunk a single f32 faer matmul `[Q₁ Q₂] = B_ch [Z₁L₁ Z₂L₂]`, then 18 multiply-adds per
    /// term and candidate, vectorised across the chunk's candidates. Member flags must already
    /// describe the new design. False (nothing changed) if a C_t is not positive definite.
    fn apply(&mut self, terms: &[Term]) -> bool {
        let (n, l) = (self.w.len(), self.w.l());
        let nt = terms.len();
        let mut zl = Mat::<f64>::zeros(l, 3 * nt);
        for (t, term) in terms.iter().enumerate() {
            let Some(chol) = nalgebra::Cholesky::new(term.c) else { return false };
            let lt = chol.l();
            let lf = Mat::from_fn(3, 3, |r, col| lt[(r, col)]);
            matmul(
                zl.as_mut().get_mut(.., 3 * t..3 * t + 3),
                Accum::Replace,
                term.z.as_ref(),
                lf.as_ref(),
                1.0,
                Par::Seq,
            );
        }
        for (t, term) in terms.iter().enumerate() {
            let q = zl.as_ref().get(.., 3 * t..3 * t + 3);
            matmul(self.minv.as_mut(), Accum::Add, q, q.transpose(), term.sign, Par::Seq);
        }
        symmetrize(&mut self.minv);
        let zz = Mat::<f32>::from_fn(l, 3 * nt, |r, col| zl[(r, col)] as f32);
        let signs: Vec<f32> = terms.iter().map(|t| t.sign as f32).collect();
        let (w, member) = (self.w, &self.member);
        let width = 3 * nt;
        let parts: Vec<Option<(usize, f64)>> = self
            .g
            .par_chunks_mut(6 * CHUNK)
            .enumerate()
            .map_init(
                || (vec![0.0f32; 3 * CHUNK * width], Vec::with_capacity(CHUNK)),
                |(buf, dets), (ci, gch)| {
                    let (start, len) = chunk_range(ci, n);
                    let q = &mut buf[..3 * len * width];
                    matmul(
                        MatMut::from_column_major_slice_mut(q, 3 * len, width),
                        Accum::Replace,
                        w.chunk32(ci),
                        zz.as_ref(),
                        1.0,
                        Par::Seq,
                    );
                    let q = &*q;
                    // plane(col, a): column `col` of [Q₁ Q₂] for row `a`, over the chunk's candidates
                    let plane =
                        |col: usize, a: usize| &q[col * 3 * len + a * len..col * 3 * len + (a + 1) * len];
                    for (t, sign) in signs.iter().enumerate() {
                        let r: [[&[f32]; 3]; 3] =
                            std::array::from_fn(|a| std::array::from_fn(|j| plane(3 * t + j, a)));
                        add_outer_products(gch, &r, *sign, len);
                    }
                    chunk_best(gch, start, len, member, dets)
                },
            )
            .collect();
        self.best = parts.into_iter().fold(None, better);
        self.since_refactor += 1;
        true
    }

    fn maybe_refactor(&mut self) {
        if self.since_refactor >= self.refactor_every {
            // A well-conditioned design cannot become singular through exchanges that keep
            // ln det finite; if it did, keep the incremental state.
            let backup = (self.minv.clone(), self.log_det, self.g.clone(), self.best);
            if !self.refactor() {
                (self.minv, self.log_det, self.g, self.best) = backup;
            }
        }
    }

    /// Non-member with the largest gain `ln det(I + G_k)` (ties: lowest index).
    fn best_addition(&self) -> Option<(usize, f64)> {
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

    fn add(&mut self, k: usize) -> bool {
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
    fn exchange_until_converged(&mut self, cap: usize) -> usize {
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
    fn excursion(&mut self, depth: usize, up: bool) -> bool {
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

    fn sorted_design(&self) -> Vec<usize> {
        let mut d = self.design.clone();
        d.sort_unstable();
        d
    }
}

// ------------------------------------------------------------------------------------------
// drivers

fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seed of restart `r`.
pub fn restart_seed(seed: u64, restart: usize) -> u64 {
    splitmix64(seed ^ splitmix64(restart as u64))
}

/// `fixed` plus `count − fixed.len()` distinct random non-fixed candidates.
fn random_start(rng: &mut ChaCha8Rng, n_candidates: usize, count: usize, fixed: &[usize]) -> Vec<usize> {
    let mut is_fixed = vec![false; n_candidates];
    for &f in fixed {
        is_fixed[f] = true;
    }
    let mut pool: Vec<usize> = (0..n_candidates).filter(|k| !is_fixed[*k]).collect();
    let need = count - fixed.len();
    for i in 0..need {
        let j = rng.random_range(i..pool.len());
        pool.swap(i, j);
    }
    let mut design = fixed.to_vec();
    design.extend_from_slice(&pool[..need]);
    design
}

fn validate(c: &Candidates, o: &DetmaxOptions) -> Result<(), ObservabilityError> {
    let (n_cand, l) = (c.len(), c.parameter_count());
    if o.count > n_cand {
        return Err(ObservabilityError::TooFewCandidates { available: n_cand, requested: o.count });
    }
    if o.ridge <= 0.0 && 3 * o.count < l {
        return Err(ObservabilityError::InvalidInput(format!(
            "{} poses give {} equations for {l} parameters: choose at least {} poses",
            o.count,
            3 * o.count,
            l.div_ceil(3)
        )));
    }
    if o.count == 0 {
        return Err(ObservabilityError::InvalidInput("the design size must be at least 1".into()));
    }
    if o.restarts == 0 {
        return Err(ObservabilityError::InvalidInput("at least one restart is needed".into()));
    }
    if !(o.ridge >= 0.0 && o.ridge.is_finite()) {
        return Err(ObservabilityError::InvalidInput(format!(
            "ridge must be finite and ≥ 0, got {}",
            o.ridge
        )));
    }
    if o.fixed.len() > o.count {
        return Err(ObservabilityError::InvalidInput(format!(
            "{} fixed poses do not fit in a design of {}",
            o.fixed.len(),
            o.count
        )));
    }
    let mut seen = vec![false; n_cand];
    for &f in &o.fixed {
        if f >= n_cand {
            return Err(ObservabilityError::InvalidInput(format!(
                "fixed pose index {f} is out of range (there are {n_cand} candidates)"
            )));
        }
        if std::mem::replace(&mut seen[f], true) {
            return Err(ObservabilityError::InvalidInput(format!("fixed pose index {f} is listed twice")));
        }
    }
    Ok(())
}

/// Refuses a candidate set whose information matrix is singular, naming the parameters
/// through the identifiability analysis.
fn check_candidate_rank(c: &Candidates) -> Result<(), ObservabilityError> {
    let total = c.total_information();
    let l = c.parameter_count();
    let d: Vec<f64> = (0..l).map(|j| total[(j, j)]).collect();
    let normalized = Mat::from_fn(l, l, |r, col| {
        let s = (d[r] * d[col]).sqrt();
        if s > 0.0 { total[(r, col)] / s } else { 0.0 }
    });
    if d.iter().all(|x| *x > 0.0) && factor(&normalized).is_some() {
        return Ok(());
    }
    let report = analyze_jacobian(c.stacked(), c.params(), &AnalysisOptions::default())?;
    if report.is_full_rank() {
        return Ok(());
    }
    Err(match rank_deficient_error(&report) {
        ObservabilityError::RankDeficient { rank, needed, unidentifiable, message } => {
            ObservabilityError::RankDeficient {
                rank,
                needed,
                unidentifiable,
                message: format!("the candidate set is rank-deficient: {message}"),
            }
        }
        other => other,
    })
}

/// Greedy (Dykstra) design: from `fixed` and a tiny ridge, add the best candidate until
/// `count`; then rebuild with the requested ridge. None if the result is singular.
fn greedy_state<'a>(w: &'a Work<'a>, o: &DetmaxOptions, fixed_mask: &[bool]) -> Option<State<'a>> {
    let n = w.len().max(1) as f64;
    let greedy_ridge: Vec<f64> =
        (0..w.l()).map(|j| w.ridge.get(j).copied().unwrap_or(0.0).max(GREEDY_RIDGE / n)).collect();
    let mut s = State::new(w, o.fixed.clone(), fixed_mask, greedy_ridge, o.refactor_every)?;
    while s.design.len() < o.count {
        let (k, _) = s.best_addition()?;
        if !s.add(k) {
            return None;
        }
    }
    s.ridge = w.ridge.clone();
    s.refactor().then_some(s)
}

fn exact_objective_value(c: &Candidates, design: &[usize], objective: Objective) -> f64 {
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
fn refine_exact(s: &mut State<'_>, c: &Candidates, o: &DetmaxOptions) -> usize {
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

/// ln det(M + R) in natural units of a design, from scratch.
fn natural_log_det(w: &Work<'_>, design: &[usize]) -> f64 {
    factor(&with_ridge(w.information(design), &w.ridge)).map_or(f64::NEG_INFINITY, |f| f.1 - w.log_scale)
}

fn run_restart<'a>(
    c: &Candidates,
    w: &'a Work<'a>,
    o: &DetmaxOptions,
    r: usize,
) -> Result<(State<'a>, RestartOutcome), ObservabilityError> {
    let seed = restart_seed(o.seed, r);
    let mut fixed_mask = vec![false; c.len()];
    for &f in &o.fixed {
        fixed_mask[f] = true;
    }
    let mut greedy_start = o.init == Initialisation::Greedy;
    let mut state = if greedy_start {
        None
    } else {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let start = random_start(&mut rng, c.len(), o.count, &o.fixed);
        State::new(w, start, &fixed_mask, w.ridge.clone(), o.refactor_every)
    };
    if state.is_none() {
        // A singular start: first make sure the candidate set itself is not rank-deficient
        // (a clear error naming the parameters), then start greedily.
        if o.ridge == 0.0 {
            check_candidate_rank(c)?;
        }
        greedy_start = true;
        state = greedy_state(w, o, &fixed_mask);
    }
    let mut s = state.ok_or_else(|| {
        ObservabilityError::InvalidInput(format!(
            "no non-singular design of {} poses found (greedy start failed); the candidates cannot identify the {} parameters together",
            o.count,
            c.parameter_count()
        ))
    })?;
    let mut exchanges = s.exchange_until_converged(o.max_exchanges);
    let mut excursions_accepted = 0;
    if let Some(max_depth) = o.excursions {
        let mut depth = 1;
        while depth <= max_depth && exchanges < o.max_exchanges {
            let mut improved = false;
            for up in [true, false] {
                let snapshot = s.clone();
                if s.excursion(depth, up) && s.log_det > snapshot.log_det + MIN_IMPROVEMENT {
                    exchanges += 2 * depth + s.exchange_until_converged(o.max_exchanges - exchanges);
                    excursions_accepted += 1;
                    improved = true;
                    break;
                }
                s = snapshot;
            }
            depth = if improved { 1 } else { depth + 1 };
        }
    }
    if o.objective != Objective::O1 {
        exchanges += refine_exact(&mut s, c, o);
    }
    let design = s.sorted_design();
    let log_det = natural_log_det(w, &design);
    let objective_value = match o.objective {
        Objective::O1 => o1_from_log_det(log_det, c.parameter_count(), design.len()),
        other => exact_objective_value(c, &design, other),
    };
    Ok((s, RestartOutcome { seed, log_det, objective_value, exchanges, excursions_accepted, greedy_start }))
}

/// A finished restart: sorted design, tracked natural ln det, summary.
type RestartRun = (Vec<usize>, f64, RestartOutcome);

/// Detmax selection of `options.count` candidates (module docs).
///
/// # Examples
/// 40 of 240 candidate probe poses for the paper's 34 parameters; the selection beats the first
/// 40 candidates (a random design) on the criterion:
/// ```
/// use vatcal_core::{CellFile, ParamSet};
/// use vatcal_kinematics::Model;
/// use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax, log_det};
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// let poses = vatcal_sim::truth::probe_start_poses(&model, 240, 1);
/// let candidates = Candidates::from_measurements(&model, &poses, &ParamSet::paper34())?;
/// let selection = detmax(&candidates, &DetmaxOptions { restarts: 2, seed: 7, ..DetmaxOptions::new(40) })?;
/// assert_eq!(selection.selected.len(), 40);
/// let random: Vec<usize> = (0..40).collect();
/// let random_log_det = log_det(&candidates, &random, 0.0).ok_or("singular random design")?;
/// assert!(selection.log_det > random_log_det);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`ObservabilityError::TooFewCandidates`] (fewer candidates than `options.count`);
/// [`ObservabilityError::InvalidInput`] for invalid options (no restart, a design size of 0,
/// fixed indices out of range or repeated, more fixed poses than the design size);
/// [`ObservabilityError::RankDeficient`] when even all candidates together cannot identify the
/// parameters (naming them); [`ObservabilityError::Numerical`] for a failed factorisation.
pub fn detmax(candidates: &Candidates, options: &DetmaxOptions) -> Result<Selection, ObservabilityError> {
    validate(candidates, options)?;
    let work = Work::new(candidates, options.ridge);
    let runs: Vec<Result<RestartRun, ObservabilityError>> = (0..options.restarts)
        .into_par_iter()
        .map(|r| {
            run_restart(candidates, &work, options, r)
                .map(|(s, out)| (s.sorted_design(), s.log_det - work.log_scale, out))
        })
        .collect();
    let mut best: Option<(usize, Vec<usize>, f64)> = None;
    let mut restarts: Vec<RestartOutcome> = Vec::with_capacity(runs.len());
    for (r, run) in runs.into_iter().enumerate() {
        let (design, tracked, outcome) = run?;
        let better = best.as_ref().is_none_or(|(b, _, _)| {
            outcome.objective_value.total_cmp(&restarts[*b].objective_value) == Ordering::Greater
        });
        if better {
            best = Some((r, design, tracked));
        }
        restarts.push(outcome);
    }
    let (best_restart, selected, tracked_log_det) =
        best.ok_or_else(|| ObservabilityError::InvalidInput("no restart ran".into()))?;
    let won = &restarts[best_restart];
    Ok(Selection {
        selected,
        log_det: won.log_det,
        tracked_log_det,
        objective_value: won.objective_value,
        best_restart,
        restarts,
    })
}

/// Greedy sequential D-optimal design (Dykstra): from `fixed` (and a tiny ridge while the
/// design is singular), add the candidate with the largest gain `count` times. No exchanges.
pub fn greedy(candidates: &Candidates, options: &DetmaxOptions) -> Result<Selection, ObservabilityError> {
    validate(candidates, options)?;
    let work = Work::new(candidates, options.ridge);
    let mut fixed_mask = vec![false; candidates.len()];
    for &f in &options.fixed {
        fixed_mask[f] = true;
    }
    let s = greedy_state(&work, options, &fixed_mask)
        .ok_or_else(|| ObservabilityError::InvalidInput("the greedy design is singular".into()))?;
    let selected = s.sorted_design();
    let log_det = natural_log_det(&work, &selected);
    let objective_value = o1_from_log_det(log_det, candidates.parameter_count(), selected.len());
    Ok(Selection {
        selected,
        log_det,
        tracked_log_det: s.log_det - work.log_scale,
        objective_value,
        best_restart: 0,
        restarts: vec![RestartOutcome {
            seed: 0,
            log_det,
            objective_value,
            exchanges: 0,
            excursions_accepted: 0,
            greedy_start: true,
        }],
    })
}

// ------------------------------------------------------------------------------------------
// naive reference

/// `ln det(JᵀJ) = 2 Σ ln σ_i` of the stacked design Jacobian, from its SVD.
pub fn log_det_by_svd(candidates: &Candidates, design: &[usize]) -> f64 {
    let j = candidates.design_jacobian(design);
    match j.singular_values() {
        Ok(s) if s.len() == candidates.parameter_count() => s.iter().map(|x| 2.0 * x.ln()).sum(),
        _ => f64::NEG_INFINITY,
    }
}

/// The plain exchange of [`detmax`] (O1, random starts, same seeds, same tie-breaking and
/// stopping rule, no excursions, no fixed poses) with every gain and loss computed from
/// scratch by an SVD of the trial design. O(N) SVDs per step: a reference, not a tool.
pub fn naive_detmax(
    candidates: &Candidates,
    options: &DetmaxOptions,
) -> Result<Selection, ObservabilityError> {
    validate(candidates, options)?;
    let mut best: Option<(usize, Vec<usize>, f64)> = None;
    let mut restarts = Vec::new();
    for r in 0..options.restarts {
        let seed = restart_seed(options.seed, r);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut design = random_start(&mut rng, candidates.len(), options.count, &options.fixed);
        let mut current = log_det_by_svd(candidates, &design);
        if !current.is_finite() {
            return Err(ObservabilityError::InvalidInput(
                "naive reference: the random start is singular".into(),
            ));
        }
        let mut exchanges = 0;
        while exchanges < options.max_exchanges {
            let mut member = vec![false; candidates.len()];
            for &k in &design {
                member[k] = true;
            }
            let mut add: Option<(usize, f64)> = None;
            for k in (0..candidates.len()).filter(|k| !member[*k]) {
                design.push(k);
                let v = log_det_by_svd(candidates, &design);
                design.pop();
                if add.is_none_or(|(_, b)| v > b) {
                    add = Some((k, v));
                }
            }
            let Some((k_in, with_in)) = add else { break };
            design.push(k_in);
            let loss_in = with_in - current;
            let mut members: Vec<usize> = design[..design.len() - 1].to_vec();
            members.sort_unstable();
            let mut out: Option<(usize, f64)> = None;
            for k in members {
                let trial: Vec<usize> = design.iter().copied().filter(|x| *x != k).collect();
                let loss = with_in - log_det_by_svd(candidates, &trial);
                if out.is_none_or(|(_, b)| loss < b) {
                    out = Some((k, loss));
                }
            }
            match out {
                Some((k_out, loss_out))
                    if loss_out < loss_in && with_in - loss_out - current > MIN_IMPROVEMENT =>
                {
                    design.retain(|x| *x != k_out);
                    current = with_in - loss_out;
                    exchanges += 1;
                }
                _ => {
                    design.pop();
                    break;
                }
            }
        }
        design.sort_unstable();
        let log_det = log_det_by_svd(candidates, &design);
        let objective_value = o1_from_log_det(log_det, candidates.parameter_count(), design.len());
        if best.as_ref().is_none_or(|(b, _, _)| {
            let bo: &RestartOutcome = &restarts[*b];
            objective_value > bo.objective_value
        }) {
            best = Some((r, design, current));
        }
        restarts.push(RestartOutcome {
            seed,
            log_det,
            objective_value,
            exchanges,
            excursions_accepted: 0,
            greedy_start: false,
        });
    }
    let (best_restart, selected, tracked_log_det) =
        best.ok_or_else(|| ObservabilityError::InvalidInput("no restart ran".into()))?;
    let won = &restarts[best_restart];
    Ok(Selection {
        selected,
        log_det: won.log_det,
        tracked_log_det,
        objective_value: won.objective_value,
        best_restart,
        restarts,
    })
}

// ------------------------------------------------------------------------------------------
// reporting helpers

/// The indices of a selection, in the two conventions of background.md §3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectionIndices {
    /// natural units (mm per parameter unit): the O1 to compare with the paper
    pub raw: ObservabilityIndices,
    /// columns divided by their norms over the **whole candidate set** (so designs stay
    /// comparable): the O2..O5, condition number and σ_min to read
    pub normalized: ObservabilityIndices,
}

/// O1..O5, rank, condition number and σ_min of `selected` (raw and candidate-normalised).
pub fn selection_indices(
    candidates: &Candidates,
    selected: &[usize],
) -> Result<SelectionIndices, ObservabilityError> {
    let j = candidates.design_jacobian(selected);
    let raw = crate::indices::observability_indices(j.as_ref(), candidates.params(), ColumnScaling::None)?;
    let factors: Vec<f64> =
        column_norms(candidates).iter().map(|x| if *x > 0.0 { 1.0 / x } else { 1.0 }).collect();
    let mut jn = j;
    crate::identifiability::scale_columns(&mut jn, &factors);
    let mut normalized =
        crate::indices::observability_indices(jn.as_ref(), candidates.params(), ColumnScaling::None)?;
    normalized.scaling = ColumnScaling::UnitNorm;
    Ok(SelectionIndices { raw, normalized })
}

/// One row of [`position_ablation`].
#[derive(Debug, Clone, PartialEq)]
pub struct AblationRow {
    /// the calibration positions the candidates were restricted to
    pub positions: Vec<u32>,
    /// number of candidates at those positions
    pub candidate_count: usize,
    /// the selection (indices into the **full** candidate list, ascending), None when there
    /// were fewer candidates than poses requested
    pub selected: Option<Vec<usize>>,
    /// its indices (None when no selection)
    pub indices: Option<SelectionIndices>,
}

/// The paper's ablation: the best Detmax selection of `options.count` poses when the
/// candidates are restricted to every subset of `subset_size` calibration positions.
/// `positions[k]` is candidate k's calibration position (None for tracker rows, which are
/// never used here). With fewer than three positions the world frame is not identifiable, so
/// the restricted selections use a ridge (`max(options.ridge, 1e-6)`); their indices are
/// computed without it, and their rank shows what is lost.
pub fn position_ablation(
    candidates: &Candidates,
    positions: &[Option<u32>],
    subset_size: usize,
    options: &DetmaxOptions,
) -> Result<Vec<AblationRow>, ObservabilityError> {
    if positions.len() != candidates.len() {
        return Err(ObservabilityError::InvalidInput(format!(
            "{} position labels for {} candidates",
            positions.len(),
            candidates.len()
        )));
    }
    let mut ids: Vec<u32> = positions.iter().flatten().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let mut rows = Vec::new();
    for subset in subsets(&ids, subset_size) {
        let members: Vec<usize> =
            (0..candidates.len()).filter(|k| positions[*k].is_some_and(|p| subset.contains(&p))).collect();
        let mut row =
            AblationRow { positions: subset, candidate_count: members.len(), selected: None, indices: None };
        if members.len() >= options.count {
            let restricted = candidates.subset(&members);
            let o = DetmaxOptions { ridge: options.ridge.max(1e-6), fixed: Vec::new(), ..options.clone() };
            let s = detmax(&restricted, &o)?;
            let selected: Vec<usize> = s.selected.iter().map(|i| members[*i]).collect();
            row.indices = Some(selection_indices(candidates, &selected)?);
            row.selected = Some(selected);
        }
        rows.push(row);
    }
    Ok(rows)
}

/// All `k`-element subsets of `ids`, in lexicographic order.
fn subsets(ids: &[u32], k: usize) -> Vec<Vec<u32>> {
    if k == 0 {
        return vec![Vec::new()];
    }
    let mut out = Vec::new();
    for (i, id) in ids.iter().enumerate() {
        for mut rest in subsets(&ids[i + 1..], k - 1) {
            rest.insert(0, *id);
            out.push(rest);
        }
    }
    out
}
