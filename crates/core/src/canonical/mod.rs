//! Knowledge of the canonical Meca500-on-guide cell kept in one place.

pub mod bounds;
