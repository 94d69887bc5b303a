//! Shared helpers for the vatcal benchmarks (nothing public yet).
