//! O1..O5 against hand-computed values, the "power 1/m" bug, rank-deficient input and scaling.

use faer::Mat;
use proptest::prelude::*;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::{ParamId, ParamSet};
use vatcal_observability::ColumnScaling;
use vatcal_observability::indices::{ObservabilityIndices, observability_indices};

/// A seeded random matrix with entries in [-1, 1).
fn random(rows: usize, cols: usize, seed: u64) -> Mat<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Mat::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0))
}

fn params(l: usize) -> ParamSet {
    ParamSet(ParamSet::paper34().0.into_iter().take(l).collect::<Vec<ParamId>>())
}

/// 3m × L matrix with prescribed singular values: rows = diag(σ) embedded and rotated by a
/// Givens rotation on the rows (which leaves the singular values unchanged).
fn with_singular_values(sigma: &[f64], poses: usize) -> Mat<f64> {
    let (rows, l) = (3 * poses, sigma.len());
    assert!(rows >= l);
    let mut j = Mat::from_fn(rows, l, |r, c| if r == c { sigma[c] } else { 0.0 });
    let (s, c) = 0.3f64.sin_cos();
    for col in 0..l {
        for r in 0..rows - 1 {
            let (a, b) = (j[(r, col)], j[(r + 1, col)]);
            j[(r, col)] = c * a - s * b;
            j[(r + 1, col)] = s * a + c * b;
        }
    }
    j
}

#[test]
fn indices_match_their_formulas() {
    let sigma = [8.0, 4.0, 2.0, 0.5];
    let poses = 5;
    let j = with_singular_values(&sigma, poses);
    let i = observability_indices(j.as_ref(), &params(4), ColumnScaling::None).expect("indices");
    let o1 = (8.0f64 * 4.0 * 2.0 * 0.5).powf(0.25) / 5f64.sqrt();
    assert!((i.o1 - o1).abs() < 1e-12, "{} vs {o1}", i.o1);
    assert!((i.o2 - 0.5 / 8.0).abs() < 1e-12);
    assert!((i.o3 - 0.5).abs() < 1e-12);
    assert!((i.o4 - 0.25 / 8.0).abs() < 1e-12);
    assert!((i.o5 - 1.0 / (1.0 / 8.0 + 0.25 + 0.5 + 2.0)).abs() < 1e-12);
    assert!((i.condition_number - 16.0).abs() < 1e-10);
    assert_eq!((i.rank, i.pose_count, i.parameter_count), (4, 5, 4));
    assert_eq!(i.sigma_min, i.o3);
}

#[test]
fn o1_uses_the_power_one_over_l_not_one_over_m() {
    // The Stefan210/kinematic_calibration bug raises the product to 1/m (poses) instead of
    // 1/L (parameters). With L != m the two differ; ours must be the 1/L one.
    let sigma = [30.0, 10.0, 3.0];
    let poses = 7;
    let i = ObservabilityIndices::from_singular_values(&sigma, 3, poses, ColumnScaling::None);
    let product: f64 = sigma.iter().product();
    let correct = product.powf(1.0 / 3.0) / (poses as f64).sqrt();
    let buggy = product.powf(1.0 / poses as f64) / (poses as f64).sqrt();
    assert!((i.o1 - correct).abs() < 1e-12);
    assert!((i.o1 - buggy).abs() > 0.5);
}

#[test]
fn o1_does_not_overflow_with_many_large_singular_values() {
    let sigma = vec![1e200; 40];
    let i = ObservabilityIndices::from_singular_values(&sigma, 40, 4, ColumnScaling::None);
    assert!((i.o1 - 1e200 / 2.0).abs() < 1e188);
    let tiny = vec![1e-200; 40];
    let i = ObservabilityIndices::from_singular_values(&tiny, 40, 4, ColumnScaling::None);
    assert!((i.o1 - 1e-200 / 2.0).abs() < 1e-212);
}

#[test]
fn rank_deficient_input_keeps_a_finite_o1_but_reports_the_rank() {
    // column 3 = column 0 + column 1: O1 is small but not zero (round-off σ), rank says 3.
    let mut j = random(12, 4, 1);
    for r in 0..12 {
        j[(r, 3)] = j[(r, 0)] + j[(r, 1)];
    }
    let i = observability_indices(j.as_ref(), &params(4), ColumnScaling::UnitNorm).expect("indices");
    assert_eq!(i.rank, 3);
    assert!(!i.is_full_rank());
    assert!(i.o1 > 0.0 && i.o1 < 1e-2, "O1 {}", i.o1);
    assert!(i.condition_number > 1e12);
    // fewer rows than columns: missing singular values are zeros
    let short = random(3, 4, 2);
    let i = observability_indices(short.as_ref(), &params(4), ColumnScaling::None).expect("indices");
    assert_eq!(i.o1, 0.0);
    assert_eq!(i.o3, 0.0);
    assert_eq!(i.o5, 0.0);
    assert!(i.condition_number.is_infinite());
    assert_eq!(i.rank, 3);
}

#[test]
fn column_count_mismatch_is_an_error() {
    let j = Mat::<f64>::zeros(6, 3);
    assert!(observability_indices(j.as_ref(), &params(4), ColumnScaling::None).is_err());
}

proptest! {
    /// Column scaling multiplies O1 by the same factor for every design, so it never changes
    /// which of two designs is better.
    #[test]
    fn o1_ranking_is_scale_invariant(seed in 0u64..1000, scale_exp in proptest::collection::vec(-4i32..4, 5)) {
        let (a, b) = (random(15, 5, seed), random(15, 5, seed + 5000));
        let scale = |m: &Mat<f64>| Mat::from_fn(15, 5, |r, c| m[(r, c)] * 10f64.powi(scale_exp[c]));
        let o1 = |m: &Mat<f64>| observability_indices(m.as_ref(), &params(5), ColumnScaling::None).expect("indices").o1;
        let ratio = o1(&a) / o1(&b);
        let ratio_scaled = o1(&scale(&a)) / o1(&scale(&b));
        prop_assert!((ratio - ratio_scaled).abs() < 1e-8 * ratio.abs());
        // unit-norm and a-priori scalings leave the rank unchanged
        let r = |m: &Mat<f64>, s| observability_indices(m.as_ref(), &params(5), s).expect("indices").rank;
        prop_assert_eq!(r(&a, ColumnScaling::None), r(&a, ColumnScaling::APriori));
    }
}
