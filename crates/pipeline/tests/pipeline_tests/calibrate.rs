//! `vatcal_pipeline::calibrate` on the in-process virtual cell (`VirtualCell::paper`: the
//! 34 parameters' errors only, no clock-driven physics, so a new cell of the same seed after an
//! interruption is the same cell): stages, the stage state file, resuming the validation after a
//! tracker fault with nothing lost or measured twice, a stage on its own, and the errors of
//! stages whose inputs are missing.

use std::path::Path;

use serde::Serialize;
use vatcal_campaign::{CampaignConfig, CellDevices, Journal, StepOutcome};
use vatcal_core::CellFile;
use vatcal_hardware_traits::{Error, ErrorKind, PositionTracker, TriCal, VirtualClock};
use vatcal_identification::Identification;
use vatcal_kinematics::Model;
use vatcal_pipeline::report::ValidationSummary;
use vatcal_pipeline::{
    CalibrateOptions, DeviceSet, NoProgress, ReportSetup, RunOptions, RunSizes, Stage, StageStatus,
    StagesFile, calibrate,
};
use vatcal_sim::{SimArm, SimGauge, SimGuide, SimOperator, SimTracker, VirtualCell};

/// A tracker that fails (timeout) after `left` good points.
struct FailingTracker {
    inner: SimTracker,
    left: Option<usize>,
}

impl PositionTracker for FailingTracker {
    fn measure_mm(&mut self, target: u32) -> vatcal_hardware_traits::Result<nalgebra::Vector3<f64>> {
        if let Some(left) = self.left.as_mut() {
            if *left == 0 {
                return Err(Error::new(ErrorKind::Timeout, "test tracker", "no answer"));
            }
            *left -= 1;
        }
        self.inner.measure_mm(target)
    }
}

struct Devices {
    arm: SimArm,
    guide: SimGuide,
    probe: TriCal<SimGauge>,
    tracker: FailingTracker,
    operator: SimOperator,
    clock: VirtualClock,
}

impl Devices {
    /// A new virtual cell of seed 5 whose tracker fails after `points` points.
    fn new(points: Option<usize>) -> Self {
        let cell = VirtualCell::paper(Model::from_cell(&nominal()).expect("model"), 5);
        Self {
            arm: cell.arm(),
            guide: cell.guide().expect("guide"),
            probe: cell.probe().expect("probe"),
            tracker: FailingTracker { inner: cell.tracker(), left: points },
            operator: cell.operator(),
            clock: cell.clock(),
        }
    }
}

impl DeviceSet for Devices {
    fn devices(&mut self) -> CellDevices<'_> {
        CellDevices {
            arm: &mut self.arm,
            guide: Some(&mut self.guide),
            probe: &mut self.probe,
            tracker: Some(&mut self.tracker),
            operator: &mut self.operator,
            clock: &self.clock,
            thermometer: None,
        }
    }
}

#[derive(Debug, Serialize)]
struct Setup;

impl ReportSetup for Setup {
    fn format(&self) -> &str {
        "calibrate-test"
    }
    fn title(&self, seed: u64) -> String {
        format!("# test {seed}")
    }
    fn intro(&self) -> String {
        String::new()
    }
    fn setup_markdown(&self, _: &ValidationSummary) -> String {
        String::new()
    }
    fn parameters(&self) -> String {
        "paper34".into()
    }
    fn method(&self) -> String {
        "LM".into()
    }
}

fn nominal() -> CellFile {
    CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture")
}

fn options() -> RunOptions {
    RunOptions {
        seed: 5,
        nominal: nominal(),
        sizes: RunSizes { orientations: 20, guide_steps: 3, count: 40, random_poses: 30, slices: 20 },
        campaign: CampaignConfig {
            show_progress: false,
            skip_failed_measurements: true,
            sync_journal_each_step: false,
            ..CampaignConfig::default()
        },
    }
}

fn stages(list: &str, resume: bool) -> CalibrateOptions {
    CalibrateOptions { stages: CalibrateOptions::parse_stages(list).expect("stages"), resume }
}

fn run(
    devices: &mut Devices,
    cal: &CalibrateOptions,
    out: &Path,
) -> Result<vatcal_pipeline::CalibrateOutcome<Setup>, vatcal_pipeline::PipelineError> {
    calibrate(&options(), None, cal, devices, |_: &Identification| Setup, out, &mut NoProgress)
}

/// `(step, joints, tracked position)` of every tracker record of a journal (not its time).
fn tracked(journal: &Path) -> Vec<(usize, Vec<f64>, [f64; 3])> {
    Journal::open(journal)
        .expect("journal")
        .records()
        .iter()
        .filter_map(|r| match &r.outcome {
            StepOutcome::Tracked { xyz_mm, .. } => {
                Some((r.step, r.state.joints.as_slice().to_vec(), *xyz_mm))
            }
            _ => None,
        })
        .collect()
}

#[test]
fn a_tracker_fault_in_the_validation_then_resume_gives_the_uninterrupted_measurements_and_report() {
    let dir = tempfile::tempdir().expect("tmp");
    let reference = dir.path().join("reference");
    let full = run(&mut Devices::new(None), &CalibrateOptions::default(), &reference).expect("uninterrupted");
    let report = full.run.expect("report").report;
    let points = tracked(&reference.join("validation.journal"));
    assert!(points.len() > 60, "{} tracker points", points.len());

    let out = dir.path().join("faulted");
    let e = run(&mut Devices::new(Some(25)), &CalibrateOptions::default(), &out).expect_err("tracker fault");
    assert!(format!("{e:?}").contains("no answer"), "{e:?}");
    let state = StagesFile::load(&out).expect("state").expect("stages.json");
    assert_eq!(state.entry(Stage::Validate).map(|e| e.status), Some(StageStatus::Running));
    assert!(state.is_done(Stage::Identify));
    assert_eq!(tracked(&out.join("validation.journal")).len(), 25);

    // a resume on a new cell of the same seed (a restarted process)
    let resumed = run(
        &mut Devices::new(None),
        &stages("plan,campaign,identify,discovery,validation,compensation", true),
        &out,
    )
    .expect("resume");
    assert_eq!(resumed.ran, vec![Stage::Validate, Stage::Report]);
    assert_eq!(resumed.recomputed, vec![Stage::Plan, Stage::Campaign, Stage::Identify]);
    assert_eq!(tracked(&out.join("validation.journal")), points, "nothing lost, nothing measured twice");
    let again = resumed.run.expect("report");
    assert_eq!(again.report.validation.models, report.validation.models);
    assert_eq!(again.report.identification, report.identification);
    assert_eq!(resumed.state.entry(Stage::Validate).map(|e| e.attempts), Some(2));

    // everything done: a resume runs nothing that measures
    let idle = run(
        &mut Devices::new(Some(0)),
        &CalibrateOptions { resume: true, ..CalibrateOptions::default() },
        &out,
    )
    .expect("nothing left");
    // (the report is written again: it is offline)
    assert!(idle.ran.iter().all(|s| !s.uses_devices()), "{:?}", idle.ran);
    assert_eq!(tracked(&out.join("validation.journal")), points);
}

#[test]
fn a_stage_on_its_own_needs_the_stages_before_it_and_clears_the_ones_after() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("run");
    let e = run(&mut Devices::new(None), &stages("identify", false), &out).expect_err("no plan yet");
    assert!(e.to_string().contains("stage `plan`"), "{e}");
    let e = CalibrateOptions::parse_stages("plan,survey").expect_err("unknown");
    assert!(e.to_string().contains("survey") && e.to_string().contains("compensation"), "{e}");

    run(&mut Devices::new(None), &stages("plan,campaign,identify", false), &out).expect("first three");
    let first = std::fs::read_to_string(out.join("calibrated.toml")).expect("calibrated");
    let again = run(&mut Devices::new(None), &stages("identify", false), &out).expect("identify alone");
    assert_eq!(again.ran, vec![Stage::Identify]);
    assert_eq!(std::fs::read_to_string(out.join("calibrated.toml")).expect("calibrated"), first);
    let e = run(&mut Devices::new(None), &stages("compensation", false), &out).expect_err("no validation");
    assert!(e.to_string().contains("stage `validation`"), "{e}");
    let mut other = options();
    other.seed = 6;
    let e = calibrate(
        &other,
        None,
        &stages("identify", false),
        &mut Devices::new(None),
        |_| Setup,
        &out,
        &mut NoProgress,
    )
    .expect_err("another seed");
    assert!(e.to_string().contains("seed 5"), "{e}");
}

/// A `kill -9` inside the two stages that take milliseconds (identify, compensation) cannot be
/// timed from outside the process (the kill tests of the measuring stages are in the CLI's
/// tests); the state such a kill leaves is built here exactly: the stage `running` in
/// `stages.json` with its attempt counted (what `calibrate` saves before the stage's first
/// step) and the stage's output file cut off half-way (a write interrupted). `--resume` runs
/// the stage again and gives the outputs of the same two calls without the kill, measuring
/// nothing again. (The reference is split at the same stage because a new process starts the
/// validation from the arm's home, not from where the campaign left it.)
#[test]
fn the_state_a_kill_inside_identify_or_compensation_leaves_resumes_to_the_uninterrupted_outputs() {
    let dir = tempfile::tempdir().expect("tmp");
    let read = |path: &Path| std::fs::read_to_string(path).expect("output file");
    let json = |p: &Path| serde_json::from_str::<serde_json::Value>(&read(p)).expect("a whole report.json");
    let all = "plan,campaign,identify,validation,compensation";
    for (stage, before, output) in [
        (Stage::Identify, "plan,campaign", "calibrated.toml"),
        (Stage::Report, "plan,campaign,identify,validation", "report.json"),
    ] {
        let reference = dir.path().join(format!("{}-reference", stage.key()));
        run(&mut Devices::new(None), &stages(before, false), &reference).expect("the stages before");
        let uninterrupted = run(&mut Devices::new(None), &stages(all, true), &reference)
            .expect("the rest")
            .run
            .expect("report");

        let out = dir.path().join(stage.key());
        run(&mut Devices::new(None), &stages(before, false), &out).expect("the stages before");
        // the kill: the stage started (one attempt, running), its output half written
        let path = out.join("stages.json");
        let mut state: serde_json::Value = serde_json::from_str(&read(&path)).expect("stages.json");
        state["stages"].as_array_mut().expect("stages").push(serde_json::json!({
            "stage": stage.key(), "status": "running", "attempts": 1, "wall_s": null, "device_s": null
        }));
        std::fs::write(&path, serde_json::to_string_pretty(&state).expect("json")).expect("write");
        let whole = read(&reference.join(output));
        std::fs::write(out.join(output), &whole[..whole.len() / 2]).expect("cut off");
        let journal = out.join("validation.journal");
        let measured_before = if journal.exists() { tracked(&journal).len() } else { 0 };

        let resumed = run(&mut Devices::new(None), &stages(all, true), &out)
            .unwrap_or_else(|e| panic!("resume after a kill in {}: {e}", stage.key()));
        assert_eq!(resumed.ran.first(), Some(&stage), "{}: ran {:?}", stage.key(), resumed.ran);
        assert_eq!(resumed.state.entry(stage).map(|e| (e.status, e.attempts)), Some((StageStatus::Done, 2)));
        assert_eq!(read(&out.join("measurements.csv")), read(&reference.join("measurements.csv")));
        assert_eq!(read(&out.join("calibrated.toml")), read(&reference.join("calibrated.toml")));
        if stage == Stage::Report {
            assert!(measured_before > 0);
            assert_eq!(tracked(&journal).len(), measured_before, "nothing measured again");
        }
        let again = resumed.run.expect("report").report;
        assert_eq!(again.identification, uninterrupted.report.identification, "{}", stage.key());
        assert_eq!(again.validation.models, uninterrupted.report.validation.models, "{}", stage.key());
        // the report file is whole again and says what the uninterrupted one says
        let (written, expected) = (json(&out.join("report.json")), json(&reference.join("report.json")));
        assert!(expected["validation"].is_object(), "{expected}");
        assert_eq!(written["validation"], expected["validation"]);
        assert_eq!(written["identification"], expected["identification"]);
    }
}
