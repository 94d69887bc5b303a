//! Detmax: agreement with the naive reference and with exhaustive search, incremental log-det
//! accuracy, comparison with greedy/random designs, determinism and input errors.

use crate::common;

use common::{canonical_model, probe_poses};
use faer::Mat;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use vatcal_core::{ParamId, ParamSet};
use vatcal_observability::ColumnScaling;
use vatcal_observability::ObservabilityError;
use vatcal_observability::detmax::{
    Candidates, DetmaxOptions, Objective, detmax, greedy, log_det, log_det_by_svd, naive_detmax,
};
use vatcal_observability::indices::observability_indices;

/// Gaussian 3×L blocks with column scales spanning 4 decades (like mm/rad vs compliance).
fn gaussian(n: usize, l: usize, seed: u64) -> Candidates {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let j = Mat::from_fn(3 * n, l, |_, c| {
        let z: f64 = StandardNormal.sample(&mut rng);
        z * 10f64.powi((c % 5) as i32 - 2)
    });
    let params = ParamSet(ParamSet::paper34().0.into_iter().take(l).collect());
    Candidates::from_stacked(j, params).expect("candidates")
}

fn model_candidates(n: usize, positions: &[u32], seed: u64) -> Candidates {
    let model = canonical_model();
    let poses = probe_poses(&model, positions, n, seed);
    Candidates::from_measurements(&model, &poses, &ParamSet::paper34()).expect("candidates")
}

fn options(count: usize, restarts: usize, seed: u64) -> DetmaxOptions {
    DetmaxOptions { restarts, seed, ..DetmaxOptions::new(count) }
}

#[test]
fn incremental_log_det_equals_from_scratch() {
    for (c, count) in [(gaussian(300, 12, 1), 20), (model_candidates(240, &[1, 2, 3], 2), 40)] {
        let mut o = options(count, 2, 9);
        o.refactor_every = usize::MAX; // pure rank-3 updates from start to end
        let s = detmax(&c, &o).expect("detmax");
        assert!(s.restarts.iter().all(|r| r.exchanges > 5), "{:?}", s.restarts);
        let scratch = log_det_by_svd(&c, &s.selected);
        assert!(
            (s.tracked_log_det - scratch).abs() < 1e-8 * scratch.abs().max(1.0),
            "{} vs {scratch}",
            s.tracked_log_det
        );
        assert!((s.log_det - scratch).abs() < 1e-9 * scratch.abs().max(1.0));
    }
}

#[test]
fn fast_path_follows_the_naive_reference_step_by_step() {
    let c = gaussian(70, 10, 3);
    let o = options(8, 3, 5);
    let fast = detmax(&c, &o).expect("fast");
    let naive = naive_detmax(&c, &o).expect("naive");
    for (f, n) in fast.restarts.iter().zip(&naive.restarts) {
        assert_eq!(f.exchanges, n.exchanges);
        assert!((f.log_det - n.log_det).abs() < 1e-9 * n.log_det.abs().max(1.0));
    }
    assert_eq!(fast.selected, naive.selected);
}

fn exhaustive_best(c: &Candidates, count: usize) -> f64 {
    let n = c.len();
    let mut best = f64::NEG_INFINITY;
    let mut idx: Vec<usize> = (0..count).collect();
    loop {
        if let Some(v) = log_det(c, &idx, 0.0) {
            best = best.max(v);
        }
        // next combination
        let mut i = count;
        while i > 0 && idx[i - 1] == n - count + i - 1 {
            i -= 1;
        }
        if i == 0 {
            return best;
        }
        idx[i - 1] += 1;
        for j in i..count {
            idx[j] = idx[j - 1] + 1;
        }
    }
}

#[test]
fn detmax_finds_the_exhaustive_optimum_on_tiny_instances() {
    for (n, count, l, seed) in [(16, 12, 10, 11), (16, 12, 12, 12), (20, 12, 12, 13)] {
        let c = gaussian(n, l, seed);
        let best = exhaustive_best(&c, count);
        let s = detmax(&c, &options(count, 8, seed)).expect("detmax");
        assert!(
            (s.log_det - best).abs() < 1e-9 * best.abs().max(1.0),
            "N={n} n={count}: {} vs optimum {best}",
            s.log_det
        );
        let mut ex = options(count, 1, seed);
        ex.excursions = Some(3);
        let e = detmax(&c, &ex).expect("excursions");
        let plain = detmax(&c, &options(count, 1, seed)).expect("plain");
        assert!(e.log_det >= plain.log_det - 1e-12);
    }
}

#[test]
fn detmax_beats_greedy_and_random_designs() {
    let c = model_candidates(360, &[1, 2, 3], 21);
    let count = 40;
    let s = detmax(&c, &options(count, 4, 1)).expect("detmax");
    let g = greedy(&c, &options(count, 1, 1)).expect("greedy");
    assert!(s.log_det >= g.log_det - 1e-9, "detmax {} < greedy {}", s.log_det, g.log_det);
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let mut best_random = f64::NEG_INFINITY;
    for _ in 0..200 {
        let mut pool: Vec<usize> = (0..c.len()).collect();
        for i in 0..count {
            let j = rng.random_range(i..pool.len());
            pool.swap(i, j);
        }
        if let Some(v) = log_det(&c, &pool[..count], 0.0) {
            best_random = best_random.max(v);
        }
    }
    assert!(s.log_det > best_random, "detmax {} <= best random {best_random}", s.log_det);
    let l = c.parameter_count();
    eprintln!(
        "O1 detmax {:.3}, greedy {:.3}, best of 200 random {:.3}",
        s.o1(l),
        g.o1(l),
        vatcal_observability::detmax::o1_from_log_det(best_random, l, count)
    );
    // O1 from the log-det equals O1 from the indices module (natural units)
    let idx = observability_indices(c.design_jacobian(&s.selected).as_ref(), c.params(), ColumnScaling::None)
        .expect("indices");
    assert!((idx.o1 - s.o1(l)).abs() < 1e-9 * idx.o1);
    assert_eq!(idx.rank, 34);
}

#[test]
fn results_are_deterministic_and_independent_of_thread_count() {
    let c = gaussian(3000, 16, 4);
    let o = options(12, 4, 42);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| detmax(&c, &o).expect("detmax"))
    };
    let a = run(1);
    let b = run(2);
    let b2 = run(2);
    assert_eq!(a, b);
    assert_eq!(b, b2);
    let other_seed = detmax(&c, &options(12, 4, 43)).expect("detmax");
    assert_ne!(other_seed.restarts[0].seed, a.restarts[0].seed);
}

#[test]
fn fixed_poses_stay_in_the_design() {
    let c = gaussian(200, 10, 6);
    let mut o = options(10, 3, 1);
    o.fixed = vec![3, 150, 199];
    let s = detmax(&c, &o).expect("detmax");
    for f in &o.fixed {
        assert!(s.selected.contains(f));
    }
    assert_eq!(s.selected.len(), 10);
    let free = detmax(&c, &options(10, 3, 1)).expect("free");
    assert!(free.log_det >= s.log_det - 1e-9);
}

#[test]
fn exact_objectives_improve_their_own_index() {
    let c = model_candidates(150, &[1, 2, 3], 8);
    let unit = c.scaled(&vatcal_observability::identifiability::column_scale_factors(
        c.stacked(),
        &c.params().0,
        ColumnScaling::UnitNorm,
    ));
    let d = detmax(&unit, &options(20, 1, 3)).expect("O1");
    let d_idx =
        observability_indices(unit.design_jacobian(&d.selected).as_ref(), unit.params(), ColumnScaling::None)
            .expect("idx");
    let mut o = options(20, 1, 3);
    o.objective = Objective::O3;
    o.shortlist = 16;
    let s = detmax(&unit, &o).expect("O3");
    let s_idx =
        observability_indices(unit.design_jacobian(&s.selected).as_ref(), unit.params(), ColumnScaling::None)
            .expect("idx");
    assert!((s.objective_value - s_idx.o3).abs() < 1e-9 * s_idx.o3);
    assert!(s_idx.o3 >= d_idx.o3, "O3 selection {} < O1 selection {}", s_idx.o3, d_idx.o3);
}

#[test]
fn bad_input_is_refused_clearly() {
    let c = gaussian(10, 8, 1);
    match detmax(&c, &options(11, 1, 0)) {
        Err(e @ ObservabilityError::TooFewCandidates { available: 10, requested: 11 }) => {
            assert!(e.to_string().contains("only 10 candidate poses for 11"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    assert!(
        matches!(detmax(&c, &options(2, 1, 0)), Err(ObservabilityError::InvalidInput(m)) if m.contains("at least 3 poses"))
    );
    let mut o = options(5, 1, 0);
    o.fixed = vec![10];
    assert!(matches!(detmax(&c, &o), Err(ObservabilityError::InvalidInput(m)) if m.contains("out of range")));

    // candidates at one calibration position cannot fix the world frame
    let one = model_candidates(60, &[2], 3);
    match detmax(&one, &options(40, 1, 0)) {
        Err(ObservabilityError::RankDeficient { rank, needed, unidentifiable, message }) => {
            assert_eq!((rank, needed), (31, 34));
            assert!(unidentifiable.iter().all(|p| matches!(p, ParamId::Base(_))), "{unidentifiable:?}");
            assert!(message.contains("candidate set is rank-deficient"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    // ... but can be used with a ridge (the ablation): the result is rank 31
    let mut o = options(40, 2, 0);
    o.ridge = 1e-6;
    let s = detmax(&one, &o).expect("ridge selection");
    let idx =
        observability_indices(one.design_jacobian(&s.selected).as_ref(), one.params(), ColumnScaling::None)
            .expect("idx");
    assert_eq!(idx.rank, 31);
    assert!(idx.o1 > 0.0 && idx.o1.is_finite());
}

#[test]
fn ablation_shows_the_rank_lost_with_fewer_positions() {
    let model = canonical_model();
    let poses = probe_poses(&model, &[1, 2, 3], 180, 31);
    let c = Candidates::from_measurements(&model, &poses, &ParamSet::paper34()).expect("candidates");
    let positions: Vec<Option<u32>> = poses.iter().map(|m| m.position()).collect();
    let o = options(20, 2, 4);
    let full = detmax(&c, &o).expect("full");
    let full_idx = vatcal_observability::detmax::selection_indices(&c, &full.selected).expect("indices");
    assert_eq!(full_idx.raw.rank, 34);
    for (size, rank) in [(1usize, 31usize), (2, 33)] {
        let rows =
            vatcal_observability::detmax::position_ablation(&c, &positions, size, &o).expect("ablation");
        assert_eq!(rows.len(), 3);
        for r in &rows {
            assert_eq!(r.positions.len(), size);
            assert_eq!(r.candidate_count, 60 * size);
            let sel = r.selected.as_ref().expect("selection");
            assert!(sel.iter().all(|k| positions[*k].is_some_and(|p| r.positions.contains(&p))));
            let idx = r.indices.expect("indices");
            assert_eq!(idx.raw.rank, rank, "{:?}", r.positions);
            assert!(idx.raw.o1 < full_idx.raw.o1);
        }
    }
    // too few candidates at a position: no selection, no error
    let rows = vatcal_observability::detmax::position_ablation(&c, &positions, 1, &options(61, 1, 0))
        .expect("ablation");
    assert!(rows.iter().all(|r| r.selected.is_none()));
}

#[test]
fn selection_reaches_99_percent_of_an_independent_reference_best() {
    // The reference: the naive exchange (every determinant from scratch), 4 restarts with
    // seeds the fast path does not use; O1 of both recomputed independently by SVD.
    let c = model_candidates(150, &[1, 2, 3], 77);
    let reference = naive_detmax(&c, &options(40, 4, 1000)).expect("reference");
    let mut o = options(40, 8, 5);
    o.excursions = Some(3);
    let ours = detmax(&c, &o).expect("detmax");
    let o1 = |sel: &[usize]| {
        observability_indices(c.design_jacobian(sel).as_ref(), c.params(), ColumnScaling::None)
            .expect("indices")
            .o1
    };
    let (mine, theirs) = (o1(&ours.selected), o1(&reference.selected));
    eprintln!("O1 ours {mine:.4}, reference best {theirs:.4}");
    assert!(mine >= 0.99 * theirs, "ours {mine} < 99% of reference {theirs}");
}

/// The parallel candidate Jacobians are the blocks of `assemble_jacobian`, bit for bit (so the
/// selection does not depend on how they are computed), and a bad measurement is reported
/// with the index of the first one, as a sequential pass would.
#[test]
fn candidate_blocks_equal_the_assembled_jacobian_and_name_the_first_bad_pose() {
    let model = canonical_model();
    let params = ParamSet::paper34();
    let mut poses = probe_poses(&model, &[1, 2, 3], 700, 21);
    let c = Candidates::from_measurements(&model, &poses, &params).expect("candidates");
    let j = vatcal_observability::assemble_jacobian(&model, &poses, &params).expect("jacobian");
    assert_eq!(c.len(), poses.len());
    let stacked = c.stacked();
    for r in 0..j.nrows() {
        for col in 0..j.ncols() {
            assert_eq!(stacked[(r, col)].to_bits(), j[(r, col)].to_bits(), "row {r}, column {col}");
        }
    }
    // unknown TCP ids in two chunks: the lower index is named
    poses[650].tcp = 99;
    poses[300].tcp = 99;
    match Candidates::from_measurements(&model, &poses, &params) {
        Err(ObservabilityError::Model { index, .. }) => assert_eq!(index, 300),
        other => panic!("expected a model error at index 300, got {other:?}"),
    }
}
