//! The candidate pool: every candidate pose as a 3 × L Jacobian block, and the check that
//! the pool as a whole can identify the parameters.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;
use vatcal_core::{Measurement, ParamSet};
use vatcal_kinematics::Model;

use crate::error::ObservabilityError;
use crate::identifiability::{measurement_block, reindex};

/// Measurements per parallel task when the candidate Jacobians are evaluated.
/// Candidates per chunk of the batched updates. Fixed, so results do not depend on the
/// number of threads.
pub(super) const CHUNK: usize = 1024;
const JACOBIAN_CHUNK: usize = 256;

/// The candidate poses as stacked 3 × L Jacobian blocks (candidate k = rows `3k..3k+3`),
/// stored row-major so that each candidate's block is contiguous.
#[derive(Debug, Clone)]
pub struct Candidates {
    /// row-major 3N × L
    pub(super) rows: Vec<f64>,
    pub(super) l: usize,
    pub(super) params: ParamSet,
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

    /// The Jacobian blocks of probe/tracker measurements (the blocks of
    /// [`assemble_jacobian`](crate::identifiability::assemble_jacobian), bit for bit). Evaluated in parallel over fixed chunks of measurements, written straight
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
    pub(super) fn row(&self, k: usize, a: usize) -> &[f64] {
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
    pub(super) fn total_information(&self) -> Mat<f64> {
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
