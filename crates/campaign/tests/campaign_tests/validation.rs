//! The validation campaign on the virtual cell: plan structure, errors of a wrong and of an
//! exact model, resume after an interruption.
//!
//! The hidden truth itself plays the "perfectly calibrated" model here (an oracle), so these
//! tests do not depend on the identification; the demo crate tests the real chain.

use crate::common;

use common::{SimDevices, nominal, paper_cell, quiet_config};
use vatcal_campaign::validation::{
    PrintingPathOptions, RandomPoseOptions, ValidationPlan, ValidationPlanOptions, ValidationRecords,
    build_validation_plan, evaluate, random_validation_poses,
};
use vatcal_campaign::{Campaign, CampaignConfig, CampaignError, CampaignStep, CellDevices};
use vatcal_core::{CellFile, JointVector, Target};
use vatcal_hardware_traits::{Error, ErrorKind, PositionTracker, Result as HwResult};
use vatcal_kinematics::Model;
use vatcal_planning::CellGeometry;
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::ik::rotation_angle_between;
use vatcal_planning::motion::JointBounds;
use vatcal_sim::VirtualCell;

const SEED: u64 = 31;

fn geometry() -> CellGeometry {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture");
    CellGeometry::from_cell(&cell).expect("geometry")
}

/// A small plan: 60 random poses, 60 slices, commanded by the nominal model and by the truth.
fn small_plan(nominal: &Model, truth: &Model) -> ValidationPlan {
    let opts = ValidationPlanOptions {
        random: RandomPoseOptions { count: 60, ..RandomPoseOptions::default() },
        printing: PrintingPathOptions { slices: 60, ..PrintingPathOptions::default() },
        seed: 4,
        ..ValidationPlanOptions::default()
    };
    build_validation_plan(nominal, &geometry(), &[("nominal", nominal), ("truth", truth)], &opts)
        .expect("plan")
}

fn config() -> CampaignConfig {
    CampaignConfig { sync_journal_each_step: false, ..quiet_config() }
}

fn smrs(model: &Model) -> Vec<(u32, nalgebra::Vector3<f64>)> {
    model.tcp_ids().into_iter().map(|id| (id, model.tcp(id).expect("tcp"))).collect()
}

#[test]
fn random_poses_are_seeded_inside_the_margins_and_collision_free() {
    let model = nominal();
    let g = geometry();
    let checker = CollisionChecker::new(&model, &g, 2.0).expect("checker");
    let opts = RandomPoseOptions { count: 200, ..RandomPoseOptions::default() };
    let poses = random_validation_poses(&model, &checker, &opts, 9).expect("poses");
    assert_eq!(poses, random_validation_poses(&model, &checker, &opts, 9).expect("again"));
    assert_ne!(poses, random_validation_poses(&model, &checker, &opts, 10).expect("other seed"));
    let bounds = JointBounds::new(&model, 5.0, 5.0).expect("bounds");
    let mut per_tcp = [0usize; 4];
    for p in &poses {
        assert!(bounds.contains(&p.q), "{:?}", p.q.to_mm_deg());
        assert!(checker.is_free(&p.q, ProbeState::Absent));
        per_tcp[p.tcp as usize] += 1;
    }
    // every SMR is used (uniform choice among the three)
    assert!(per_tcp[1..].iter().all(|n| *n > 40), "{per_tcp:?}");
    // the whole workspace: every arm joint spans most of its range
    for k in 1..7 {
        let (lo, hi) = bounds.bounds[k];
        let min = poses.iter().map(|p| p.q[k]).fold(f64::INFINITY, f64::min);
        let max = poses.iter().map(|p| p.q[k]).fold(f64::NEG_INFINITY, f64::max);
        assert!(max - min > 0.6 * (hi - lo), "joint {} spans {min}..{max}", k + 1);
    }
}

#[test]
fn the_plan_measures_every_pose_and_slice_along_verified_paths() {
    let model = nominal();
    let truth = paper_cell(SEED).truth();
    let plan = small_plan(&model, &truth);
    assert_eq!(plan.random_poses.len(), 60);
    assert_eq!(plan.slices.len(), 60);
    assert_eq!(plan.path_runs.len(), 2);
    assert_eq!(plan.measurement_count(), 60 + 2 * 60 * 3);
    plan.campaign.validate(&model).expect("valid campaign plan");
    // each model's joints put ITS tool on the intended pose (the IK is done on that model)
    for (run, m) in plan.path_runs.iter().zip([&model, &truth]) {
        for (q, slice) in run.joints.iter().zip(&plan.slices) {
            let tool = m.chain(q).tool;
            assert!((tool.p - slice.tool_pose.p).norm() < 1e-8, "{}", run.label);
            assert!(rotation_angle_between(&tool.r, &slice.tool_pose.r) < 1e-10);
        }
        // the guide lifts by one layer per slice
        let lift = run.joints[59].guide_mm() - run.joints[0].guide_mm();
        assert!((lift - 59.0 * 0.1).abs() < 1e-9, "{lift}");
    }
    // the two runs differ by the model error (small joint corrections, same branch)
    let dq = plan.path_runs[0]
        .joints
        .iter()
        .zip(&plan.path_runs[1].joints)
        .map(|(a, b)| (1..7).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max));
    let dq_max = dq.fold(0.0, f64::max);
    assert!(dq_max > 1e-5 && dq_max < 0.05, "{dq_max} rad");
    // every move ends on the planned pose of the following track steps, and consecutive
    // waypoints are collision-free straight segments
    let g = geometry();
    let checker = CollisionChecker::new(&model, &g, 2.0).expect("checker");
    let res = vatcal_planning::motion::Resolution::default();
    let mut prev: Option<JointVector> = None;
    for step in &plan.campaign.steps {
        if let CampaignStep::Move { path } = step {
            for q in path {
                if let Some(p) = prev {
                    assert!(vatcal_planning::paths::segment_is_free(
                        &checker,
                        &p,
                        q,
                        ProbeState::Absent,
                        &res
                    ));
                }
                prev = Some(*q);
            }
        }
    }
}

#[test]
fn an_exact_model_is_validated_at_the_noise_floor_and_the_nominal_one_is_not() {
    let model = nominal();
    let cell = paper_cell(SEED);
    let truth = cell.truth();
    let plan = small_plan(&model, &truth);
    let dir = tempfile::tempdir().expect("tmp");
    let mut d = SimDevices::of(&cell);
    let records = plan
        .run(&mut Campaign::new(d.devices(), &model, config()), dir.path().join("v.journal"))
        .expect("run");
    assert_eq!(records.random.len(), 60);
    assert!(records.random.iter().zip(&plan.random_poses).all(|(m, p)| m.q == p.q && m.tcp == p.tcp));
    let results = evaluate(&records, &plan.slices, &[("nominal", &model), ("truth", &truth)], &smrs(&model))
        .expect("evaluate");
    let (nom, exact) = (&results[0], &results[1]);
    let (nom_path, exact_path) = (nom.path.as_ref().expect("path"), exact.path.as_ref().expect("path"));
    eprintln!("nominal: random {} | path {}", nom.random.stats.one_line(), nom_path.tip_stats.one_line());
    eprintln!("exact:   random {} | path {}", exact.random.stats.one_line(), exact_path.tip_stats.one_line());
    // tracker noise 20 µm (3σ per axis), robot 5 µm, tool changer 5 µm
    assert!(
        exact.random.stats.mean < 0.02 && exact.random.stats.max < 0.05,
        "{}",
        exact.random.stats.one_line()
    );
    assert!(exact_path.tip_stats.mean < 0.03 && exact_path.tip_stats.max < 0.08);
    assert!(nom.random.stats.mean > 0.3 && nom_path.tip_stats.mean > 0.3);
    // the orientation of the plate: the nominal model tilts it by a few hundredths of a degree
    let tilt = nom_path.orientation_errors_rad.iter().sum::<f64>() / 60.0;
    let exact_tilt = exact_path.orientation_errors_rad.iter().sum::<f64>() / 60.0;
    assert!(tilt > 5.0 * exact_tilt, "{tilt} vs {exact_tilt} rad");
    // the tracker measured what the physics did: its readings agree with the truth's FK within
    // the noise
    for m in &records.random {
        let Target::Tracker { xyz_mm } = m.target else { panic!("tracker measurement") };
        assert!((xyz_mm - truth.tcp_position(&m.q, m.tcp).expect("fk")).norm() < 0.05);
    }
}

/// A tracker that loses the line of sight at its `n`-th measurement.
struct FailingTracker<T> {
    inner: T,
    remaining: usize,
}

impl<T: PositionTracker> PositionTracker for FailingTracker<T> {
    fn measure_mm(&mut self, target: u32) -> HwResult<nalgebra::Vector3<f64>> {
        if self.remaining == 0 {
            return Err(Error::new(ErrorKind::OutOfRange, "test tracker", "SMR not visible"));
        }
        self.remaining -= 1;
        self.inner.measure_mm(target)
    }
}

fn run_fresh(plan: &ValidationPlan, journal: &std::path::Path) -> ValidationRecords {
    let model = nominal();
    let cell = paper_cell(SEED);
    let mut d = SimDevices::of(&cell);
    plan.run(&mut Campaign::new(d.devices(), &model, config()), journal).expect("run")
}

#[test]
fn an_interrupted_validation_resumes_to_the_same_measurements() {
    let model = nominal();
    let truth = paper_cell(SEED).truth();
    let plan = small_plan(&model, &truth);
    let dir = tempfile::tempdir().expect("tmp");
    let reference = run_fresh(&plan, &dir.path().join("reference.journal"));

    let journal = dir.path().join("interrupted.journal");
    {
        let cell = paper_cell(SEED);
        let mut d = SimDevices::of(&cell);
        let mut tracker = FailingTracker { inner: cell.tracker(), remaining: 100 };
        let devices = CellDevices { tracker: Some(&mut tracker), ..d.devices() };
        let e = plan
            .run(&mut Campaign::new(devices, &model, config()), &journal)
            .expect_err("line of sight lost");
        assert!(
            matches!(&e, vatcal_campaign::validation::ValidationError::Campaign(c)
                if matches!(**c, CampaignError::Device { ref source, .. } if source.kind() == ErrorKind::OutOfRange)),
            "{e}"
        );
    }
    // a new session (fresh virtual cell, same seed) resumes the journal
    let cell = VirtualCell::paper(nominal(), SEED);
    let mut d = SimDevices::of(&cell);
    let resumed = plan.run(&mut Campaign::new(d.devices(), &model, config()), &journal).expect("resume");
    assert_eq!(resumed.random.len(), reference.random.len());
    for (a, b) in resumed.random.iter().zip(&reference.random) {
        assert_eq!((a.tcp, a.q), (b.tcp, b.q));
    }
    assert_eq!(resumed.paths.len(), 2);
    let results = evaluate(&resumed, &plan.slices, &[("truth", &truth)], &smrs(&model)).expect("evaluate");
    assert!(results[0].path.as_ref().expect("path").tip_stats.mean < 0.03);
}
