//! Plane rows (issue 31 item 3) in the observability analysis and in Detmax: the UR5e (perturbed
//! geometry, the hidden truth) pressing its tool on a horizontal table and on the top of a
//! 50 mm gauge block standing on it, and touching a wall. Horizontal planes see heights only:
//! the base's x, y and rotation about the vertical cannot be identified from them; planes at
//! unknown places leave the scale free until a known distance between two parallel planes
//! fixes it. Detmax picks among plane and tracker rows like among any rows.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use vatcal_core::{BaseParam, CellFile, Measurement, ParamId, PlaneDistance, PlaneDof};
use vatcal_kinematics::{ContactPlane, Model};
use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax, selection_indices};
use vatcal_observability::sets::{
    DataDesign, GenericSet, analyze_design, generic_order, generic_set, resolve_spec,
};
use vatcal_sim::truth::{
    ErrorBudget, perturbed_truth, synthetic_plane_contacts, synthetic_tracker_measurements,
};

const TABLE: u32 = 1;
const BLOCK: u32 = 2;
const WALL: u32 = 3;

fn ur5e() -> Model {
    let cell =
        CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml")).expect("fixture");
    Model::from_cell(&cell).expect("model")
}

/// The perturbed UR5e with an exactly horizontal table 50 mm below the base, the block's top
/// 50 mm above the table and a (slightly tilted) wall 450 mm along x.
fn truth(seed: u64) -> Model {
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut t = perturbed_truth(&ur5e(), seed, &budget);
    t.insert_plane(TABLE, ContactPlane::new(Vector3::z(), -50.0, 40.0));
    t.insert_plane(BLOCK, ContactPlane::new(Vector3::z(), 0.0, 40.0));
    t.insert_plane(WALL, ContactPlane::new(Vector3::new(-1.0, 0.004, 0.002), -450.0, 40.0));
    t
}

fn names(params: &[ParamId]) -> Vec<String> {
    let mut v: Vec<String> = params.iter().map(|p| p.name()).collect();
    v.sort();
    v
}

/// Known horizontal planes, the TCP touching them (height rows only): of the `kinematic` order
/// (base pose first) exactly the base's x, y and rotation about z are lost beyond what tracker
/// rows of the same truth lose (x and y without effect, the rotation absorbed by the base's
/// tilts), and the identifiable basis is of full rank. Pressing the face on half of the contacts
/// (tool-axis rows) loses the same three; pressing it on all of them also loses the TCP's offset
/// across the tool axis (the axis is then always vertical).
#[test]
fn horizontal_planes_lose_base_x_y_and_rotation_about_z() {
    let truth = truth(21);
    let design = DataDesign::default();
    let trackers: Vec<Measurement> = synthetic_tracker_measurements(&truth, 200, 0.0, 7)
        .into_iter()
        .filter(|m| m.tcp == 1)
        .take(60)
        .collect();
    assert_eq!(trackers.len(), 60);
    // touched only, half pressed, all pressed
    for pressed_share in [0, 15, 30] {
        let pressed = pressed_share == 30;
        let mut rows = Vec::new();
        for (k, plane) in [TABLE, BLOCK].into_iter().enumerate() {
            let s = 5 + 2 * k as u64;
            rows.extend(synthetic_plane_contacts(&truth, plane, 1, true, pressed_share, 0.0, s));
            rows.extend(synthetic_plane_contacts(&truth, plane, 1, false, 30 - pressed_share, 0.0, s + 1));
        }
        assert_eq!(rows.len(), 60, "every contact found");
        let order = generic_order(&truth, &rows, GenericSet::Kinematic, &design);
        let base: Vec<ParamId> = BaseParam::ALL.map(ParamId::Base).to_vec();
        assert!(base.iter().all(|p| order.0.contains(p)), "known planes anchor the base pose");
        let report = analyze_design(&truth, &rows, &design, &order).expect("analysis");
        assert_eq!(report.measurement_count, 60);
        assert_eq!(report.equation_count, 60 + 2 * 2 * pressed_share);
        let tracker_report = analyze_design(&truth, &trackers, &design, &order).expect("tracker analysis");
        let lost = names(&report.unidentifiable());
        eprintln!(
            "{pressed_share} of 30 pressed: planes rank {} of {}; trackers rank {}; not identifiable: {lost:?}",
            report.rank, report.parameter_count, tracker_report.rank
        );
        assert!(names(&tracker_report.unidentifiable()).iter().all(|p| !p.starts_with("base_")));
        for p in ["base_gamma", "base_x", "base_y"] {
            assert!(lost.iter().any(|l| l == p), "{p} not named: {lost:?}");
        }
        if pressed {
            // the tool axis always along the normal: the TCP's offset across it is invisible
            assert!(lost.iter().any(|l| l == "tcp1_x") && lost.iter().any(|l| l == "tcp1_y"), "{lost:?}");
            continue;
        }
        assert_eq!(tracker_report.rank - report.rank, 3, "three directions lost beyond the trackers'");
        if pressed_share > 0 {
            continue;
        }
        eprintln!("{report}");
        // heights do not see the base's x and y at all; its rotation (about its own, slightly
        // tilted z) only through the tilt it implies, which base_alpha and base_beta absorb
        for p in [BaseParam::X, BaseParam::Y] {
            let r = report.redundant.iter().find(|r| r.param == ParamId::Base(p)).expect("named");
            assert!(r.sentence().contains("has no effect"), "{}", r.sentence());
        }
        let gamma =
            report.redundant.iter().find(|r| r.param == ParamId::Base(BaseParam::Gamma)).expect("named");
        assert!(
            gamma
                .confounded_with
                .iter()
                .all(|(p, _)| matches!(p, ParamId::Base(BaseParam::Alpha | BaseParam::Beta))),
            "{}",
            gamma.sentence()
        );
        let basis = report.identifiable_set();
        assert_eq!(basis.len(), report.rank);
        let again = analyze_design(&truth, &rows, &design, &basis).expect("basis");
        assert!(again.is_full_rank(), "{again}");
    }
}

/// Unknown planes: the scale of the chain is free (the `kinematic` set is refused) until the
/// known 50 mm between table and block fixes it: one more identifiable direction, nothing else.
/// (`all-identifiable`, which has the compliances, is the same size with and without it.)
#[test]
fn a_plane_distance_fixes_the_scale_of_unknown_planes() {
    let truth = truth(22);
    let mut rows = Vec::new();
    for (k, plane) in [TABLE, BLOCK].into_iter().enumerate() {
        rows.extend(synthetic_plane_contacts(&truth, plane, 1, true, 15, 0.0, 9 + 2 * k as u64));
        rows.extend(synthetic_plane_contacts(&truth, plane, 1, false, 15, 0.0, 10 + 2 * k as u64));
    }
    rows.extend(synthetic_plane_contacts(&truth, WALL, 1, false, 15, 0.0, 13));
    let free = DataDesign { free_planes: vec![TABLE, BLOCK, WALL], ..DataDesign::default() };
    let e = generic_set(&truth, &rows, GenericSet::Kinematic, &free).expect_err("no scale").to_string();
    assert!(e.contains("--plane-distance"), "{e}");
    let fixed = DataDesign {
        plane_distances: vec![PlaneDistance { a: TABLE, b: BLOCK, distance_mm: 50.0, sigma_mm: 0.01 }],
        ..free.clone()
    };
    let order = generic_order(&truth, &rows, GenericSet::Kinematic, &fixed);
    assert_eq!(order, generic_order(&truth, &rows, GenericSet::Kinematic, &free));
    assert!(order.0.iter().all(|p| !matches!(p, ParamId::Base(_))), "unanchored: no base pose");
    assert_eq!(order.0[..9].iter().filter(|p| matches!(p, ParamId::Plane { .. })).count(), 9);
    let without = analyze_design(&truth, &rows, &free, &order).expect("analysis");
    let with = analyze_design(&truth, &rows, &fixed, &order).expect("analysis");
    eprintln!("without the distance:\n{without}\nwith it:\n{with}");
    assert_eq!(with.rank, without.rank + 1, "the distance fixes exactly one direction");
    assert_eq!(with.equation_count, without.equation_count + 3);
    let basis = generic_set(&truth, &rows, GenericSet::Kinematic, &fixed).expect("scale fixed");
    assert!(basis.0.iter().any(|p| matches!(p, ParamId::Plane { id: BLOCK, dof: PlaneDof::Offset })));
    // all-identifiable: the free planes' parameters come first
    let a = resolve_spec("all-identifiable", &truth, &rows, &free).expect("basis");
    assert!(matches!(a.0[0], ParamId::Plane { id: TABLE, .. }), "{a:?}");
}

/// Detmax selects `n` of a pool of plane and tracker rows (the planes unknown): its O1 beats
/// every one of 20 random selections of `n` (seeded).
#[test]
fn detmax_selects_among_plane_and_tracker_rows() {
    let truth = truth(23);
    let mut pool = Vec::new();
    pool.extend(synthetic_plane_contacts(&truth, TABLE, 1, true, 30, 0.0, 31));
    pool.extend(synthetic_plane_contacts(&truth, BLOCK, 1, false, 30, 0.0, 32));
    pool.extend(synthetic_plane_contacts(&truth, WALL, 1, false, 30, 0.0, 33));
    pool.extend(
        synthetic_tracker_measurements(&truth, 300, 0.0, 34).into_iter().filter(|m| m.tcp == 1).take(60),
    );
    assert_eq!(pool.len(), 150);
    let design = DataDesign { free_planes: vec![TABLE, BLOCK, WALL], ..DataDesign::default() };
    let params = resolve_spec("all-identifiable", &truth, &pool, &design).expect("params");
    assert!(params.0.iter().any(|p| matches!(p, ParamId::Plane { .. })), "{params:?}");
    let candidates = Candidates::from_measurements(&truth, &pool, &params).expect("candidates");
    let n = 40;
    let selection = detmax(&candidates, &DetmaxOptions { restarts: 4, seed: 3, ..DetmaxOptions::new(n) })
        .expect("selection");
    let chosen = selection_indices(&candidates, &selection.selected).expect("indices");
    assert!(chosen.raw.is_full_rank(), "rank {}/{}", chosen.raw.rank, chosen.raw.parameter_count);
    let planes = selection.selected.iter().filter(|k| pool[**k].target.is_plane()).count();
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let mut best_random = 0.0_f64;
    for _ in 0..20 {
        let mut idx: Vec<usize> = (0..pool.len()).collect();
        idx.shuffle(&mut rng);
        idx.truncate(n);
        best_random = best_random.max(selection_indices(&candidates, &idx).expect("indices").raw.o1);
    }
    eprintln!(
        "{} params; Detmax O1 {:.4} ({planes} plane rows of {n}); best of 20 random O1 {best_random:.4}",
        params.len(),
        chosen.raw.o1
    );
    assert!(chosen.raw.o1 > best_random, "{} vs {best_random}", chosen.raw.o1);
    // touches give one equation each: 20 of them cannot fix 41 parameters (60 rows would)
    let touches: Vec<usize> = (30..90).collect();
    let e = detmax(&candidates.subset(&touches), &DetmaxOptions::new(20)).expect_err("too few equations");
    assert!(e.to_string().contains("at most 20 equations for 41 parameters"), "{e}");
}
