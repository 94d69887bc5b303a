//! Candidate generation: every candidate independently verified; orientation distribution.

use crate::common;

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use vatcal_core::deg_to_rad;
use vatcal_kinematics::Model;
use vatcal_planning::candidates::{
    CandidateOptions, CandidateSet, generate_candidates, guide_positions, sample_orientation,
};
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::motion::{Resolution, SingularityMargins};
use vatcal_planning::paths::segment_is_free;

fn small_options(seed: u64) -> CandidateOptions {
    CandidateOptions { orientations: 12, guide_steps: 6, seed, ..CandidateOptions::default() }
}

fn generate(model: &Model, opts: &CandidateOptions) -> CandidateSet {
    let geometry = CellGeometry::from_cell(&common::cell()).expect("geometry");
    let checker = CollisionChecker::new(model, &geometry, opts.collision_margin_mm).expect("checker");
    generate_candidates(model, &checker, opts).expect("candidates")
}

/// The acceptance check of issue 6, done with the model and a fresh checker only.
fn verify_every_candidate(model: &Model, set: &CandidateSet, opts: &CandidateOptions) {
    let geometry = CellGeometry::from_cell(&common::cell()).expect("geometry");
    let checker = CollisionChecker::new(model, &geometry, opts.collision_margin_mm).expect("checker");
    let limits = model.joint_limits();
    let margin = deg_to_rad(opts.joint_margin_deg);
    for c in &set.candidates {
        let tcp = model.tcp_position(&c.q, c.tcp).expect("fk");
        let err = (tcp - model.position(c.position).expect("position")).norm();
        assert!(err < 1e-6, "candidate {c:?}: TCP {err} mm from the calibration position");
        for (k, (lo, hi)) in limits.iter().enumerate().skip(1) {
            assert!(
                c.q[k] >= lo + margin - 1e-12 && c.q[k] <= hi - margin + 1e-12,
                "joint {} of {c:?}",
                k + 1
            );
        }
        assert!((limits[0].0..=limits[0].1).contains(&c.q[0]));
        assert!(opts.singularity.clear(model, &model.chain(&c.q)));
        let measuring = ProbeState::Measuring { position: c.position, tcp: c.tcp };
        assert!(checker.is_free(&c.q, measuring), "{c:?} collides: {:?}", checker.check(&c.q, measuring));
        // the retreat pose: same orientation, ball 30 mm straight above, clear of every probe placement
        let above = model.tcp_position(&c.retreat, c.tcp).expect("fk");
        assert!((above - tcp - nalgebra::Vector3::new(0.0, 0.0, opts.retreat_height_mm)).norm() < 1e-6);
        assert!(checker.is_free(&c.retreat, ProbeState::Everywhere));
        assert!(segment_is_free(&checker, &c.retreat, &c.q, measuring, &Resolution::default()));
    }
}

#[test]
fn every_nominal_candidate_is_verifiable() {
    let model = common::nominal();
    let opts = small_options(11);
    let set = generate(&model, &opts);
    let c = set.counts;
    assert_eq!(c.poses, 12 * 9);
    assert!(c.ik_solutions <= 8 * 6 * c.poses);
    assert!(c.ik_solutions >= c.within_limits && c.within_limits >= c.clear_of_singularities);
    assert!(c.clear_of_singularities >= c.collision_free && c.collision_free >= c.retreat_clear);
    assert_eq!(c.retreat_clear, set.candidates.len());
    assert!(set.candidates.len() > 50, "{c:?}");
    for p in model.position_ids() {
        assert!(set.candidates.iter().any(|x| x.position == p), "no candidate at position {p}");
    }
    verify_every_candidate(&model, &set, &opts);
}

#[test]
fn candidates_of_a_calibrated_model_hit_its_positions() {
    let model = common::perturbed(5);
    let opts = small_options(12);
    let set = generate(&model, &opts);
    assert!(set.candidates.len() > 50, "{:?}", set.counts);
    verify_every_candidate(&model, &set, &opts);
}

#[test]
fn generation_is_deterministic() {
    let model = common::nominal();
    let a = generate(&model, &small_options(3));
    let b = generate(&model, &small_options(3));
    assert_eq!(a, b);
    let c = generate(&model, &small_options(4));
    assert_ne!(a.candidates, c.candidates);
}

#[test]
fn stricter_margins_never_add_candidates() {
    let model = common::nominal();
    let base = small_options(8);
    let strict = CandidateOptions {
        joint_margin_deg: 15.0,
        singularity: SingularityMargins { wrist_deg: 25.0, ..SingularityMargins::default() },
        ..base.clone()
    };
    let (a, b) = (generate(&model, &base), generate(&model, &strict));
    assert!(b.counts.within_limits < a.counts.within_limits);
    for c in &b.candidates {
        assert!(a.candidates.contains(c));
    }
}

#[test]
fn guide_positions_span_the_stroke() {
    let model = common::nominal();
    let g = guide_positions(&model, 10, 5.0).expect("ok");
    assert_eq!(g.len(), 10);
    assert!((g[0] - 5.0).abs() < 1e-12 && (g[9] - 295.0).abs() < 1e-12);
    assert_eq!(guide_positions(&model, 1, 5.0).expect("ok"), vec![150.0]);
    assert!(guide_positions(&model, 0, 5.0).is_err());
    assert!(guide_positions(&model, 3, 200.0).is_err());
}

#[test]
fn bad_options_are_rejected() {
    let model = common::nominal();
    let geometry = CellGeometry::default();
    let checker = CollisionChecker::new(&model, &geometry, 0.0).expect("checker");
    for opts in [
        CandidateOptions { orientations: 0, ..CandidateOptions::default() },
        CandidateOptions { cone_half_angle_deg: 0.0, ..CandidateOptions::default() },
        CandidateOptions { positions: Some(vec![9]), ..CandidateOptions::default() },
        CandidateOptions { tcps: Some(vec![]), ..CandidateOptions::default() },
        CandidateOptions { retreat_height_mm: f64::NAN, ..CandidateOptions::default() },
    ] {
        assert!(generate_candidates(&model, &checker, &opts).is_err(), "{opts:?}");
    }
}

/// The orientation sampler: ball-to-flange direction uniform on the cap (cos of its angle to
/// +z uniform on [cos(cone), 1], azimuth uniform), spin about it uniform.
#[test]
fn orientation_distribution_is_uniform_on_the_cap() {
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let u = nalgebra::Vector3::new(56.78, -30.515, -67.113).normalize(); // -t_1
    let cone = 60f64.to_radians();
    let n = 20_000;
    let (mut sum_cos, mut sum_az_cos, mut sum_spin_cos) = (0.0, 0.0, 0.0);
    for _ in 0..n {
        let r = sample_orientation(&mut rng, &u, cone);
        let a = r * u;
        assert!((r.transpose() * r - nalgebra::Matrix3::identity()).norm() < 1e-12);
        assert!(a.z >= cone.cos() - 1e-12, "direction {a} outside the cone");
        sum_cos += a.z;
        sum_az_cos += a.y.atan2(a.x).cos();
        // spin: angle of the tool x axis projected on the plane normal to a
        let x = r.column(0).into_owned();
        let ref_axis = a.cross(&nalgebra::Vector3::x()).normalize();
        let proj = (x - a * x.dot(&a)).normalize();
        sum_spin_cos += proj.dot(&ref_axis);
    }
    let nf = n as f64;
    let expected_cos = 0.5 * (1.0 + cone.cos());
    // standard error of each mean is < 0.01
    assert!((sum_cos / nf - expected_cos).abs() < 0.01, "mean cos {}", sum_cos / nf);
    assert!((sum_az_cos / nf).abs() < 0.02, "azimuth not uniform");
    assert!((sum_spin_cos / nf).abs() < 0.02, "spin not uniform");
}
