//! Tour sequencing against exact optima (Held–Karp, brute force) and its invariants.

use proptest::prelude::*;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::JointVector;
use vatcal_core::cell::MotionLimits;
use vatcal_planning::motion::MotionTimer;
use vatcal_planning::tour::{TourCosts, TourOptions, held_karp, solve_open_path};

/// A random instance: `n` joint vectors in the Meca500 range, groups (calibration positions)
/// 1..=3, the cell's motion-time model and re-placement time, optionally a start.
fn instance(seed: u64, n: usize, with_start: bool) -> (TourCosts, Vec<u32>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let timer = MotionTimer::from_limits(&MotionLimits::default()).expect("timer");
    let random_q = |rng: &mut ChaCha8Rng| {
        let mut arm = [0.0; 6];
        for v in arm.iter_mut() {
            *v = rng.random_range(-150.0..150.0);
        }
        JointVector::from_mm_deg(rng.random_range(0.0..300.0), arm)
    };
    let qs: Vec<JointVector> = (0..n).map(|_| random_q(&mut rng)).collect();
    let groups: Vec<u32> = (0..n).map(|_| rng.random_range(1..=3u32)).collect();
    let start = random_q(&mut rng);
    let cost = |i: usize, j: usize| {
        timer.move_time_s(&qs[i], &qs[j])
            + if groups[i] != groups[j] { timer.probe_replacement_s } else { 0.0 }
    };
    let from_start = |j: usize| timer.move_time_s(&start, &qs[j]);
    let costs =
        if with_start { TourCosts::new(n, cost, Some(&from_start)) } else { TourCosts::new(n, cost, None) };
    (costs, groups)
}

fn brute_force(costs: &TourCosts) -> f64 {
    fn rec(costs: &TourCosts, order: &mut Vec<usize>, used: &mut Vec<bool>, best: &mut f64) {
        if order.len() == costs.len() {
            *best = best.min(costs.path_cost(order));
            return;
        }
        for j in 0..costs.len() {
            if !used[j] {
                used[j] = true;
                order.push(j);
                rec(costs, order, used, best);
                order.pop();
                used[j] = false;
            }
        }
    }
    let mut best = f64::INFINITY;
    rec(costs, &mut Vec::new(), &mut vec![false; costs.len()], &mut best);
    best
}

fn is_permutation(order: &[usize], n: usize) -> bool {
    let mut seen = vec![false; n];
    order.len() == n && order.iter().all(|&i| i < n && !std::mem::replace(&mut seen[i], true))
}

#[test]
fn held_karp_matches_brute_force() {
    for seed in 0..40 {
        let n = 2 + (seed as usize % 6);
        let (costs, _) = instance(seed, n, seed % 2 == 0);
        let (hk, order) = held_karp(&costs).expect("small");
        assert!(is_permutation(&order, n));
        assert!((costs.path_cost(&order) - hk).abs() < 1e-9);
        let bf = brute_force(&costs);
        assert!((hk - bf).abs() < 1e-9, "seed {seed}: Held-Karp {hk} vs brute force {bf}");
    }
}

#[test]
fn heuristic_matches_exact_optimum_on_small_instances() {
    let mut worst_gap: f64 = 0.0;
    for seed in 0..300 {
        let n = 3 + (seed as usize % 8); // 3..=10
        let (costs, groups) = instance(1000 + seed, n, seed % 3 == 0);
        let order = solve_open_path(&costs, &groups, &TourOptions { restarts: 16, seed });
        assert!(is_permutation(&order, n));
        let (opt, _) = held_karp(&costs).expect("small");
        let gap = costs.path_cost(&order) - opt;
        worst_gap = worst_gap.max(gap);
        assert!(gap < 1e-9, "seed {seed}, n {n}: heuristic {} vs optimum {opt}", costs.path_cost(&order));
    }
    assert!(worst_gap < 1e-9);
}

#[test]
fn optimum_keeps_positions_together() {
    for seed in 0..50 {
        let (costs, groups) = instance(5000 + seed, 9, false);
        let order = solve_open_path(&costs, &groups, &TourOptions::default());
        let changes = order.windows(2).filter(|w| groups[w[0]] != groups[w[1]]).count();
        let mut distinct = groups.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(changes, distinct.len() - 1, "seed {seed}: order {order:?} groups {groups:?}");
    }
}

#[test]
fn exact_solver_declines_large_instances() {
    let (costs, _) = instance(1, 17, false);
    assert!(held_karp(&costs).is_none());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The result is a permutation and never costlier than the input order.
    #[test]
    fn result_is_a_permutation_no_worse_than_input(seed in 0u64..u64::MAX, n in 1usize..40, start in any::<bool>()) {
        let (costs, groups) = instance(seed, n, start);
        let order = solve_open_path(&costs, &groups, &TourOptions { restarts: 3, seed });
        prop_assert!(is_permutation(&order, n));
        let identity: Vec<usize> = (0..n).collect();
        prop_assert!(costs.path_cost(&order) <= costs.path_cost(&identity) + 1e-9);
    }
}
