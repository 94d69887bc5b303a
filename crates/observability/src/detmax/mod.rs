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
//!    [`ObservabilityError::RankDeficient`](crate::ObservabilityError::RankDeficient) naming the
//!    parameters; a non-singular start already proves full rank, so the common case skips this O(N L²) check), then start greedily:
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
//! # Prior information
//! [`detmax_with_prior`] selects with rows that are in every design (known distances between
//! fixed points or parallel planes, or any other prior information in the units of the
//! candidate blocks): they are packed into zero-padded 3-row pseudo-candidates, held fixed,
//! and stripped from the returned selection; the criterion it reports includes them.
//!
//! # Reference
//! [`naive_detmax`] runs the same exchange with every gain and loss computed from scratch from
//! the singular values of the stacked design Jacobian — for tests and the benchmark.

mod ablation;
mod bookkeeping;
mod candidates;
mod exchange;
mod options;
mod prior;
mod reference;
mod restarts;

pub use ablation::{AblationRow, SelectionIndices, position_ablation, selection_indices};
pub use candidates::Candidates;
pub use options::{
    DetmaxOptions, Initialisation, Objective, RestartOutcome, Selection, log_det, o1_from_log_det,
};
pub use prior::{detmax_with_prior, selection_indices_with_prior, with_prior_rows};
pub use reference::{log_det_by_svd, naive_detmax};
pub use restarts::{detmax, greedy, restart_seed};
