//! The campaign runner on the virtual cell: complete runs, resume after an interruption and a
//! torn journal record, plan mismatch, skipped measurements, warm-up, CSV output.

use crate::common;

use std::time::Duration;

use common::{
    SimDevices, assert_close_measurements, assert_same_measurements, nominal, paper_cell, plan, quiet_config,
};
use nalgebra::Vector3;
use vatcal_campaign::{
    Campaign, CampaignConfig, CampaignError, CampaignPlan, CampaignStep, CellDevices, Journal, StepOutcome,
    WarmUp, export_measurements,
};
use vatcal_core::{JointVector, Measurement};
use vatcal_hardware_traits::{
    ArmJoints, ArmStatus, Clock, Error, ErrorKind, LinearFrame, MotionOptions, Operator, OperatorInstruction,
    Result as HwResult, RobotArm, Thermometer,
};
use vatcal_sim::VirtualCell;

const SEED: u64 = 2024;

fn run(
    cell: &VirtualCell,
    plan: &CampaignPlan,
    journal: &std::path::Path,
    config: CampaignConfig,
) -> Result<vatcal_campaign::CampaignReport, CampaignError> {
    let model = nominal();
    let mut d = SimDevices::of(cell);
    Campaign::new(d.devices(), &model, config).run(plan, journal)
}

#[test]
fn a_complete_campaign_records_centred_joints_with_time_and_direction() {
    let dir = tempfile::tempdir().expect("tmp");
    let journal = dir.path().join("campaign.journal");
    let plan = plan(9, 1);
    let cell = paper_cell(SEED);
    let live_csv = dir.path().join("live.csv");
    let config = CampaignConfig { measurements_csv: Some(live_csv.clone()), ..quiet_config() };
    let report = run(&cell, &plan, &journal, config).expect("campaign");
    assert_eq!(report.measurements.len(), plan.measurement_count());
    assert_eq!(report.resumed_at_step, None);
    assert_eq!(report.records.len(), plan.steps.len());
    let truth = cell.truth();
    let nominal = nominal();
    let mut last_time = -1.0;
    for m in &report.measurements {
        // the recorded joints put the TRUE ball on the TRUE probe origin (within the budget)...
        let r_true = truth.residual(m).expect("residual").norm();
        assert!(r_true < 0.015, "true residual {r_true} mm");
        // ...while the nominal model disagrees: the data calibration needs
        assert!(nominal.residual(m).expect("residual").norm() > 0.1);
        let t = m.context.time_s.expect("time_s");
        assert!(t > last_time);
        last_time = t;
        let dir = &m.context.dir.expect("dir")[1..7];
        assert!(dir.iter().all(|d| *d == 1 || *d == -1), "every arm joint has moved: {dir:?}");
    }
    // the campaign's direction record agrees with the physics' at the end
    assert_eq!(report.records.last().expect("last").state.dir, cell.motion_directions());
    // one header + one line per step in the journal
    let lines = std::fs::read_to_string(&journal).expect("read").lines().count();
    assert_eq!(lines, 1 + plan.steps.len());
    // CSV in the probe-measurement format, read back through vatcal-io
    let csv = dir.path().join("measurements.csv");
    assert_eq!(export_measurements(&journal, &csv).expect("export"), report.measurements.len());
    let header = std::fs::read_to_string(&csv).expect("csv").lines().next().expect("header").to_string();
    assert_eq!(
        header,
        "position,tcp,q1,q2,q3,q4,q5,q6,q7,time_s,dir2,dir3,dir4,dir5,dir6,dir7,offset_x_mm,offset_y_mm,offset_z_mm"
    );
    let back = vatcal_io::read_probe_measurements(&csv, &nominal).expect("read csv");
    assert_close_measurements(&back, &report.measurements);
    assert_eq!(
        std::fs::read(&live_csv).expect("live csv"),
        std::fs::read(&csv).expect("csv"),
        "kept up to date"
    );
    // virtual time: 3 plate placements (60 s each) plus motions
    let elapsed = cell.clock().now_s();
    assert!(elapsed > 180.0 && elapsed < 3600.0, "{elapsed} s");
}

/// An operator that refuses the `n`-th instruction (like pressing `abort`).
struct AbortAt<O> {
    inner: O,
    remaining: usize,
}

impl<O: Operator> Operator for AbortAt<O> {
    fn perform(&mut self, instruction: &OperatorInstruction) -> HwResult<()> {
        if self.remaining == 0 {
            return Err(Error::new(ErrorKind::Cancelled, "test operator", "abort"));
        }
        self.remaining -= 1;
        self.inner.perform(instruction)
    }
}

#[test]
fn an_interrupted_campaign_resumes_to_the_same_measurements() {
    let dir = tempfile::tempdir().expect("tmp");
    let plan = plan(9, 2);
    let reference =
        run(&paper_cell(SEED), &plan, &dir.path().join("ref.journal"), quiet_config()).expect("reference");

    let journal = dir.path().join("interrupted.journal");
    {
        // first session: the operator aborts at the third plate placement
        let cell = paper_cell(SEED);
        let model = nominal();
        let mut d = SimDevices::of(&cell);
        let mut operator = AbortAt { inner: cell.operator(), remaining: 2 };
        let devices = CellDevices { operator: &mut operator, ..d.devices() };
        let e = Campaign::new(devices, &model, quiet_config()).run(&plan, &journal).expect_err("aborted");
        assert!(
            matches!(e, CampaignError::Device { ref source, .. } if source.kind() == ErrorKind::Cancelled),
            "{e}"
        );
    }
    let done = Journal::open(&journal).expect("journal").records().len();
    assert!(done > 3 && done < plan.steps.len(), "{done} steps done");
    // a crash in the middle of the next write leaves a torn record behind
    let mut bytes = std::fs::read(&journal).expect("read");
    bytes.extend_from_slice(b"0123456789abcdef {\"record\":\"step\",\"step\":");
    std::fs::write(&journal, bytes).expect("tear");

    // second session: a new process (fresh cell, same seed), same plan, same journal
    let cell = paper_cell(SEED);
    let resumed = run(&cell, &plan, &journal, quiet_config()).expect("resumed");
    assert_eq!(resumed.resumed_at_step, Some(done));
    assert!(resumed.torn_bytes_dropped > 0);
    assert_same_measurements(&resumed.measurements, &reference.measurements);
    let times: Vec<f64> = resumed.measurements.iter().map(|m| m.context.time_s.expect("t")).collect();
    assert!(times.windows(2).all(|w| w[1] > w[0]), "time never goes back: {times:?}");
    // the journal now holds every step exactly once
    let steps: Vec<usize> =
        Journal::open(&journal).expect("journal").records().iter().map(|r| r.step).collect();
    assert_eq!(steps, (0..plan.steps.len()).collect::<Vec<_>>());

    // resuming a finished journal does nothing and returns the same set
    let again = run(&paper_cell(SEED), &plan, &journal, quiet_config()).expect("again");
    assert_same_measurements(&again.measurements, &reference.measurements);
}

/// An arm whose connection drops at its `n`-th relative linear move (inside auto-centering).
struct DropsAt<A> {
    inner: A,
    remaining: usize,
}

impl<A: RobotArm> RobotArm for DropsAt<A> {
    fn joint_count(&self) -> usize {
        self.inner.joint_count()
    }
    fn activate_and_home(&mut self, timeout: Duration) -> HwResult<()> {
        self.inner.activate_and_home(timeout)
    }
    fn status(&mut self) -> HwResult<ArmStatus> {
        self.inner.status()
    }
    fn joints(&mut self) -> HwResult<ArmJoints> {
        self.inner.joints()
    }
    fn move_joints(&mut self, target: &ArmJoints, options: &MotionOptions) -> HwResult<()> {
        self.inner.move_joints(target, options)
    }
    fn move_linear_relative(
        &mut self,
        d: &Vector3<f64>,
        frame: LinearFrame,
        options: &MotionOptions,
    ) -> HwResult<()> {
        if self.remaining == 0 {
            return Err(Error::new(ErrorKind::Disconnected, "test arm", "connection reset"));
        }
        self.remaining -= 1;
        self.inner.move_linear_relative(d, frame, options)
    }
    fn wait_idle(&mut self, timeout: Duration) -> HwResult<()> {
        self.inner.wait_idle(timeout)
    }
    fn stop(&mut self) -> HwResult<()> {
        self.inner.stop()
    }
    fn reset_error(&mut self) -> HwResult<()> {
        self.inner.reset_error()
    }
}

#[test]
fn a_connection_lost_during_centering_resumes_to_the_same_measurements() {
    let dir = tempfile::tempdir().expect("tmp");
    let plan = plan(6, 6);
    let reference =
        run(&paper_cell(SEED), &plan, &dir.path().join("ref.journal"), quiet_config()).expect("reference");
    // the linear corrections of the whole run: drop the connection at the first, one in the
    // middle and the last
    let corrections: usize = reference
        .records
        .iter()
        .map(|r| match r.outcome {
            StepOutcome::Measured { iterations, .. } => iterations,
            _ => 0,
        })
        .sum();
    assert!(corrections >= 3, "{corrections} corrections");
    for drop_at in [0, corrections / 2, corrections - 1] {
        let journal = dir.path().join(format!("drop{drop_at}.journal"));
        {
            let cell = paper_cell(SEED);
            let model = nominal();
            let mut d = SimDevices::of(&cell);
            let mut arm = DropsAt { inner: cell.arm(), remaining: drop_at };
            let devices = CellDevices { arm: &mut arm, ..d.devices() };
            let e = Campaign::new(devices, &model, quiet_config()).run(&plan, &journal).expect_err("dropped");
            assert!(matches!(e, CampaignError::Centering { .. }), "{e}");
        }
        let resumed = run(&paper_cell(SEED), &plan, &journal, quiet_config()).expect("resumed");
        let at = resumed.resumed_at_step.expect("resumed");
        assert!(matches!(plan.steps[at], CampaignStep::Measure { .. }), "crashed inside a measurement");
        assert_same_measurements(&resumed.measurements, &reference.measurements);
    }
}

#[test]
fn a_journal_only_resumes_its_own_plan() {
    let dir = tempfile::tempdir().expect("tmp");
    let journal = dir.path().join("j");
    let first = plan(3, 3);
    run(&paper_cell(SEED), &first, &journal, quiet_config()).expect("first");
    let other = plan(3, 4);
    let e = run(&paper_cell(SEED), &other, &journal, quiet_config()).expect_err("mismatch");
    assert!(matches!(e, CampaignError::PlanMismatch { .. }), "{e}");
}

#[test]
fn invalid_plans_are_refused_before_anything_moves() {
    let dir = tempfile::tempdir().expect("tmp");
    let cell = paper_cell(SEED);
    let bad = CampaignPlan { steps: vec![CampaignStep::Measure { position: 1, tcp: 1 }] };
    let e = run(&cell, &bad, &dir.path().join("a"), quiet_config()).expect_err("no plate");
    assert!(e.to_string().contains("add a place_probe step"), "{e}");
    let beyond = CampaignPlan {
        steps: vec![CampaignStep::Move { path: vec![JointVector::from_mm_deg(350.0, [0.0; 6])] }],
    };
    let e = run(&cell, &beyond, &dir.path().join("b"), quiet_config()).expect_err("limits");
    assert!(e.to_string().contains("q1 = 350"), "{e}");
    // a probe without a placement for position 1
    let model = nominal();
    let mut d = SimDevices::of(&cell);
    let mut config = cell.probe_config();
    config.placements.retain(|p| p.position != 1);
    let mut probe = vatcal_hardware_traits::TriCal::new(cell.gauges(), config).expect("probe");
    let devices = CellDevices { probe: &mut probe, ..d.devices() };
    let e = Campaign::new(devices, &model, quiet_config())
        .run(&plan(3, 1), dir.path().join("c"))
        .expect_err("placement");
    assert!(matches!(e, CampaignError::NoProbePlacement { position: 1 }), "{e}");
    assert!(
        !dir.path().join("a").exists() && !dir.path().join("b").exists() && !dir.path().join("c").exists(),
        "no journal for a refused plan"
    );
    assert_eq!(cell.clock().now(), Duration::ZERO, "nothing moved");
}

#[test]
fn unsafe_measurements_can_be_skipped_and_the_campaign_goes_on() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut plan = plan(6, 5);
    // push the approach pose of the first measurement 30° off on joint 2: the ball misses the probe
    let first_move =
        plan.steps.iter().position(|s| matches!(s, CampaignStep::Measure { .. })).expect("measure") - 1;
    if let CampaignStep::Move { path } = &mut plan.steps[first_move] {
        path[0][1] += 0.5;
    }
    let strict =
        run(&paper_cell(SEED), &plan, &dir.path().join("strict"), quiet_config()).expect_err("stops");
    assert!(matches!(strict, CampaignError::Centering { .. }), "{strict}");
    let lenient = CampaignConfig { skip_failed_measurements: true, ..quiet_config() };
    let report = run(&paper_cell(SEED), &plan, &dir.path().join("lenient"), lenient).expect("goes on");
    assert_eq!(report.skipped, 1);
    assert_eq!(report.measurements.len(), plan.measurement_count() - 1);
    assert!(
        report
            .records
            .iter()
            .any(|r| matches!(&r.outcome, StepOutcome::Skipped { reason } if reason.contains("probe")))
    );
}

#[test]
fn warm_up_and_tracker_steps() {
    let dir = tempfile::tempdir().expect("tmp");
    let cell = paper_cell(SEED);
    let q = JointVector::from_mm_deg(100.0, [10.0, 20.0, -20.0, 5.0, 30.0, 0.0]);
    let plan =
        CampaignPlan { steps: vec![CampaignStep::Move { path: vec![q] }, CampaignStep::Track { tcp: 2 }] };
    let config = CampaignConfig {
        warm_up: Some(WarmUp { path: vec![q, common::clear_pose()], duration: Duration::from_secs(600) }),
        ..quiet_config()
    };
    let report = run(&cell, &plan, &dir.path().join("j"), config).expect("run");
    assert!(report.records[0].time_s > 600.0, "warm-up first: {}", report.records[0].time_s);
    let m: &Measurement = &report.measurements[0];
    let truth_p = cell.truth().tcp_position(&m.q, 2).expect("fk");
    let vatcal_core::Target::Tracker { xyz_mm } = m.target else { panic!("tracker measurement") };
    assert!((xyz_mm - truth_p).norm() < 0.1);
    // without a tracker, a track step is a clear error
    let model = nominal();
    let mut d = SimDevices::of(&paper_cell(SEED));
    let devices = CellDevices { tracker: None, ..d.devices() };
    let e = Campaign::new(devices, &model, quiet_config())
        .run(&plan, dir.path().join("k"))
        .expect_err("no tracker");
    assert!(matches!(e, CampaignError::NoTracker { step: 1 }), "{e}");
}

/// With joint backlash in the truth, the physical pose depends on the side each joint last
/// moved from. A crash right after a move in which joint 7 did not move: the recovery must
/// re-approach from the recorded side, or the resumed measurement differs.
#[test]
fn recovery_restores_the_backlash_side_of_joints_that_did_not_move() {
    use vatcal_core::EffectSpec;
    use vatcal_core::params::{EffectParam, ParamId};
    let model = nominal();
    let mut truth =
        vatcal_sim::truth::perturbed_truth(&model, SEED, &vatcal_sim::truth::ErrorBudget::realistic());
    truth.enable_effect(EffectSpec::JointBacklash { joint: 7 }).expect("effect");
    truth.set_param(ParamId::Effect(EffectParam::Backlash { joint: 7 }), 0.002).expect("value");
    let cell = || VirtualCell::new(model.clone(), truth.clone(), vatcal_sim::SimConfig::default(), SEED);

    // a probe pose with J6 (q7) > 0.2 rad
    let pose = common::poses(30, 7).into_iter().find(|m| m.q[6] > 0.2).expect("pose with q7 > 0.2");
    let position = pose.position().expect("probe");
    let mut from_above = pose.q; // q7 higher: the final approach of q7 is downward
    from_above[6] += 0.3;
    let mut same_q7 = pose.q; // other joints elsewhere, q7 already at its final value
    same_q7[2] -= 0.2;
    same_q7[3] += 0.2;
    let plan = CampaignPlan {
        steps: vec![
            CampaignStep::Move { path: vec![common::clear_pose()] },
            CampaignStep::PlaceProbe { position },
            CampaignStep::Move { path: vec![from_above, same_q7, pose.q] },
            CampaignStep::Measure { position, tcp: pose.tcp },
        ],
    };
    let dir = tempfile::tempdir().expect("tmp");
    let reference = run(&cell(), &plan, &dir.path().join("ref"), quiet_config()).expect("reference");
    let after_move = &reference.records[2].state;
    assert_eq!(after_move.dir[5], -1, "q7 approached downward");
    assert_eq!(after_move.arm_from[5], after_move.joints[6], "q7 did not move in the last motion");

    let journal = dir.path().join("crash");
    {
        let c = cell();
        let mut d = SimDevices::of(&c);
        let mut arm = DropsAt { inner: c.arm(), remaining: 1 };
        let devices = CellDevices { arm: &mut arm, ..d.devices() };
        Campaign::new(devices, &model, quiet_config())
            .run(&plan, &journal)
            .expect_err("crash in the measurement");
    }
    let resumed = run(&cell(), &plan, &journal, quiet_config()).expect("resumed");
    assert_eq!(resumed.resumed_at_step, Some(3));
    assert_same_measurements(&resumed.measurements, &reference.measurements);
}

/// A thermometer that fails from its `n`-th reading on.
struct FailingThermometer<T> {
    inner: T,
    remaining: usize,
}

impl<T: Thermometer> Thermometer for FailingThermometer<T> {
    fn read_c(&mut self) -> HwResult<f64> {
        if self.remaining == 0 {
            return Err(Error::new(ErrorKind::Timeout, "test thermometer", "no answer"));
        }
        self.remaining -= 1;
        self.inner.read_c()
    }
}

#[test]
fn a_cell_with_a_thermometer_records_the_temperature_of_each_measurement() {
    let dir = tempfile::tempdir().expect("tmp");
    let plan = plan(9, 1);
    let cell = vatcal_sim::truth::TruthSpec::PaperLike.virtual_cell(nominal(), SEED).expect("cell");
    let profile = cell.config().physics.thermal.expect("temperature channel");
    let start_s = cell.clock().now_s();
    let journal = dir.path().join("j");
    let report = run(&cell, &plan, &journal, quiet_config()).expect("campaign");
    assert_eq!(report.measurements.len(), plan.measurement_count());
    for m in &report.measurements {
        let t = m.context.temperature_c.expect("temperature_c on every measurement");
        // the reading is the cell's temperature at the measurement, within the sensor's noise
        let truth = profile.at(start_s + m.context.time_s.expect("time"));
        assert!((t - truth).abs() < 0.1, "read {t} °C, the cell had {truth} °C");
    }
    let temps: Vec<f64> = report.measurements.iter().filter_map(|m| m.context.temperature_c).collect();
    let spread =
        temps.iter().copied().fold(f64::MIN, f64::max) - temps.iter().copied().fold(f64::MAX, f64::min);
    assert!(spread > 0.05, "the campaign sees the warm-up: {spread} K");
    // the CSV carries the column and reads back
    let csv = dir.path().join("m.csv");
    export_measurements(&journal, &csv).expect("export");
    let header = std::fs::read_to_string(&csv).expect("csv").lines().next().expect("header").to_string();
    assert!(header.contains(",time_s,temperature_c,"), "{header}");
    let back = vatcal_io::read_probe_measurements(&csv, &nominal()).expect("read csv");
    assert_close_measurements(&back, &report.measurements);
    for (b, m) in back.iter().zip(&report.measurements) {
        assert_eq!(b.context.temperature_c, m.context.temperature_c);
    }

    // a thermometer failing after the second measurement's first reading: that measurement is
    // journaled (with the reading from before its step), the campaign stops with an error
    // naming the thermometer, and resuming with a working thermometer completes it
    let model = nominal();
    let cell = vatcal_sim::truth::TruthSpec::PaperLike.virtual_cell(nominal(), SEED).expect("cell");
    let mut d = SimDevices::of(&cell);
    let mut failing = FailingThermometer { inner: cell.thermometer().expect("thermometer"), remaining: 3 };
    let journal = dir.path().join("k");
    let devices = CellDevices { thermometer: Some(&mut failing), ..d.devices() };
    let e =
        Campaign::new(devices, &model, quiet_config()).run(&plan, &journal).expect_err("thermometer fault");
    assert!(matches!(&e, CampaignError::Device { action, .. } if action == "reading the thermometer"), "{e}");
    let kept = Journal::open(&journal).expect("journal").measurements();
    assert_eq!(kept.len(), 2, "the measurement in progress is kept");
    assert!(kept.iter().all(|m| m.context.temperature_c.is_some()));
    let resumed = Campaign::new(d.devices(), &model, quiet_config()).run(&plan, &journal).expect("resume");
    assert_eq!(resumed.measurements.len(), plan.measurement_count());
    assert!(resumed.measurements.iter().all(|m| m.context.temperature_c.is_some()));
}

// --- any serial chain: a UR5e-class arm without a guide on the virtual cell ---

/// The UR5e-class fixture (`fixtures/ur5e.toml`, six revolute joints, no guide).
fn ur5e() -> (vatcal_core::CellFile, vatcal_kinematics::Model) {
    let cell = vatcal_core::CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))
        .expect("fixture");
    let model = vatcal_kinematics::Model::from_cell(&cell).expect("model");
    (cell, model)
}

/// A hidden truth of the UR5e: the realistic error budget, with compliances scaled to the
/// UR5e's gravity torques (about 50 N·m at the shoulder, ten times the Meca500's): the same
/// joint deflections as the paper's cell, so that the nominal pose puts the ball inside the
/// ±6 mm gauges.
fn ur5e_truth(nominal: &vatcal_kinematics::Model, seed: u64) -> vatcal_kinematics::Model {
    let budget = vatcal_sim::truth::ErrorBudget {
        compliance_range: (1e-5, 4e-5),
        ..vatcal_sim::truth::ErrorBudget::realistic()
    };
    vatcal_sim::truth::perturbed_truth(nominal, seed, &budget)
}

#[test]
fn a_ur5e_virtual_cell_is_measured_by_the_same_campaign_and_calibrated() {
    use vatcal_planning::candidates::CandidateOptions;
    use vatcal_planning::plan::{PlanOptions, plan_campaign};

    let (cell_file, nominal) = ur5e();
    let geometry = vatcal_planning::geometry::CellGeometry::from_cell(&cell_file).expect("geometry");
    let options = PlanOptions {
        candidates: CandidateOptions { orientations: 20, progress: false, ..CandidateOptions::default() },
        count: 40,
        params: vatcal_core::ParamSet(Vec::new()),
        detmax_restarts: 2,
        tour_restarts: 2,
        motion: cell_file.motion_limits(),
        seed: 1,
        ..PlanOptions::default()
    };
    let planned = plan_campaign(&nominal, &geometry, &options).expect("plan");
    // through the tour file, as `vatcal campaign` reads it (q1..q6, no guide)
    let dir = tempfile::tempdir().expect("tmp");
    vatcal_planning::output::write_plan(&planned, dir.path()).expect("write plan");
    let tour = CampaignPlan::read_tour_for(dir.path().join("tour.csv"), nominal.joint_kinds()).expect("tour");
    assert_eq!(tour.measurement_count(), 40);
    assert!(CampaignPlan::read_tour(dir.path().join("tour.csv")).is_err(), "not a 7-joint tour");

    let truth = ur5e_truth(&nominal, 1);
    let cell =
        VirtualCell::new(nominal.clone(), truth.clone(), vatcal_sim::SimConfig::paper_for(&nominal), 1);
    assert!(cell.guide().is_none(), "a UR5e has no guide");
    let (mut arm, mut probe, mut operator) = (cell.arm(), cell.probe().expect("probe"), cell.operator());
    assert_eq!(RobotArm::joint_count(&arm), 6);
    let clock = cell.clock();
    let devices = CellDevices {
        arm: &mut arm,
        guide: None,
        probe: &mut probe,
        tracker: None,
        operator: &mut operator,
        clock: &clock,
        thermometer: None,
    };
    let csv = dir.path().join("measurements.csv");
    let config = CampaignConfig { measurements_csv: Some(csv.clone()), ..quiet_config() };
    let report = Campaign::new(devices, &nominal, config).run(&tour, dir.path().join("j")).expect("campaign");

    // every planned measurement centred within the paper's 5 µm
    assert_eq!(report.measurements.len(), 40);
    assert_eq!(report.skipped, 0);
    let mut worst_mm: f64 = 0.0;
    for r in &report.records {
        if let StepOutcome::Measured { composite_history_mm, .. } = &r.outcome {
            let last = *composite_history_mm.last().expect("a reading");
            assert!(last < 0.005, "step {}: composite {last} mm", r.step);
            worst_mm = worst_mm.max(last);
            assert!(r.state.guide_from_mm.is_none() && r.state.dir.len() == 6);
        }
    }
    // the journal's `dir` are the six arm joints = cell joints 1..6
    let m = &report.measurements[0];
    let dir_of = m.context.dir.expect("dir");
    assert!(dir_of[..6].iter().any(|d| *d != 0) && dir_of[6..].iter().all(|d| *d == 0), "{dir_of:?}");
    let text = std::fs::read_to_string(&csv).expect("csv");
    let header = text.lines().next().expect("header");
    assert!(header.starts_with("position,tcp,q1,q2,q3,q4,q5,q6,time_s,"), "{header}");
    assert!(header.contains("dir1,dir2,dir3,dir4,dir5,dir6") && !header.contains("q7"), "{header}");

    // identify the plan's parameters: held-out error from the nominal's down to the noise
    let fit = vatcal_identification::identify(
        &nominal,
        &report.measurements,
        &planned.params,
        &vatcal_identification::IdentifyOptions::default(),
    )
    .expect("identify");
    let held_out = vatcal_sim::truth::synthetic_tracker_measurements(&truth, 200, 0.0, 9);
    let mean = |model: &vatcal_kinematics::Model| {
        held_out.iter().map(|x| model.residual(x).expect("residual").norm()).sum::<f64>()
            / held_out.len() as f64
    };
    let (before, after) = (mean(&nominal), mean(&fit.model));
    eprintln!(
        "UR5e virtual cell: worst centring {worst_mm:.4} mm; held-out mean error nominal {before:.4} mm -> calibrated {after:.4} mm ({} parameters)",
        fit.params.len()
    );
    assert!(before > 0.3, "the nominal model must be wrong: {before} mm");
    assert!(after < 0.05 && after < before / 10.0, "calibrated {after} mm (nominal {before} mm)");
}

#[test]
fn devices_that_do_not_fit_the_chain_are_refused_before_anything_moves() {
    // the canonical cell without its guide
    let cell = paper_cell(SEED);
    let model = nominal();
    let mut d = SimDevices::of(&cell);
    let devices = CellDevices { guide: None, ..d.devices() };
    let dir = tempfile::tempdir().expect("tmp");
    let e = Campaign::new(devices, &model, quiet_config())
        .run(&plan(3, 1), dir.path().join("a"))
        .expect_err("no guide");
    assert!(matches!(e, CampaignError::DeviceMismatch { .. }), "{e}");
    assert!(e.to_string().contains("no guide device"), "{e}");
    assert_eq!(cell.clock().now(), Duration::ZERO, "nothing moved");
    // a UR5e model with the canonical cell's devices (a guide, and a six-joint arm)
    let (_, ur) = ur5e();
    let e = Campaign::new(d.devices(), &ur, quiet_config())
        .run(&CampaignPlan { steps: vec![CampaignStep::PlaceProbe { position: 1 }] }, dir.path().join("b"))
        .expect_err("a guide too many");
    assert!(e.to_string().contains("6 joints (RRRRRR)") && e.to_string().contains("no guide joint"), "{e}");
}
