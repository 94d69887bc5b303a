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
        Target::Tracker { .. } => None,
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
