#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Which parameters a set of measurements can identify, how well, and which poses to measure.
//!
//! * [`identifiability`] — the stacked measurement Jacobian, its numerical rank, the
//!   identifiable basis chosen in a preference order, the redundant parameters with the
//!   parameters that absorb them, and the invisible parameter combinations
//!   (background.md §5);
//! * [`indices`] — the observability indices O1..O5, always reported together with rank,
//!   condition number and σ_min (background.md §3);
//! * [`sets`] — the robot-agnostic parameter sets (`registration` ⊂ `joint-offsets` ⊂
//!   `kinematic` ⊂ `kinematic+compliance`), unknown fixed points and known distances between
//!   them ([`sets::DataDesign`]), and the resolution of `--params` specifications;
//! * `detmax` (feature `detmax`, on by default; rayon and rand) — D-optimal selection of `n`
//!   poses out of `N` candidates with rank-3 determinant-lemma / Woodbury updates
//!   (background.md §4), plus a naive reference.
//!
//! Units inside: mm, rad, rad/(N·m). Jacobian columns are `d(FK − target)/dρ` in those units.

#[cfg(feature = "detmax")]
pub mod detmax;
mod error;
pub mod identifiability;
pub mod indices;
pub mod sets;

pub use error::ObservabilityError;
pub use identifiability::{
    ColumnScaling, IdentifiabilityReport, LostDirection, Redundancy, all_identifiable, analyze,
    assemble_jacobian, check_identifiable,
};
pub use indices::{ObservabilityIndices, observability_indices, observability_indices_for};
