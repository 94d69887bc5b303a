//! A real crash: a child process runs the campaign on the virtual cell and is killed with
//! SIGKILL in the middle; the campaign is resumed in this process from the journal the child
//! left behind. The final measurement set must equal that of an uninterrupted run with the
//! same seed: nothing lost, nothing measured twice.
//!
//! The child is this very test binary, started with `--exact kill_resume::child_campaign` and an
//! environment variable naming the journal; without the variable that test does nothing.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{SimDevices, assert_same_measurements, nominal, paper_cell, plan, quiet_config};
use nalgebra::Vector3;
use vatcal_campaign::{Campaign, CampaignPlan, CampaignReport, CellDevices, Journal};
use vatcal_hardware_traits::{
    ArmJoints, ArmStatus, LinearFrame, MotionOptions, Result as HwResult, RobotArm,
};

const SEED: u64 = 77;
const CHILD_JOURNAL: &str = "VATCAL_TEST_CHILD_JOURNAL";
/// real time each arm motion of the child takes, so that it is killed in the middle of a step
const CHILD_MOTION_DELAY: Duration = Duration::from_millis(8);

/// The simulated arm, with every wait taking some real time as well.
struct RealTimeArm<A>(A);

impl<A: RobotArm> RobotArm for RealTimeArm<A> {
    fn joint_count(&self) -> usize {
        self.0.joint_count()
    }
    fn activate_and_home(&mut self, timeout: Duration) -> HwResult<()> {
        self.0.activate_and_home(timeout)
    }
    fn status(&mut self) -> HwResult<ArmStatus> {
        self.0.status()
    }
    fn joints(&mut self) -> HwResult<ArmJoints> {
        self.0.joints()
    }
    fn move_joints(&mut self, target: &ArmJoints, options: &MotionOptions) -> HwResult<()> {
        self.0.move_joints(target, options)
    }
    fn move_linear_relative(
        &mut self,
        d: &Vector3<f64>,
        frame: LinearFrame,
        options: &MotionOptions,
    ) -> HwResult<()> {
        self.0.move_linear_relative(d, frame, options)
    }
    fn wait_idle(&mut self, timeout: Duration) -> HwResult<()> {
        std::thread::sleep(CHILD_MOTION_DELAY);
        self.0.wait_idle(timeout)
    }
    fn stop(&mut self) -> HwResult<()> {
        self.0.stop()
    }
    fn reset_error(&mut self) -> HwResult<()> {
        self.0.reset_error()
    }
}

fn scenario() -> CampaignPlan {
    plan(9, 8)
}

fn run(journal: &Path, real_time: bool) -> CampaignReport {
    let cell = paper_cell(SEED);
    let model = nominal();
    let mut d = SimDevices::of(&cell);
    let mut slow = RealTimeArm(cell.arm());
    let devices = if real_time { CellDevices { arm: &mut slow, ..d.devices() } } else { d.devices() };
    Campaign::new(devices, &model, quiet_config()).run(&scenario(), journal).expect("campaign")
}

/// The child's body: runs only when spawned by the test below.
#[test]
fn child_campaign() {
    if let Some(journal) = std::env::var_os(CHILD_JOURNAL) {
        run(Path::new(&journal), true);
    }
}

fn journal_records(path: &Path) -> usize {
    // count complete lines only (the child may be writing)
    std::fs::read(path).map(|b| b.iter().filter(|c| **c == b'\n').count().saturating_sub(1)).unwrap_or(0)
}

#[test]
fn killed_campaign_resumes_without_losing_or_repeating_a_measurement() {
    let dir = tempfile::tempdir().expect("tmp");
    let plan = scenario();
    let reference = run(&dir.path().join("reference.journal"), false);
    assert_eq!(reference.measurements.len(), plan.measurement_count());

    let journal: PathBuf = dir.path().join("killed.journal");
    let exe = std::env::current_exe().expect("test binary");
    // the child test's name in the harness: its module path without the crate's name
    // (`kill_resume::child_campaign` in the crate's one test binary)
    let child_test = match module_path!().split_once("::") {
        Some((_, module)) => format!("{module}::child_campaign"),
        None => "child_campaign".to_string(),
    };
    let mut child = Command::new(exe)
        .args(["--exact", child_test.as_str(), "--test-threads=1", "--nocapture"])
        .env(CHILD_JOURNAL, &journal)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn the child campaign");
    // wait until the child has journaled a good part of the plan, then SIGKILL it
    let kill_after = plan.steps.len() / 2;
    let deadline = Instant::now() + Duration::from_secs(30);
    while journal_records(&journal) < kill_after {
        assert!(Instant::now() < deadline, "the child campaign did not progress");
        if let Some(status) = child.try_wait().expect("try_wait") {
            panic!("the child exited ({status}) before it could be killed");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    // a little later, so that the child is inside the next step (moving or centering)
    std::thread::sleep(CHILD_MOTION_DELAY * 3 / 2);
    child.kill().expect("SIGKILL");
    child.wait().expect("reap");

    let survived = Journal::open(&journal).expect("journal after the kill");
    let done = survived.records().len();
    assert!(done >= kill_after && done < plan.steps.len(), "killed mid-way: {done}/{}", plan.steps.len());
    let measured_before = survived.measurements().len();

    let resumed = run(&journal, false);
    assert_eq!(resumed.resumed_at_step, Some(done));
    assert_same_measurements(&resumed.measurements, &reference.measurements);
    // the measurements journaled by the child are kept as they were (time stamps included)
    assert_eq!(&resumed.measurements[..measured_before], &survived.measurements()[..]);
    let steps: Vec<usize> = resumed.records.iter().map(|r| r.step).collect();
    assert_eq!(steps, (0..plan.steps.len()).collect::<Vec<_>>(), "every step exactly once");
    eprintln!(
        "killed after {done}/{} steps ({measured_before} measurements) while executing {}; resumed to {} measurements",
        plan.steps.len(),
        match &plan.steps[done] {
            vatcal_campaign::CampaignStep::Move { .. } => "a move",
            vatcal_campaign::CampaignStep::Measure { .. } => "a measurement",
            _ => "another step",
        },
        resumed.measurements.len()
    );
}
