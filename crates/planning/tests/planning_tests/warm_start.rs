//! Warm-started numerical IK (issue 31 item 5): `NumericIk::solve_warm` stops once it has as
//! many solutions as the neighbour it started from, `ModelIk::solve_at_guide_warm` continues a
//! guide step from the previous one, and the candidate generator's warm chains are
//! deterministic (also on one thread) and find nearly every solution the cold multi-start finds.

use super::ik::pose_errors;
use crate::common;

use vatcal_core::{CellFile, JointVector};
use vatcal_kinematics::Model;
use vatcal_planning::candidates::{Candidate, CandidateOptions, CandidateSet, IkChoice, generate_candidates};
use vatcal_planning::collision::CollisionChecker;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::ik::{ChainTool, ModelIk, RefineOptions, wrap_angle};
use vatcal_planning::numeric_ik::{IkTarget, JointSpec, MultiStartOptions, NumericIk};

fn fixture(name: &str) -> (CellFile, Model) {
    let path = format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    let cell = CellFile::load(&path).expect("fixture");
    let model = Model::from_cell(&cell).expect("model");
    (cell, model)
}

fn same(a: &JointVector, b: &JointVector) -> bool {
    a.as_slice().iter().zip(b.as_slice()).all(|(x, y)| wrap_angle(x - y).abs() < 1e-6)
}

/// The UR5e's six joints as the numerical IK sees them.
fn ur5e_numeric(model: &Model) -> NumericIk<ChainTool<'_>> {
    let tool =
        ChainTool { model, fixed: JointVector::zeros(6), free: (1..=6).collect(), revolute: vec![true; 6] };
    let joints: Vec<JointSpec> =
        model.joint_limits().iter().map(|(lo, hi)| JointSpec::revolute(*lo, *hi)).collect();
    NumericIk::new(tool, &joints, MultiStartOptions::default()).expect("numeric ik")
}

#[test]
fn solve_warm_stops_at_the_neighbours_count() {
    let (_, model) = fixture("ur5e.toml");
    let ik = ur5e_numeric(&model);
    let q = JointVector::from_slice(&[0.3, -1.2, 1.1, -0.8, 1.4, 0.6]).expect("joints");
    let target = model.chain(&q).tool;
    let cold = ik.solve(&IkTarget::Pose(target));
    assert!(cold.solutions.len() >= 4, "{}", cold.solutions.len());
    assert_eq!(cold.starts, ik.starts().len());
    // a neighbouring pose: the same joints 3 degrees further on every joint
    let near =
        JointVector::from_slice(&q.as_slice().iter().map(|v| v + 0.05).collect::<Vec<_>>()).expect("q");
    let near_target = model.chain(&near).tool;
    let warm: Vec<&[f64]> = cold.joints().collect();
    let out = ik.solve_warm(&IkTarget::Pose(near_target), &warm, warm.len());
    assert_eq!(out.solutions.len(), cold.solutions.len(), "every branch continued");
    assert_eq!(out.starts, warm.len(), "one local solve per branch, no fixed start");
    for s in out.joints() {
        let qs = JointVector::from_slice(s).expect("q");
        let (dp, dr) = pose_errors(&model, &qs, &near_target);
        assert!(dp < 1e-9 && dr < 1e-12, "{dp} mm, {dr} rad");
    }
    assert!(out.joints().any(|s| same(&JointVector::from_slice(s).expect("q"), &near)), "generating joints");
    // enough = 0: every start, as solve_from
    let all = ik.solve_warm(&IkTarget::Pose(near_target), &warm, 0);
    assert_eq!(all.starts, warm.len() + ik.starts().len());
    assert!(all.solutions.len() >= out.solutions.len());
    // a lost branch (two warm starts on one solution) falls back to the fixed starts
    let doubled = vec![warm[0], warm[0]];
    let out = ik.solve_warm(&IkTarget::Pose(near_target), &doubled, 2);
    assert_eq!(out.solutions.len(), 2);
    assert!(out.starts > 2);
}

#[test]
fn a_guide_step_is_continued_from_the_previous_one() {
    // the canonical cell through the numerical IK (its guide held at each position), checked
    // against its closed form (complete)
    let model = common::nominal();
    let ik = ModelIk::numerical(&model, MultiStartOptions::default()).expect("ik");
    let closed = ModelIk::new(&model, RefineOptions::default(), MultiStartOptions::default()).expect("ik");
    let q = JointVector::from_mm_deg(120.0, [30.0, 20.0, -40.0, 50.0, 60.0, -70.0]);
    let target = model.chain(&q).tool;
    let first = ik.solve_at_guide(120.0, &target);
    assert!(!first.is_empty());
    for guide in [130.0, 150.0] {
        let cold = ik.solve_at_guide(guide, &target);
        let warm = ik.solve_at_guide_warm(guide, &target, &first, first.len());
        assert!(!warm.is_empty());
        for s in &warm {
            assert_eq!(s[0], guide, "the guide is held");
            let (dp, dr) = pose_errors(&model, s, &target);
            assert!(dp < 1e-9 && dr < 1e-12, "{dp} mm, {dr} rad");
            let exact = closed.solve_at_guide(guide, &target);
            assert!(exact.iter().any(|c| same(c, s)), "guide {guide}: {s:?} not a closed-form solution");
        }
        assert!(warm.len() + 1 >= cold.len(), "guide {guide}: {} warm vs {} cold", warm.len(), cold.len());
    }
    // a closed form ignores the warm starts
    assert_eq!(closed.solve_at_guide_warm(150.0, &target, &first, 1), closed.solve_at_guide(150.0, &target));
}

fn candidates(model: &Model, geometry: &CellGeometry, ik: IkChoice, warm_start: bool) -> CandidateSet {
    let checker = CollisionChecker::new(model, geometry, 2.0).expect("checker");
    let opts = CandidateOptions { orientations: 30, ik, warm_start, seed: 5, ..CandidateOptions::default() };
    generate_candidates(model, &checker, &opts).expect("candidates")
}

#[test]
fn warm_chains_are_deterministic_and_find_nearly_every_solution() {
    let (cell, model) = fixture("ur5e.toml");
    let geometry = CellGeometry::from_cell(&cell).expect("geometry");
    let numeric = IkChoice::Numerical;
    let warm = candidates(&model, &geometry, numeric, true);
    let cold = candidates(&model, &geometry, numeric, false);
    // the UR5e's closed form has every solution (8 per pose with its +-360 deg limits)
    let exact = candidates(&model, &geometry, IkChoice::ClosedFormFirst, true);
    eprintln!("warm {:?}\ncold {:?}\nclosed form {:?}", warm.counts, cold.counts, exact.counts);
    // independent of the thread count and of the run
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
    let single = pool.install(|| candidates(&model, &geometry, numeric, true));
    assert_eq!(warm, single);
    assert_eq!(warm, candidates(&model, &geometry, numeric, true));
    // every candidate a closed-form one, in the cold order (position, TCP, orientation)
    let key = |c: &Candidate| (c.position, c.tcp, c.orientation);
    for c in &warm.candidates {
        assert!(exact.candidates.iter().any(|e| key(e) == key(c) && same(&e.q, &c.q)), "{c:?}");
    }
    assert!(warm.candidates.windows(2).all(|w| key(&w[0]) <= key(&w[1])));
    // nearly every solution (270 poses): as many as the cold multi-start, within 1 %
    let (w, c, e) = (warm.counts, cold.counts, exact.counts);
    assert_eq!(w.poses, c.poses);
    assert_eq!(e.ik_solutions, 8 * e.poses);
    for (what, a, b) in
        [("IK solutions", w.ik_solutions, c.ik_solutions), ("candidates", w.retreat_clear, c.retreat_clear)]
    {
        assert!(a as f64 >= 0.99 * b as f64, "{what}: warm {a}, cold {b}");
    }
    assert!(w.ik_solutions as f64 >= 0.95 * e.ik_solutions as f64, "{w:?}");
}

#[test]
fn solutions_of_a_far_neighbour_are_only_starts() {
    // warm starts from an unrelated pose: the fixed starts still find the branches
    let (_, model) = fixture("ur5e.toml");
    let ik = ur5e_numeric(&model);
    let q = JointVector::from_slice(&[0.3, -1.2, 1.1, -0.8, 1.4, 0.6]).expect("joints");
    let other = JointVector::from_slice(&[-2.0, -0.4, -1.5, 2.0, -0.7, 2.5]).expect("joints");
    let far = ik.solve(&IkTarget::Pose(model.chain(&other).tool));
    let target = model.chain(&q).tool;
    let warm: Vec<&[f64]> = far.joints().collect();
    let out = ik.solve_warm(&IkTarget::Pose(target), &warm, warm.len());
    let cold = ik.solve(&IkTarget::Pose(target));
    assert!(
        out.solutions.len() >= warm.len().min(cold.solutions.len()),
        "{} vs {}",
        out.solutions.len(),
        cold.solutions.len()
    );
}
