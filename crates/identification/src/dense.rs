//! A small dense Householder QR with preallocated storage, so the iteration loop does not
//! allocate.
//!
//! The matrices of a fit are small (e.g. 120 × 34, and the 68 × 34 damped-step problem), where
//! faer's blocked QR spends most of its time in set-up and in its overflow-safe column norms.
//! This is the unblocked Householder QR of LAPACK's `dgeqr2` (`H_k = I − τ_k v_k v_kᵀ`,
//! `v_k[k] = 1`, `R_kk = −sign(α)‖x‖`), on contiguous faer columns, with the dot products
//! summed in four fixed lanes. The result does not depend on the CPU: no fused multiply–add,
//! the same order of operations on every target (the AVX2 build of the same code only widens
//! the lanes).

use faer::linalg::triangular_solve;
use faer::{Mat, MatRef, Par};

/// An m × n (m ≥ n) least-squares matrix `a` with a right-hand side `rhs`, factored in place
/// as `a = Q R`; after [`DenseQr::factor_and_apply`], `rhs` holds `Qᵀ rhs`.
pub(crate) struct DenseQr {
    /// the matrix; after factoring: R in the upper triangle, Householder vectors below
    pub a: Mat<f64>,
    /// right-hand side (m × 1); after factoring: `Qᵀ rhs`
    pub rhs: Mat<f64>,
    /// `τ_k` of the reflectors
    tau: Vec<f64>,
    /// scratch: the current reflector below its leading 1
    v: Vec<f64>,
}

impl std::fmt::Debug for DenseQr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DenseQr").field("nrows", &self.a.nrows()).field("ncols", &self.a.ncols()).finish()
    }
}

impl DenseQr {
    /// Workspace for an `m × n` problem.
    pub fn new(m: usize, n: usize) -> Self {
        Self { a: Mat::zeros(m, n), rhs: Mat::zeros(m, 1), tau: vec![0.0; m.min(n)], v: vec![0.0; m] }
    }

    /// Number of columns.
    pub fn ncols(&self) -> usize {
        self.a.ncols()
    }

    /// Factors `a` in place and applies `Qᵀ` to `rhs`.
    pub fn factor_and_apply(&mut self) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { householder_qr_avx2(&mut self.a, &mut self.rhs, &mut self.tau, &mut self.v) };
            return;
        }
        householder_qr(&mut self.a, &mut self.rhs, &mut self.tau, &mut self.v);
    }

    /// The n × n factor R (upper triangle of the top block; the strictly lower part of the view
    /// holds Householder data and must be ignored).
    pub fn r_view(&self) -> MatRef<'_, f64> {
        let n = self.ncols();
        self.a.as_ref().get(..n, ..n)
    }

    /// R as an owned upper-triangular matrix (lower part zeroed).
    pub fn r_owned(&self) -> Mat<f64> {
        let n = self.ncols();
        Mat::from_fn(n, n, |i, j| if i <= j { self.a[(i, j)] } else { 0.0 })
    }

    /// Solves `R x = (Qᵀ rhs)[..n]` in place; the solution is `rhs[..n]`.
    pub fn solve_in_place(&mut self) {
        let n = self.ncols();
        triangular_solve::solve_upper_triangular_in_place(
            self.a.as_ref().get(..n, ..n),
            self.rhs.as_mut().get_mut(..n, ..),
            Par::Seq,
        );
    }
}

/// [`householder_qr`] compiled for AVX2 (the same operations, wider lanes).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn householder_qr_avx2(a: &mut Mat<f64>, rhs: &mut Mat<f64>, tau: &mut [f64], v: &mut [f64]) {
    householder_qr(a, rhs, tau, v);
}

/// `Σ x_i y_i`, summed in four fixed lanes (vectorisable, deterministic order).
#[inline(always)]
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (xc, yc) = (x.chunks_exact(4), y.chunks_exact(4));
    let (xr, yr) = (xc.remainder(), yc.remainder());
    for (a, b) in xc.zip(yc) {
        for l in 0..4 {
            acc[l] += a[l] * b[l];
        }
    }
    let mut rest = 0.0;
    for (a, b) in xr.iter().zip(yr) {
        rest += a * b;
    }
    ((acc[0] + acc[2]) + (acc[1] + acc[3])) + rest
}

/// `y ← y − w x`.
#[inline(always)]
fn sub_scaled(y: &mut [f64], w: f64, x: &[f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi -= w * xi;
    }
}

/// Applies `H = I − τ v vᵀ` (`v[0] = 1` implied, `v_tail` = the rest) to `y` (rows k..m).
#[inline(always)]
fn reflect(y: &mut [f64], v_tail: &[f64], tau: f64) {
    let Some((head, tail)) = y.split_first_mut() else { return };
    let w = tau * (*head + dot(v_tail, tail));
    *head -= w;
    sub_scaled(tail, w, v_tail);
}

/// `‖x‖₂`, overflow- and underflow-safe only where it matters (the plain sum of squares is used
/// whenever it is in the normal range).
#[inline(always)]
pub(crate) fn norm(x: &[f64]) -> f64 {
    let s = dot(x, x);
    if s.is_finite() && s > f64::MIN_POSITIVE / f64::EPSILON {
        return s.sqrt();
    }
    let big = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if big == 0.0 || !big.is_finite() {
        return if big.is_nan() { f64::NAN } else { big };
    }
    big * x.iter().map(|v| (v / big) * (v / big)).sum::<f64>().sqrt()
}

/// Unblocked Householder QR of `a` (m × n, m ≥ n) in place (LAPACK `dgeqr2` conventions),
/// applying `Qᵀ` to `rhs` (m × 1). `tau` holds min(m, n) values, `v` m values of scratch.
#[inline(always)]
fn householder_qr(a: &mut Mat<f64>, rhs: &mut Mat<f64>, tau: &mut [f64], v: &mut [f64]) {
    let (m, n) = (a.nrows(), a.ncols());
    for k in 0..m.min(n) {
        let col = &mut a.col_as_slice_mut(k)[k..m];
        let alpha = col[0];
        let tail_norm = norm(&col[1..]);
        if tail_norm == 0.0 {
            tau[k] = 0.0; // H = I
            continue;
        }
        let x_norm = alpha.hypot(tail_norm);
        let beta = if alpha >= 0.0 { -x_norm } else { x_norm };
        tau[k] = (beta - alpha) / beta;
        let scale = 1.0 / (alpha - beta);
        for x in &mut col[1..] {
            *x *= scale;
        }
        col[0] = beta;
        // the reflector, copied so that the other columns can be borrowed mutably
        let v_tail = &mut v[..m - k - 1];
        v_tail.copy_from_slice(&col[1..]);
        for j in k + 1..n {
            reflect(&mut a.col_as_slice_mut(j)[k..m], v_tail, tau[k]);
        }
        reflect(&mut rhs.col_as_slice_mut(0)[k..m], v_tail, tau[k]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_recovers_a_known_solution() {
        let (m, n) = (12, 4);
        let mut qr = DenseQr::new(m, n);
        let x_true = [1.0, -2.0, 0.5, 3.0];
        for i in 0..m {
            let mut b = 0.0;
            for (j, x) in x_true.iter().enumerate() {
                let v = ((i * 7 + j * 3) % 11) as f64 - 5.0 + if i == j { 10.0 } else { 0.0 };
                qr.a[(i, j)] = v;
                b += v * x;
            }
            qr.rhs[(i, 0)] = b;
        }
        qr.factor_and_apply();
        qr.solve_in_place();
        for (j, x) in x_true.iter().enumerate() {
            assert!((qr.rhs[(j, 0)] - x).abs() < 1e-12, "{j}: {}", qr.rhs[(j, 0)]);
        }
    }

    fn filled(m: usize, n: usize, seed: u64) -> DenseQr {
        let mut qr = DenseQr::new(m, n);
        let mut state = seed;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for j in 0..n {
            for i in 0..m {
                qr.a[(i, j)] = next() * 10f64.powi(j as i32 % 5 - 2);
            }
        }
        for i in 0..m {
            qr.rhs[(i, 0)] = next();
        }
        qr
    }

    /// `RᵀR = AᵀA`, `‖Qᵀb‖ = ‖b‖`, `(Rᵀ(Qᵀb))_j = (Aᵀb)_j`, and `R` matches faer's QR up to the
    /// signs of its rows (above the zero column), on a matrix with a zero column (no reflection) and mixed scales.
    #[test]
    fn factors_match_the_normal_equations_and_faer() {
        let (m, n) = (23, 7);
        let mut qr = filled(m, n, 3);
        for i in 0..m {
            qr.a[(i, 4)] = 0.0;
        }
        let a0 = qr.a.clone();
        let b0 = qr.rhs.clone();
        qr.factor_and_apply();
        let r = qr.r_owned();
        let ata = a0.transpose() * &a0;
        let rtr = r.transpose() * &r;
        let atb = a0.transpose() * &b0;
        let rtqb = r.transpose() * qr.rhs.as_ref().get(..n, ..);
        for i in 0..n {
            for j in 0..n {
                let tol = 1e-12 * (ata[(i, i)] * ata[(j, j)]).sqrt().max(1e-300);
                assert!((ata[(i, j)] - rtr[(i, j)]).abs() <= tol, "({i}, {j})");
            }
            assert!(
                (atb[(i, 0)] - rtqb[(i, 0)]).abs() <= 1e-12 * ata[(i, i)].sqrt().max(1e-300) * b0.norm_l2()
            );
        }
        assert!((qr.rhs.norm_l2() - b0.norm_l2()).abs() <= 1e-13 * b0.norm_l2());
        // rows from the zero column on are not unique (rank-deficient): compare the rows above
        let faer_r = a0.qr().thin_R().to_owned();
        for i in 0..4 {
            let sign = if (faer_r[(i, i)] >= 0.0) == (r[(i, i)] >= 0.0) { 1.0 } else { -1.0 };
            for j in i..n {
                let tol = 1e-12 * r.col(j).norm_l2().max(1e-300);
                assert!((faer_r[(i, j)] - sign * r[(i, j)]).abs() <= tol, "R({i}, {j})");
            }
        }
    }

    /// The AVX2 build of the kernel gives bit-identical factors (no CPU-dependent results).
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn avx2_build_is_bit_identical() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut fast = filled(41, 13, 11);
        let mut plain = filled(41, 13, 11);
        fast.factor_and_apply();
        householder_qr(&mut plain.a, &mut plain.rhs, &mut plain.tau, &mut plain.v);
        for j in 0..13 {
            for i in 0..41 {
                assert_eq!(fast.a[(i, j)].to_bits(), plain.a[(i, j)].to_bits(), "({i}, {j})");
            }
        }
        for i in 0..41 {
            assert_eq!(fast.rhs[(i, 0)].to_bits(), plain.rhs[(i, 0)].to_bits());
        }
    }

    #[test]
    fn norm_is_safe_at_the_extremes() {
        assert_eq!(norm(&[3.0, 4.0]), 5.0);
        assert!((norm(&[3e200, 4e200]) / 5e200 - 1.0).abs() < 1e-15);
        assert!((norm(&[3e-200, 4e-200]) / 5e-200 - 1.0).abs() < 1e-15);
        assert_eq!(norm(&[0.0, 0.0]), 0.0);
        assert!(norm(&[f64::NAN, 1.0]).is_nan());
    }
}
