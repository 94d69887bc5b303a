//! The bookkeeping of the exchange: the normalised working copy of the candidates ([`Work`]),
//! the small 3 × 3 and factorisation helpers, and the exchange state ([`State`]) that keeps
//! `M⁻¹`, `ln det M` and every candidate's `G_k` up to date through rank-3 updates (module
//! docs of `detmax`, "Fast path").

use std::cmp::Ordering;

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::DenseSolveCore;
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};
use nalgebra::Matrix3;
use rayon::prelude::*;

use super::candidates::{CHUNK, Candidates};

/// A Cholesky pivot `L_ii²` below this fraction of `M_ii` counts as singular.
const PIVOT_FRACTION: f64 = 1e-13;

type Sym3 = [f64; 6];

pub(super) fn sym_of(m: &Matrix3<f64>) -> Sym3 {
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
pub(super) fn gain_of(g: &Sym3) -> f64 {
    let d = det_i_plus(g, 1.0);
    if d > 0.0 { d.ln() } else { f64::NEG_INFINITY }
}

/// `−ln det(I − G)` (∞ when removing makes M singular)
pub(super) fn loss_of(g: &Sym3) -> f64 {
    let d = det_i_plus(g, -1.0);
    if d > 0.0 { -d.ln() } else { f64::INFINITY }
}

/// Euclidean norm of every column over all candidates.
pub(super) fn column_norms(c: &Candidates) -> Vec<f64> {
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
pub(super) fn ridge_diagonal(c: &Candidates, ridge: f64) -> Vec<f64> {
    if ridge <= 0.0 {
        return Vec::new();
    }
    let n = c.len().max(1) as f64;
    column_norms(c).into_iter().map(|x| ridge * x * x / n).collect()
}

pub(super) fn with_ridge(mut m: Mat<f64>, r: &[f64]) -> Mat<f64> {
    for (j, v) in r.iter().enumerate() {
        m[(j, j)] += v;
    }
    m
}

/// `(M⁻¹, ln det M)`, or None if M is (numerically) singular.
pub(super) fn factor(m: &Mat<f64>) -> Option<(Mat<f64>, f64)> {
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
pub(super) fn is_above(a: f64, b: f64) -> bool {
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

/// The candidates as the exchange sees them (module docs, "Numerics"): the caller's blocks
/// with column factors `1/‖col_j‖`, plus an f32 copy of the normalised blocks for the bulk
/// passes, stored per chunk of [`CHUNK`] candidates, column-major, in *planar* row order (all
/// x rows of the chunk, then all y rows, then all z rows), so that every product with it
/// yields, for each (row, column), a contiguous vector over the chunk's candidates and the
/// 3 × 3 updates vectorise across candidates.
pub(super) struct Work<'a> {
    /// the caller's candidates (natural units)
    orig: &'a Candidates,
    /// column factors `1/‖col_j‖` (1 for an all-zero column)
    pub(super) factors: Vec<f64>,
    rows32: Vec<f32>,
    /// `2 Σ ln(1/‖col_j‖)`: ln det of the normalised M = natural ln det + this
    pub(super) log_scale: f64,
    /// ridge on the normalised columns (`ridge / N`, 0 for an all-zero column)
    pub(super) ridge: Vec<f64>,
}

/// `(start, len)` of chunk `ci` of `n` candidates.
fn chunk_range(ci: usize, n: usize) -> (usize, usize) {
    let start = ci * CHUNK;
    (start, CHUNK.min(n - start))
}

impl<'a> Work<'a> {
    pub(super) fn new(orig: &'a Candidates, ridge: f64) -> Self {
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

    pub(super) fn len(&self) -> usize {
        self.orig.len()
    }

    pub(super) fn l(&self) -> usize {
        self.orig.l
    }

    /// Normalised row `a` of candidate `k`, element `j`.
    pub(super) fn at(&self, k: usize, a: usize, j: usize) -> f64 {
        self.orig.row(k, a)[j] * self.factors[j]
    }

    /// Normalised information matrix `D (Σ_design B_kᵀB_k) D`.
    pub(super) fn information(&self, design: &[usize]) -> Mat<f64> {
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

/// One rank-3 term `sign · Z C Zᵀ` of an inverse update.
pub(super) struct Term {
    pub(super) z: Mat<f64>,
    pub(super) c: Matrix3<f64>,
    pub(super) sign: f64,
}

#[derive(Clone)]
pub(super) struct State<'a> {
    pub(super) w: &'a Work<'a>,
    pub(super) ridge: Vec<f64>,
    pub(super) design: Vec<usize>,
    pub(super) member: Vec<bool>,
    pub(super) fixed: Vec<bool>,
    minv: Mat<f64>,
    pub(super) log_det: f64,
    /// `G_k` of all candidates, per chunk six planes (g₀..g₅ of [`SYM`]) over its candidates
    pub(super) g: Vec<f64>,
    /// best non-member `(k, det(I + G_k))`, refreshed by every pass over `g`
    pub(super) best: Option<(usize, f64)>,
    since_refactor: usize,
    pub(super) refactor_every: usize,
}

/// Keeps the larger `det(I + G)`; ties keep the lower index.
pub(super) fn better(a: Option<(usize, f64)>, b: Option<(usize, f64)>) -> Option<(usize, f64)> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if y.1 > x.1 || (y.1 == x.1 && y.0 < x.0) { y } else { x }),
        (x, None) => x,
        (None, y) => y,
    }
}

impl<'a> State<'a> {
    /// Builds the state of `design` with the ridge `ridge` (normalised units); None if
    /// singular.
    pub(super) fn new(
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
    pub(super) fn refactor(&mut self) -> bool {
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
    pub(super) fn g_of(&self, k: usize) -> Sym3 {
        let ci = k / CHUNK;
        let (start, len) = chunk_range(ci, self.w.len());
        let base = 6 * start + (k - start);
        std::array::from_fn(|e| self.g[base + e * len])
    }

    /// `M⁻¹ bᵀ` (L × 3) for candidate k (f64).
    pub(super) fn z_of(&self, k: usize) -> Mat<f64> {
        let bt = Mat::from_fn(self.w.l(), 3, |j, a| self.w.at(k, a, j));
        let mut z = Mat::<f64>::zeros(self.w.l(), 3);
        matmul(z.as_mut(), Accum::Replace, self.minv.as_ref(), bt.as_ref(), 1.0, Par::Seq);
        z
    }

    /// `B_k Z` (3 × 3, f64).
    pub(super) fn bz(&self, k: usize, z: &Mat<f64>) -> Matrix3<f64> {
        Matrix3::from_fn(|a, b| {
            let row = self.w.orig.row(k, a);
            (0..row.len()).map(|j| row[j] * self.w.factors[j] * z[(j, b)]).sum()
        })
    }

    /// Exact `G_k = B_k M⁻¹ B_kᵀ` (f64), for the members whose losses decide removals.
    pub(super) fn exact_g(&self, k: usize) -> Matrix3<f64> {
        self.bz(k, &self.z_of(k))
    }

    /// Applies `M⁻¹ += Σ sign Z C Zᵀ` and the matching `G_k` update for all candidates, and
    /// refreshes the best non-member. With `C_t = L_t L_tᵀ` (3 × 3 Cholesky; C is positive
    /// definite for additions and for removals that keep M non-singular) the update is
    /// `G_k += Σ_t sign_t Q_t Q_tᵀ`, `Q_t = B_k Z_t L_t`. One pass over the candidates: per
    /// chunk a single f32 faer matmul `[Q₁ Q₂] = B_ch [Z₁L₁ Z₂L₂]`, then 18 multiply-adds per
    /// term and candidate, vectorised across the chunk's candidates. Member flags must already
    /// describe the new design. False (nothing changed) if a C_t is not positive definite.
    pub(super) fn apply(&mut self, terms: &[Term]) -> bool {
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

    pub(super) fn maybe_refactor(&mut self) {
        if self.since_refactor >= self.refactor_every {
            // A well-conditioned design cannot become singular through exchanges that keep
            // ln det finite; if it did, keep the incremental state.
            let backup = (self.minv.clone(), self.log_det, self.g.clone(), self.best);
            if !self.refactor() {
                (self.minv, self.log_det, self.g, self.best) = backup;
            }
        }
    }
}
