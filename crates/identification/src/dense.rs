//! Small wrappers over faer's in-place Householder QR with preallocated scratch, so the
//! iteration loop does not allocate.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::householder;
use faer::linalg::qr::no_pivoting::factor;
use faer::linalg::triangular_solve;
use faer::{Conj, Mat, MatRef, Par};

/// An m × n (m ≥ n) least-squares matrix `a` with a right-hand side `rhs`, factored in place
/// as `a = Q R`; after [`DenseQr::factor_and_apply`], `rhs` holds `Qᵀ rhs`.
pub(crate) struct DenseQr {
    /// the matrix; after factoring: R in the upper triangle, Householder vectors below
    pub a: Mat<f64>,
    /// right-hand side (m × 1); after factoring: `Qᵀ rhs`
    pub rhs: Mat<f64>,
    h: Mat<f64>,
    mem: MemBuffer,
}

impl std::fmt::Debug for DenseQr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DenseQr").field("nrows", &self.a.nrows()).field("ncols", &self.a.ncols()).finish()
    }
}

impl DenseQr {
    /// Workspace for an `m × n` problem.
    pub fn new(m: usize, n: usize) -> Self {
        let bs = factor::recommended_block_size::<f64>(m, n).max(1);
        let req = StackReq::any_of(&[
            factor::qr_in_place_scratch::<f64>(m, n, bs, Par::Seq, Default::default()),
            householder::apply_block_householder_sequence_transpose_on_the_left_in_place_scratch::<f64>(
                m, bs, 1,
            ),
        ]);
        Self {
            a: Mat::zeros(m, n),
            rhs: Mat::zeros(m, 1),
            h: Mat::zeros(bs, m.min(n)),
            mem: MemBuffer::new(req),
        }
    }

    /// Number of columns.
    pub fn ncols(&self) -> usize {
        self.a.ncols()
    }

    /// Factors `a` in place and applies `Qᵀ` to `rhs`.
    pub fn factor_and_apply(&mut self) {
        factor::qr_in_place(
            self.a.as_mut(),
            self.h.as_mut(),
            Par::Seq,
            MemStack::new(&mut self.mem),
            Default::default(),
        );
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
            self.a.as_ref(),
            self.h.as_ref(),
            Conj::No,
            self.rhs.as_mut(),
            Par::Seq,
            MemStack::new(&mut self.mem),
        );
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
}
