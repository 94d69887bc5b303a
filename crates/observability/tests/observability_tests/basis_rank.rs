//! The identifiable basis is consistent with the SVD rank: exactly `rank` parameters, of full
//! rank on their own. The preference-ordered QR alone misses dependencies with large weights
//! (a column's remaining norm ≈ σ × weight passes the threshold although σ ≈ 1e-12): on the
//! UR5e touching two unknown parallel planes it kept `alpha_0` beside both planes' tilts
//! (a base rotation about x is the same as tilting both planes).

use faer::Mat;
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::{CellFile, Measurement, ParamId, ParamSet};
use vatcal_kinematics::{ContactPlane, Model};
use vatcal_observability::IdentifiabilityReport;
use vatcal_observability::identifiability::{
    AnalysisOptions, ColumnScaling, analyze_jacobian, apply_column_scaling, full_rank_basis,
    negligible_columns, preference_order, preference_ordered_basis, select_columns,
};
use vatcal_observability::sets::{
    DataDesign, GenericSet, analyze_design, assemble_design_jacobian, generic_order, resolve_spec,
};
use vatcal_sim::truth::{
    ErrorBudget, insert_table_and_block, perturbed_truth, synthetic_plane_contacts,
    synthetic_tracker_measurements, table_and_block_contacts,
};

use crate::common;

/// A singular value counted in the rank this many times above the threshold is reached by some
/// subset of the columns (closer to the threshold the basis may be one short).
const GAP: f64 = 10.0;

fn ur5e() -> Model {
    let cell =
        CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml")).expect("fixture");
    Model::from_cell(&cell).expect("model")
}

/// The hidden truth of `crates/cli/tests/cli_tests/plane_rows_observability.rs`: the perturbed
/// UR5e, a table 50 mm below its base and a gauge block's top 50 mm above it (parallel).
fn plane_truth() -> Model {
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut t = perturbed_truth(&ur5e(), 4, &budget);
    insert_table_and_block(&mut t);
    t
}

/// 20 touches of the table, 20 presses on the block (5 µm contact noise), as the CLI test.
fn plane_rows(truth: &Model) -> Vec<Measurement> {
    let rows = table_and_block_contacts(truth, 20, 0.005);
    assert_eq!(rows.len(), 40);
    rows
}

/// The least-squares plane through the contact points `model` predicts for plane `id`'s rows,
/// its normal upwards: what the CLI adds for a plane the cell file lacks
/// (`vatcal_identification::estimate_planes`, not a dependency of this crate).
fn estimated_plane(model: &Model, rows: &[Measurement], id: u32) -> ContactPlane {
    let points: Vec<Vector3<f64>> = rows
        .iter()
        .filter(|m| m.plane_id() == Some(id))
        .map(|m| model.tcp_position_ctx(&m.q, &m.context, m.tcp).expect("contact point"))
        .collect();
    let c = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let scatter: Matrix3<f64> = points.iter().map(|p| (p - c) * (p - c).transpose()).sum();
    let eig = scatter.symmetric_eigen();
    let k = (0..3).min_by(|a, b| eig.eigenvalues[*a].total_cmp(&eig.eigenvalues[*b])).expect("3 values");
    let mut n: Vector3<f64> = eig.eigenvectors.column(k).normalize();
    if n.z < 0.0 {
        n = -n;
    }
    ContactPlane::new(n, n.dot(&c), 40.0)
}

/// The nominal UR5e with both planes estimated through its contacts, as `vatcal select` and
/// `vatcal observability` analyse these rows; the planes are free.
fn nominal_with_planes(rows: &[Measurement]) -> (Model, DataDesign) {
    let mut model = ur5e();
    for id in [1, 2] {
        let plane = estimated_plane(&model, rows, id);
        model.insert_plane(id, plane);
    }
    (model, DataDesign { free_planes: vec![1, 2], ..DataDesign::default() })
}

/// The order `resolve_spec("all-identifiable" | "default")` analyses with free planes: the
/// planes' tilts and offsets, then every parameter of the model in preference order.
fn all_identifiable_order(model: &Model, rows: &[Measurement], design: &DataDesign) -> ParamSet {
    let mut order = generic_order(model, rows, GenericSet::Registration, design);
    order.0.retain(|p| matches!(p, ParamId::Plane { .. }));
    for p in preference_order(model).0 {
        if !order.0.contains(&p) {
            order.0.push(p);
        }
    }
    order
}

/// The unit-normalised Jacobian the analysis works on (columns without effect zeroed) and the
/// report's absolute rank threshold.
fn normalised(model: &Model, rows: &[Measurement], design: &DataDesign, order: &ParamSet) -> Mat<f64> {
    let mut j = assemble_design_jacobian(model, rows, design, order).expect("jacobian");
    let norms: Vec<f64> = (0..j.ncols()).map(|c| j.col(c).norm_l2()).collect();
    apply_column_scaling(&mut j, order, ColumnScaling::UnitNorm);
    for c in negligible_columns(&norms, &order.0) {
        j.col_mut(c).iter_mut().for_each(|x| *x = 0.0);
    }
    j
}

/// `identifiable.len() == rank` (at most `rank` when the smallest singular value counted is
/// within [`GAP`] of the threshold: a subset of the columns may then not reach it), the basis a
/// subset of the input in input order, every other parameter named redundant, and the basis of
/// full rank when analysed on its own.
fn assert_consistent(j: faer::MatRef<'_, f64>, params: &ParamSet, report: &IdentifiabilityReport) {
    let clear = report.rank == 0 || report.singular_values[report.rank - 1] > GAP * report.threshold();
    if clear {
        assert_eq!(report.identifiable.len(), report.rank, "{report}");
    } else {
        assert!(report.identifiable.len() <= report.rank, "{report}");
    }
    let positions: Vec<usize> =
        report.identifiable.iter().map(|p| params.index_of(*p).expect("a parameter of the input")).collect();
    assert!(positions.windows(2).all(|w| w[0] < w[1]), "input order: {positions:?}");
    assert_eq!(report.redundant.len(), params.len() - report.identifiable.len(), "{report}");
    assert!(report.redundant.iter().all(|r| !report.identifiable.contains(&r.param)));
    assert_eq!(report.unidentifiable().len(), params.len() - report.identifiable.len());
    if report.identifiable.is_empty() {
        return;
    }
    let basis = report.identifiable_set();
    let sub = select_columns(j, params, &basis).expect("columns");
    let own = analyze_jacobian(sub.as_ref(), &basis, &AnalysisOptions::default()).expect("basis analysis");
    assert!(own.is_full_rank(), "the basis alone: {own}");
}

/// The defect and its fix on the CLI's plane data: the preference-ordered QR keeps `alpha_0`
/// although its column is in the span of the two planes' tilts (the kept columns' SVD rank is
/// one less than their number); the basis now leaves it out, names the planes' tilts as what
/// absorbs it, and is of full rank.
#[test]
fn two_unknown_parallel_planes_do_not_keep_alpha_0() {
    let rows = plane_rows(&plane_truth());
    let (model, design) = nominal_with_planes(&rows);
    let order = all_identifiable_order(&model, &rows, &design);
    let report = analyze_design(&model, &rows, &design, &order).expect("analysis");
    let jn = normalised(&model, &rows, &design, &order);
    assert_eq!(report.threshold(), report.tolerance * report.singular_values[0]);

    // the QR alone: alpha_0 kept, one more column than the SVD rank, a direction below the
    // threshold among them made of alpha_0 and the planes' tilts
    let qr = preference_ordered_basis(jn.as_ref(), report.threshold());
    let qr_set = ParamSet(qr.iter().map(|c| order.0[*c]).collect());
    let qr_report = analyze_jacobian(
        select_columns(jn.as_ref(), &order, &qr_set).expect("columns").as_ref(),
        &qr_set,
        &AnalysisOptions::default(),
    )
    .expect("QR basis analysis");
    eprintln!("full order: rank {} of {}\nthe QR's basis alone:\n{qr_report}", report.rank, order.len());
    assert!(qr_set.0.contains(&ParamId::Alpha(1)), "{:?}", qr_set.names());
    assert_eq!(qr_set.len(), report.rank + 1);
    assert_eq!(qr_report.rank, report.rank);
    let lost = &qr_report.lost_directions[0];
    assert!(lost.singular_value < 1e-9 * qr_report.singular_values[0], "{}", lost.sentence());
    let members: Vec<ParamId> = lost.combination.iter().map(|(p, _)| *p).collect();
    assert!(members.contains(&ParamId::Alpha(1)), "{}", lost.sentence());
    assert!(members.iter().all(|p| *p == ParamId::Alpha(1) || matches!(p, ParamId::Plane { .. })));

    // the fix: the report's basis is `rank` columns of full rank, without alpha_0
    assert_eq!(
        full_rank_basis(jn.as_ref(), report.threshold(), report.rank).expect("basis").len(),
        report.rank
    );
    assert!(!report.identifiable.contains(&ParamId::Alpha(1)), "{report}");
    assert_consistent(jn.as_ref(), &order, &report);
    let alpha0 = report.redundant.iter().find(|r| r.param == ParamId::Alpha(1)).expect("alpha_0 named");
    eprintln!("{}", alpha0.sentence());
    assert!(alpha0.fit_residual < 1e-9, "{}", alpha0.sentence());
    for id in [1, 2] {
        assert!(
            alpha0.confounded_with.iter().any(|(p, _)| matches!(p, ParamId::Plane { id: i, .. } if *i == id)),
            "{}",
            alpha0.sentence()
        );
    }

    // what --params default / all-identifiable resolve to: the same basis
    for spec in ["default", "all-identifiable"] {
        let set = resolve_spec(spec, &model, &rows, &design).expect("spec");
        assert_eq!(set.0, report.identifiable, "{spec}");
        let own = analyze_design(&model, &rows, &design, &set).expect("basis");
        eprintln!(
            "{spec}: {} parameters, smallest singular value {:.3e}",
            set.len(),
            own.singular_values[own.rank - 1]
        );
        assert!(own.is_full_rank(), "{spec}: {own}");
    }
}

/// At the truth (the model and planes the rows were made with) the QR kept two columns too many (d_3 and
/// d_4 beside d_2, along the nearly parallel axes 2..4, with weights of ~1e5): the basis is now
/// `rank` columns of full rank there too.
#[test]
fn the_basis_at_the_truth_is_of_full_rank() {
    let truth = plane_truth();
    let rows = plane_rows(&truth);
    let design = DataDesign { free_planes: vec![1, 2], ..DataDesign::default() };
    let order = all_identifiable_order(&truth, &rows, &design);
    let report = analyze_design(&truth, &rows, &design, &order).expect("analysis");
    let jn = normalised(&truth, &rows, &design, &order);
    let qr = preference_ordered_basis(jn.as_ref(), report.threshold());
    eprintln!("truth: rank {}, QR kept {}, basis {}", report.rank, qr.len(), report.identifiable.len());
    assert!(qr.len() > report.rank, "the QR alone keeps too many here (the case this test covers)");
    assert_consistent(jn.as_ref(), &order, &report);
    // d_3 and d_4: kept by the QR, now absorbed by d_2
    for p in [ParamId::D(3), ParamId::D(4)] {
        assert!(qr.contains(&order.index_of(p).expect("in the order")), "{p}");
        let r = report.redundant.iter().find(|r| r.param == p).expect("named redundant");
        assert_eq!(r.confounded_with[0].0, ParamId::D(2), "{}", r.sentence());
    }
    // every redundancy is explained by the basis within the rank threshold, with moderate weights
    for r in report.redundant.iter().filter(|r| !r.confounded_with.is_empty()) {
        eprintln!("{} (residual {:.1e})", r.sentence(), r.fit_residual);
        assert!(r.fit_residual <= report.threshold(), "{}", r.sentence());
        assert!(r.normalized_weights.iter().all(|w| w.abs() < 10.0), "{}", r.sentence());
    }
}

/// A column that is a combination of earlier ones with large weights — two nearly parallel
/// columns, their difference × 1e5 — with round-off-sized noise in those columns: the QR's
/// remaining norm of the late column is ~1e5 × σ and passes the threshold. The lost direction
/// weighs the two nearly parallel columns equally (0.707 each) and the late column hardly at
/// all: the later of the two goes, which leaves a well-conditioned basis (keeping both and
/// dropping the late column would keep their near-dependency, σ ≈ 1e-6).
#[test]
fn a_dependency_with_large_weights_is_dropped() {
    let (m, l) = (60, 5);
    let mut j = Mat::<f64>::zeros(m, l);
    for r in 0..m {
        let x = r as f64;
        j[(r, 0)] = (0.3 * x).sin() + 0.2;
        j[(r, 1)] = j[(r, 0)] + 1e-5 * (0.11 * x * x).cos();
        j[(r, 2)] = (0.05 * x * x).sin();
        j[(r, 3)] = 1e5 * (j[(r, 1)] - j[(r, 0)]);
        j[(r, 4)] = (0.7 * x + 1.0).cos();
        // round-off-sized noise in column 1 after column 3 was made from it
        j[(r, 1)] += 1e-12 * (1.7 * x).sin();
    }
    let params =
        ParamSet(vec![ParamId::D(2), ParamId::D(3), ParamId::A(2), ParamId::Alpha(1), ParamId::A(3)]);
    let report = analyze_jacobian(j.as_ref(), &params, &AnalysisOptions::default()).expect("analysis");
    eprintln!("{report}");
    let mut jn = j.clone();
    apply_column_scaling(&mut jn, &params, ColumnScaling::UnitNorm);
    let qr = preference_ordered_basis(jn.as_ref(), report.threshold());
    assert_eq!(qr, vec![0, 1, 2, 3, 4], "the QR alone keeps every column");
    assert_eq!(report.rank, 4);
    assert!(report.singular_values[4] < 1e-10, "{report}");
    assert_eq!(report.identifiable, vec![ParamId::D(2), ParamId::A(2), ParamId::Alpha(1), ParamId::A(3)]);
    assert_eq!(report.redundant[0].param, ParamId::D(3));
    assert_consistent(j.as_ref(), &params, &report);
    let basis = report.identifiable_set();
    let sub = select_columns(j.as_ref(), &params, &basis).expect("columns");
    let own = analyze_jacobian(sub.as_ref(), &basis, &AnalysisOptions::default()).expect("basis");
    assert!(own.singular_values[3] > 1e-2, "{own}");
}

/// Random columns, some of them random combinations of the others with weights over several
/// orders of magnitude, plus noise at the round-off level or far above the threshold.
fn planted(seed: u64, rows: usize, cols: usize, dependent: usize) -> Mat<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut j = Mat::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0));
    for _ in 0..dependent {
        let target = rng.random_range(0..cols);
        let noise = if rng.random_bool(0.7) { 1e-14 } else { 1e-3 };
        let weights: Vec<f64> = (0..cols)
            .map(|c| {
                if c == target || !rng.random_bool(0.5) {
                    0.0
                } else {
                    rng.random_range(-1.0..1.0) * 10f64.powi(rng.random_range(-2..5))
                }
            })
            .collect();
        for r in 0..rows {
            let v: f64 = (0..cols).map(|c| weights[c] * j[(r, c)]).sum();
            j[(r, target)] = v + noise * rng.random_range(-1.0..1.0);
        }
    }
    j
}

/// The parameters of `model` as `preference_order` lists them, a random subset (at least 3).
fn random_subset(order: &ParamSet, seed: u64) -> ParamSet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let keep = rng.random_range(0.3..1.0);
    let mut v: Vec<ParamId> = order.0.iter().copied().filter(|_| rng.random_bool(keep)).collect();
    if v.len() < 3 {
        v = order.0[..3].to_vec();
    }
    ParamSet(v)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Synthetic Jacobians with planted dependencies.
    #[test]
    fn planted_dependencies_give_a_basis_of_rank_size(
        seed in 0u64..10_000,
        rows in 4usize..40,
        cols in 2usize..14,
        dependent in 0usize..5,
    ) {
        let j = planted(seed, rows, cols, dependent);
        let params = ParamSet((1..=cols as u8).map(ParamId::D).collect());
        let report = analyze_jacobian(j.as_ref(), &params, &AnalysisOptions::default()).expect("analysis");
        assert_consistent(j.as_ref(), &params, &report);
    }

    /// Random subsets of every parameter of a perturbed model, on probe rows (canonical cell),
    /// tracker rows and rows on unknown planes (UR5e).
    #[test]
    fn random_subsets_of_random_models_give_a_basis_of_rank_size(
        seed in 0u64..10_000,
        data in 0usize..3,
        count in 6usize..30,
    ) {
        let budget = ErrorBudget::realistic();
        let (model, rows, design) = match data {
            0 => {
                let truth = perturbed_truth(&common::canonical_model(), seed, &budget);
                let rows = common::probe_poses(&truth, &[1, 2, 3], count, seed);
                (truth, rows, DataDesign::default())
            }
            1 => {
                let truth = perturbed_truth(&ur5e(), seed, &budget);
                let rows = synthetic_tracker_measurements(&truth, count, 0.0, seed);
                (truth, rows, DataDesign::default())
            }
            _ => {
                let mut truth = perturbed_truth(&ur5e(), seed, &budget);
                insert_table_and_block(&mut truth);
                let mut rows = synthetic_plane_contacts(&truth, 1, 1, false, count, 0.0, seed);
                rows.extend(synthetic_plane_contacts(&truth, 2, 1, seed % 2 == 0, count, 0.0, seed + 1));
                (truth, rows, DataDesign { free_planes: vec![1, 2], ..DataDesign::default() })
            }
        };
        prop_assume!(!rows.is_empty());
        let order = all_identifiable_order(&model, &rows, &design);
        let params = random_subset(&order, seed);
        let report = analyze_design(&model, &rows, &design, &params).expect("analysis");
        let jn = normalised(&model, &rows, &design, &params);
        assert_consistent(jn.as_ref(), &params, &report);
    }
}
