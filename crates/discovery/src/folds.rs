//! Seeded, stratified K-fold splits over poses.
//!
//! Every stratum (a calibration position, or "tracker") is shuffled with its own stream of a
//! ChaCha8 generator and dealt round-robin into the folds, starting at a random fold, so every
//! fold holds (nearly) the same share of every calibration position and every training set keeps
//! all of them (the world frame needs three positions, background.md §5.3).

use std::collections::BTreeMap;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::{Measurement, Target};

/// The stratum of a measurement: its calibration position, or `None` for tracker data.
pub fn stratum(m: &Measurement) -> Option<u32> {
    match m.target {
        Target::Probe { position } => Some(position),
        Target::Tracker { .. } | Target::Orientation { .. } | Target::Plane { .. } => None,
    }
}

/// Fold index (0..k) of every measurement. `k` is clamped to `1..=len`.
pub fn stratified_folds(measurements: &[Measurement], k: usize, seed: u64) -> Vec<usize> {
    let k = k.clamp(1, measurements.len().max(1));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut groups: BTreeMap<Option<u32>, Vec<usize>> = BTreeMap::new();
    for (i, m) in measurements.iter().enumerate() {
        groups.entry(stratum(m)).or_default().push(i);
    }
    let mut fold = vec![0; measurements.len()];
    for members in groups.values_mut() {
        // Fisher–Yates
        for i in (1..members.len()).rev() {
            let j = rng.random_range(0..=i);
            members.swap(i, j);
        }
        let start = rng.random_range(0..k);
        for (pos, idx) in members.iter().enumerate() {
            fold[*idx] = (start + pos) % k;
        }
    }
    fold
}

/// Seeded split into a screening part (`true`) and a confirmation part (`false`), stratified by
/// calibration position: in every stratum a share `screen_fraction` (rounded, at least one and,
/// with two or more members, at most all but one) goes to screening. Deterministic for a seed.
pub fn screening_split(measurements: &[Measurement], screen_fraction: f64, seed: u64) -> Vec<bool> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5c7e_e41d_c0f1_a2b3);
    let mut groups: BTreeMap<Option<u32>, Vec<usize>> = BTreeMap::new();
    for (i, m) in measurements.iter().enumerate() {
        groups.entry(stratum(m)).or_default().push(i);
    }
    let frac = if screen_fraction.is_finite() { screen_fraction.clamp(0.0, 1.0) } else { 0.5 };
    let mut screen = vec![false; measurements.len()];
    for members in groups.values_mut() {
        for i in (1..members.len()).rev() {
            let j = rng.random_range(0..=i);
            members.swap(i, j);
        }
        let n = members.len();
        let take = ((frac * n as f64).round() as usize).clamp(1.min(n), n.saturating_sub(1).max(1));
        for idx in &members[..take.min(n)] {
            screen[*idx] = true;
        }
    }
    screen
}

/// Indices of the training and test measurements of fold `f`.
pub fn split(folds: &[usize], f: usize) -> (Vec<usize>, Vec<usize>) {
    (0..folds.len()).partition(|i| folds[*i] != f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::JointVector;

    fn data(n: usize) -> Vec<Measurement> {
        (0..n).map(|i| Measurement::probe(1 + (i % 3) as u32, 1, JointVector::default())).collect()
    }

    #[test]
    fn folds_are_balanced_deterministic_and_keep_every_position_in_training() {
        let m = data(181);
        let f = stratified_folds(&m, 5, 42);
        assert_eq!(f, stratified_folds(&m, 5, 42));
        assert_ne!(f, stratified_folds(&m, 5, 43));
        for fold in 0..5 {
            let (train, test) = split(&f, fold);
            assert!((35..=38).contains(&test.len()), "{}", test.len());
            for p in 1..=3 {
                let in_test = test.iter().filter(|i| m[**i].position() == Some(p)).count();
                assert!((11..=13).contains(&in_test), "position {p}: {in_test}");
                assert!(train.iter().any(|i| m[*i].position() == Some(p)));
            }
        }
    }

    #[test]
    fn screening_split_is_stratified_deterministic_and_disjoint() {
        let m = data(90);
        let s = screening_split(&m, 0.5, 7);
        assert_eq!(s, screening_split(&m, 0.5, 7));
        assert_ne!(s, screening_split(&m, 0.5, 8));
        for p in 1..=3 {
            let n_screen = (0..90).filter(|i| s[*i] && m[*i].position() == Some(p)).count();
            assert_eq!(n_screen, 15, "position {p}");
        }
        let s3 = screening_split(&m, 0.3, 7);
        assert_eq!(s3.iter().filter(|x| **x).count(), 27);
    }

    proptest::proptest! {
        #[test]
        fn every_measurement_is_in_exactly_one_fold(n in 1usize..200, k in 1usize..10, seed in 0u64..1000) {
            let m = data(n);
            let f = stratified_folds(&m, k, seed);
            let kk = k.clamp(1, n);
            proptest::prop_assert!(f.iter().all(|x| *x < kk));
            let total: usize = (0..kk).map(|fold| split(&f, fold).1.len()).sum();
            proptest::prop_assert_eq!(total, n);
        }
    }
}
