//! The campaign runner: executes a [`CampaignPlan`] on any devices, step by step, journaling
//! every completed step, and resumes a journal exactly where it stopped.

use std::path::{Path, PathBuf};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use vatcal_core::{JointKind, JointVector, Measurement};
use vatcal_hardware_traits::{
    ArmJoints, Clock, ErrorKind, JointLayout, LinearAxis, MotionOptions, Operator, OperatorInstruction,
    PositionTracker, Probe3d, RobotArm, Thermometer,
};
use vatcal_kinematics::Model;

use crate::centering::{CenteringConfig, CenteringError, auto_center};
use crate::journal::{CellState, Journal, JournalError, JournalHeader, StepOutcome, StepRecord};
use crate::plan::{CampaignPlan, CampaignPlanError, CampaignStep};

/// The devices a campaign drives — trait objects only, so any driver (real or simulated) fits.
pub struct CellDevices<'a> {
    /// the robot arm
    pub arm: &'a mut dyn RobotArm,
    /// the linear guide carrying the arm; `None` for a cell without one (the controller
    /// model's [`JointLayout`] decides which the cell needs)
    pub guide: Option<&'a mut dyn LinearAxis>,
    /// the 3D probe (TriCal)
    pub probe: &'a mut dyn Probe3d,
    /// a tracker, needed only by [`CampaignStep::Track`] steps
    pub tracker: Option<&'a mut dyn PositionTracker>,
    /// the operator (re-places the probe plate)
    pub operator: &'a mut dyn Operator,
    /// the clock time stamps come from
    pub clock: &'a dyn Clock,
    /// a thermometer: when present, every measurement records the cell temperature
    /// (`temperature_c`) read when its step completed
    pub thermometer: Option<&'a mut dyn Thermometer>,
}

impl std::fmt::Debug for CellDevices<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CellDevices")
            .field("guide", &self.guide.is_some())
            .field("tracker", &self.tracker.is_some())
            .field("clock", &self.clock)
            .field("thermometer", &self.thermometer.is_some())
            .finish_non_exhaustive()
    }
}

/// Optional warm-up before the first step of a fresh campaign (paper: ~30 min).
#[derive(Debug, Clone, PartialEq)]
pub struct WarmUp {
    /// poses visited in a loop
    pub path: Vec<JointVector>,
    /// keep looping until this much clock time has passed
    pub duration: Duration,
}

/// Settings of a campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct CampaignConfig {
    /// auto-centering settings
    pub centering: CenteringConfig,
    /// speed and timeout of the plan's moves
    pub motion: MotionOptions,
    /// timeout of arm activation/homing and guide homing
    pub home_timeout: Duration,
    /// warm-up motion before a fresh campaign
    pub warm_up: Option<WarmUp>,
    /// when auto-centering refuses (unsafe step, out of range, cap): record the step as skipped,
    /// return the arm to the approach pose and go on (`true`), or stop the campaign (`false`)
    pub skip_failed_measurements: bool,
    /// draw a progress bar with ETA on stderr
    pub show_progress: bool,
    /// after a crash the arm re-approaches the last recorded pose from this far on the side
    /// each joint last moved from \[rad\], restoring every joint's backlash side
    pub recovery_approach_rad: f64,
    /// free text stored in the journal header
    pub note: String,
    /// keep this measurements CSV up to date after every measurement (`position,tcp,q1..qN,
    /// time_s[,temperature_c],dir{j}` of the revolute joints j, mm/deg; the canonical cell:
    /// `q1..q7`, `dir2..dir7`; replaced atomically)
    pub measurements_csv: Option<PathBuf>,
    /// a failed tracker reading of a `track` step (line of sight lost, timeout, garbled
    /// answer, a tracker fault) is tried again up to this many times (default 2); a cancelled
    /// or disconnected tracker is not retried
    pub tracker_retries: u32,
    /// when a `track` step still fails after its retries: record it as skipped and go on
    /// (`true`; the validation evaluates what was measured and counts the skipped points), or
    /// stop the campaign safely (`false`, the default; the journal keeps every completed step
    /// and a resume measures the point again)
    pub skip_failed_tracks: bool,
    /// `fsync` the journal after every step (default `true`). Set it to `false` only for
    /// simulated cells, whose steps take microseconds: the records are still written one by
    /// one (a killed process loses nothing) and the journal is synced once at the end, but a
    /// power cut could lose the last records.
    pub sync_journal_each_step: bool,
    /// the instruments' noise, recorded in `measurements_csv` as a `# vatcal-noise:` line
    /// (none by default)
    pub noise: vatcal_io::metadata::NoiseMetadata,
    /// the calibration position the probe plate is already at when the campaign starts (left
    /// there by the campaign before): the plan may measure there before any `place_probe`
    /// step, and no operator is asked to place it again (`None`: the plan must place it)
    pub plate_at_start: Option<u32>,
}

impl Default for CampaignConfig {
    /// Default centering, 25 % speed with 120 s timeouts, no warm-up, stop on failures,
    /// progress bar on, 0.01 rad recovery approach, no CSV, tracker readings retried twice,
    /// journal synced after every step.
    fn default() -> Self {
        Self {
            centering: CenteringConfig::default(),
            motion: MotionOptions::default(),
            home_timeout: Duration::from_secs(120),
            warm_up: None,
            skip_failed_measurements: false,
            show_progress: true,
            recovery_approach_rad: 0.01,
            note: String::new(),
            measurements_csv: None,
            tracker_retries: 2,
            skip_failed_tracks: false,
            sync_journal_each_step: true,
            noise: vatcal_io::metadata::NoiseMetadata::default(),
            plate_at_start: None,
        }
    }
}

/// Errors of a campaign. The journal keeps every completed step: fix the cause and run the
/// same plan on the same journal to resume.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    /// The plan is invalid for the model.
    #[error("invalid plan: {0}")]
    Plan(#[from] CampaignPlanError),
    /// The journal cannot be read or written.
    #[error(transparent)]
    Journal(#[from] JournalError),
    /// The journal was started with another plan.
    #[error(
        "journal {path} belongs to another plan (fingerprint {journal:016x}, this plan {plan:016x}): resume with the original plan or start a new journal"
    )]
    PlanMismatch {
        /// journal file
        path: PathBuf,
        /// fingerprint in the journal
        journal: u64,
        /// fingerprint of the given plan
        plan: u64,
    },
    /// The devices do not fit the controller model's joints (an arm with another joint count,
    /// a guide missing or one too many).
    #[error("the devices do not fit the cell's model ({chain}): {reason}")]
    DeviceMismatch {
        /// the model's chain, e.g. `6 joints (RRRRRR)`
        chain: String,
        /// what does not fit
        reason: String,
    },
    /// A device failed.
    #[error("step {step}: {action}: {source}")]
    Device {
        /// plan step (`None` before the first step: homing, recovery, warm-up)
        step: StepLabel,
        /// what the campaign was doing
        action: String,
        /// the device error
        source: vatcal_hardware_traits::Error,
    },
    /// Auto-centering refused to go on.
    #[error("step {step}: auto-centering TCP {tcp} at calibration position {position}: {source}")]
    Centering {
        /// plan step
        step: usize,
        /// calibration position
        position: u32,
        /// TCP id
        tcp: u32,
        /// why
        source: CenteringError,
    },
    /// The probe has no orientation configured for a calibration position of the plan.
    #[error("the plan measures at calibration position {position} but the probe has no placement for it")]
    NoProbePlacement {
        /// calibration position
        position: u32,
    },
    /// A `track` step without a tracker.
    #[error("step {step}: the plan measures with a tracker but none is connected")]
    NoTracker {
        /// plan step
        step: usize,
    },
    /// Writing the measurements CSV failed.
    #[error(transparent)]
    Output(#[from] vatcal_io::IoError),
}

/// A plan step index, or the phase before the first step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepLabel {
    /// before the plan (homing, recovery after a crash, warm-up)
    Setup,
    /// plan step (0-based)
    Step(usize),
}

impl std::fmt::Display for StepLabel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StepLabel::Setup => f.write_str("setup"),
            StepLabel::Step(s) => write!(f, "{s}"),
        }
    }
}

/// What a campaign run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct CampaignReport {
    /// every measurement of the journal (including those recorded before a crash), in order
    pub measurements: Vec<Measurement>,
    /// every journal record
    pub records: Vec<StepRecord>,
    /// the step this run resumed at (`None`: fresh start)
    pub resumed_at_step: Option<usize>,
    /// bytes of a torn last record dropped from the journal
    pub torn_bytes_dropped: usize,
    /// measurements skipped because auto-centering refused
    pub skipped: usize,
}

impl CampaignReport {
    /// The devices' working time of the campaign \[s\]: the sum of its steps' durations (each
    /// record's time since the previous one). The first step of a resumed run
    /// ([`StepRecord::resumed`]) is counted at the median duration of the other steps: the
    /// time since its previous record includes the stop, the recovery and the restart
    /// (minutes to hours on a real cell; a simulated cell's clock runs on while the program is
    /// down), which is not time the devices spent on the plan. Without a resume it is the last
    /// record's time.
    pub fn device_s(&self) -> f64 {
        let mut own = Vec::with_capacity(self.records.len());
        let (mut previous_s, mut resumes) = (0.0, 0usize);
        for r in &self.records {
            let duration = (r.time_s - previous_s).max(0.0);
            previous_s = r.time_s;
            if r.resumed {
                resumes += 1;
            } else {
                own.push(duration);
            }
        }
        let total: f64 = own.iter().sum();
        if resumes == 0 || own.is_empty() {
            return total;
        }
        own.sort_by(f64::total_cmp);
        let median = if own.len() % 2 == 1 {
            own[own.len() / 2]
        } else {
            0.5 * (own[own.len() / 2 - 1] + own[own.len() / 2])
        };
        total + resumes as f64 * median
    }
}

/// Runs campaigns on a set of devices.
pub struct Campaign<'a> {
    devices: CellDevices<'a>,
    controller: &'a Model,
    layout: JointLayout,
    config: CampaignConfig,
    observer: Option<Observer<'a>>,
}

/// Callback run after every journaled step.
type Observer<'a> = Box<dyn FnMut(&StepRecord) + 'a>;

impl std::fmt::Debug for Campaign<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Campaign")
            .field("devices", &self.devices)
            .field("config", &self.config)
            .finish_non_exhaustive()
    }
}

/// What the campaign knows about the cell while it runs (the journal's [`CellState`]).
type State = CellState;

fn device_err(
    step: StepLabel,
    action: impl Into<String>,
) -> impl FnOnce(vatcal_hardware_traits::Error) -> CampaignError {
    move |source| CampaignError::Device { step, action: action.into(), source }
}

impl<'a> Campaign<'a> {
    /// A campaign on `devices`. `controller` is the kinematic model the robot controller
    /// believes (the nominal cell): auto-centering uses it to express corrections in the
    /// flange frame, and the plan is validated against its limits and ids.
    pub fn new(devices: CellDevices<'a>, controller: &'a Model, config: CampaignConfig) -> Self {
        let layout = JointLayout::of(controller.joint_kinds());
        Self { devices, controller, layout, config, observer: None }
    }

    /// Calls `f` after every journaled step (logging, a live display, tests).
    pub fn on_record(mut self, f: impl FnMut(&StepRecord) + 'a) -> Self {
        self.observer = Some(Box::new(f));
        self
    }

    /// Runs `plan`, journaling into `journal_path`. A journal that already holds records of the
    /// same plan is resumed: the cell is put back into the last recorded state (after the
    /// operator confirmed) and execution continues with the next step, so no measurement is
    /// lost or repeated.
    pub fn run(
        &mut self,
        plan: &CampaignPlan,
        journal_path: impl AsRef<Path>,
    ) -> Result<CampaignReport, CampaignError> {
        self.check_plan(plan)?;
        let mut journal = self.open_journal(plan, journal_path.as_ref())?;
        journal.set_sync_each_record(self.config.sync_journal_each_step);
        self.prepare_devices()?;
        let (mut state, time_offset_s, resumed_at_step) = self.restore(&journal, plan)?;
        let progress = self.progress_bar(plan.steps.len(), journal.next_step());
        for step in journal.next_step()..plan.steps.len() {
            progress.set_message(describe(&plan.steps[step]));
            let measuring =
                matches!(plan.steps[step], CampaignStep::Measure { .. } | CampaignStep::Track { .. });
            // read before the step too: a faulty thermometer stops the campaign before it moves
            let before_c = if measuring { self.read_temperature(StepLabel::Step(step))? } else { None };
            let outcome = self.execute(step, &plan.steps[step], &mut state)?;
            let time_s = self.elapsed_s(journal.header()) + time_offset_s;
            // the temperature when the measurement was taken; if the thermometer fails now, the
            // measurement is journaled with the reading from before the step, then the
            // campaign stops (nothing measured is lost)
            let after = if measuring { self.read_temperature(StepLabel::Step(step)) } else { Ok(None) };
            let (temperature_c, fault) = match after {
                Ok(t) => (t, None),
                Err(e) => (before_c, Some(e)),
            };
            let resumed = resumed_at_step == Some(step);
            let record = StepRecord { step, time_s, temperature_c, state: state.clone(), outcome, resumed };
            journal.append(record.clone())?;
            if let Some(e) = fault {
                journal.sync()?;
                if let Some(csv) = &self.config.measurements_csv {
                    write_csv_atomically(
                        csv,
                        &journal.measurements(),
                        self.controller.joint_kinds(),
                        &self.config.noise,
                    )?;
                }
                return Err(e);
            }
            if record.measurement().is_some()
                && let Some(csv) = &self.config.measurements_csv
            {
                write_csv_atomically(
                    csv,
                    &journal.measurements(),
                    self.controller.joint_kinds(),
                    &self.config.noise,
                )?;
            }
            if let Some(f) = self.observer.as_mut() {
                f(&record);
            }
            progress.inc(1);
        }
        progress.finish_with_message("campaign complete");
        journal.sync()?;
        let skipped =
            journal.records().iter().filter(|r| matches!(r.outcome, StepOutcome::Skipped { .. })).count();
        Ok(CampaignReport {
            measurements: journal.measurements(),
            records: journal.records().to_vec(),
            resumed_at_step,
            torn_bytes_dropped: journal.torn_bytes_dropped(),
            skipped,
        })
    }

    /// The plan is valid for the controller model and the probe knows every position.
    fn check_plan(&self, plan: &CampaignPlan) -> Result<(), CampaignError> {
        plan.validate_from(self.controller, self.config.plate_at_start)?;
        for s in &plan.steps {
            if let CampaignStep::Measure { position, .. } = s
                && self.devices.probe.placement(*position).is_none()
            {
                return Err(CampaignError::NoProbePlacement { position: *position });
            }
        }
        Ok(())
    }

    /// Opens (or creates) the journal and checks that it belongs to `plan`.
    fn open_journal(&self, plan: &CampaignPlan, path: &Path) -> Result<Journal, CampaignError> {
        let fingerprint = plan.fingerprint();
        let start = self.devices.clock.now_s();
        let header = JournalHeader::new(fingerprint, plan.steps.len(), start, self.config.note.clone());
        let (journal, _) = Journal::open_or_create(path, header)?;
        let h = journal.header();
        if h.plan_fingerprint != fingerprint || h.plan_steps != plan.steps.len() {
            return Err(CampaignError::PlanMismatch {
                path: path.into(),
                journal: h.plan_fingerprint,
                plan: fingerprint,
            });
        }
        Ok(journal)
    }

    /// The state to continue from: after a crash, the recorded state (the cell is put back
    /// into it) and the time offset that keeps time increasing; on a fresh start, the current
    /// state after the optional warm-up.
    fn restore(
        &mut self,
        journal: &Journal,
        plan: &CampaignPlan,
    ) -> Result<(State, f64, Option<usize>), CampaignError> {
        let Some(last) = journal.records().last() else {
            let mut state = self.initial_state()?;
            if let Some(w) = self.config.warm_up.clone() {
                self.warm_up(&w, &mut state)?;
            }
            return Ok((state, 0.0, None));
        };
        if journal.next_step() < plan.steps.len() {
            self.recover(&last.state)?;
        }
        // a clock that restarted (virtual, or monotonic after a reboot) must not make time go
        // backwards in the journal
        let time_offset_s = (last.time_s - self.elapsed_s(journal.header())).max(0.0);
        Ok((last.state.clone(), time_offset_s, Some(journal.next_step())))
    }

    /// The thermometer's reading \[°C\], `None` without a thermometer.
    fn read_temperature(&mut self, step: StepLabel) -> Result<Option<f64>, CampaignError> {
        match self.devices.thermometer.as_mut() {
            Some(t) => t.read_c().map(Some).map_err(device_err(step, "reading the thermometer")),
            None => Ok(None),
        }
    }

    fn elapsed_s(&self, header: &JournalHeader) -> f64 {
        self.devices.clock.now_s() - header.start_clock_s
    }

    fn progress_bar(&self, steps: usize, done: usize) -> ProgressBar {
        let target = if self.config.show_progress {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        };
        let bar = ProgressBar::with_draw_target(Some(steps as u64), target);
        if let Ok(style) = ProgressStyle::with_template(
            "[{elapsed_precise}] {wide_bar} {pos}/{len} steps, ETA {eta} — {msg}",
        ) {
            bar.set_style(style);
        }
        bar.set_position(done as u64);
        bar.reset_eta();
        bar
    }

    /// Checks that the devices fit the controller model (arm joint count, guide present
    /// exactly when the model has one) before anything moves, then activates and homes them.
    fn prepare_devices(&mut self) -> Result<(), CampaignError> {
        let mismatch = |reason: String| CampaignError::DeviceMismatch {
            chain: self.controller.describe_chain(),
            reason,
        };
        let layout = self.layout;
        match (layout.has_guide(), self.devices.guide.is_some()) {
            (true, false) => {
                return Err(mismatch("joint 1 is a prismatic guide but no guide device is connected".into()));
            }
            (false, true) => {
                return Err(mismatch("a guide device is connected but the model has no guide joint".into()));
            }
            _ => {}
        }
        let n = self.devices.arm.joint_count();
        if let Err(e) = layout.check_arm_count(n) {
            return Err(mismatch(e.to_string()));
        }
        let t = self.config.home_timeout;
        let d = &mut self.devices;
        d.arm.activate_and_home(t).map_err(device_err(StepLabel::Setup, "activating and homing the arm"))?;
        if let Some(guide) = d.guide.as_deref_mut() {
            let homed = guide.is_homed().map_err(device_err(StepLabel::Setup, "reading the guide state"))?;
            if !homed {
                guide.home(t).map_err(device_err(StepLabel::Setup, "homing the guide"))?;
            }
        }
        Ok(())
    }

    fn read_joints(&mut self, step: StepLabel) -> Result<JointVector, CampaignError> {
        let arm = self.devices.arm.joints().map_err(device_err(step, "reading the arm joints"))?;
        let guide = match self.devices.guide.as_deref_mut() {
            Some(g) => Some(g.position_mm().map_err(device_err(step, "reading the guide position"))?),
            None => None,
        };
        self.layout.join(guide, &arm).map_err(device_err(step, "reading the arm joints"))
    }

    fn initial_state(&mut self) -> Result<State, CampaignError> {
        let joints = self.read_joints(StepLabel::Setup)?;
        Ok(CellState {
            arm_from: self.layout.arm(&joints).values(),
            guide_from_mm: self.layout.guide_mm(&joints),
            joints,
            dir: vec![0; self.layout.arm_joint_count()],
            placement: self.config.plate_at_start,
        })
    }

    /// `q` in file units (mm / degrees) for messages.
    fn file_units(&self, q: &JointVector) -> String {
        let v = q.to_file_units(self.controller.joint_kinds());
        v.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(", ")
    }

    /// Commands guide and arm to `target` together, waits for both, and updates the state
    /// (`*_from` = the joints before this command, `dir` from the joints that changed).
    fn move_to(
        &mut self,
        step: StepLabel,
        target: &JointVector,
        state: &mut State,
    ) -> Result<(), CampaignError> {
        let options = self.config.motion;
        let before = self.read_joints(step)?;
        let layout = self.layout;
        let q_text = self.file_units(target);
        let what = |s: &str| format!("{s} to q = [{q_text}] (mm/deg)");
        let d = &mut self.devices;
        let guide_target = layout.guide_mm(target);
        if let (Some(guide), Some(g)) = (d.guide.as_deref_mut(), guide_target) {
            guide.move_absolute_mm(g, &options).map_err(device_err(step, what("moving the guide")))?;
        }
        d.arm.move_joints(&layout.arm(target), &options).map_err(device_err(step, what("moving the arm")))?;
        if let (Some(guide), Some(_)) = (d.guide.as_deref_mut(), guide_target) {
            guide.wait_idle(options.timeout).map_err(device_err(step, what("waiting for the guide")))?;
        }
        d.arm.wait_idle(options.timeout).map_err(device_err(step, what("waiting for the arm")))?;
        let after = self.read_joints(step)?;
        state.arm_from = layout.arm(&before).values();
        state.guide_from_mm = layout.guide_mm(&before);
        update_dir(&layout, &mut state.dir, &before, &after);
        state.joints = after;
        Ok(())
    }

    /// Puts the cell back into the recorded state `s`: plate confirmed at its position, then
    /// guide and arm replay the last motion of the recorded step (from `*_from` to the recorded
    /// joints), the arm first approaching `arm_from` from the side each joint last moved on.
    fn recover(&mut self, s: &State) -> Result<(), CampaignError> {
        let step = StepLabel::Setup;
        if let Some(position) = s.placement {
            self.devices
                .operator
                .perform(&OperatorInstruction::PlaceProbe { position })
                .map_err(device_err(step, "confirming the probe plate after a restart"))?;
        }
        let description = format!(
            "resuming: the {} return{} to the last recorded pose q = [{}] (mm/deg)",
            if self.layout.has_guide() { "guide and the arm" } else { "arm" },
            if self.layout.has_guide() { "" } else { "s" },
            self.file_units(&s.joints)
        );
        self.devices
            .operator
            .perform(&OperatorInstruction::ConfirmMotion { description })
            .map_err(device_err(step, "confirming the recovery motion"))?;
        let layout = self.layout;
        let target_arm = layout.arm(&s.joints);
        let arm_from = ArmJoints::from_values(s.arm_from);
        let limits = self.controller.joint_limits();
        let mut pre = arm_from;
        for j in 0..pre.len().min(target_arm.len()) {
            let d = s.dir.get(j).copied().unwrap_or(0);
            if arm_from[j] == target_arm[j] && d != 0 {
                let (lo, hi) = limits[layout.cell_joint(j) - 1];
                pre[j] = (pre[j] - f64::from(d) * self.config.recovery_approach_rad).clamp(lo, hi);
            }
        }
        let mut scratch = s.clone();
        let guide_from = s.guide_from_mm;
        for (guide, arm) in
            [(guide_from, pre), (guide_from, arm_from), (layout.guide_mm(&s.joints), target_arm)]
        {
            let q = layout.join(guide, &arm).map_err(device_err(step, "restoring the recorded pose"))?;
            self.move_to(step, &q, &mut scratch)?;
        }
        Ok(())
    }

    fn warm_up(&mut self, w: &WarmUp, state: &mut State) -> Result<(), CampaignError> {
        if w.path.is_empty() {
            return Ok(());
        }
        let start = self.devices.clock.now();
        while self.devices.clock.now().saturating_sub(start) < w.duration {
            for q in &w.path {
                self.move_to(StepLabel::Setup, q, state)?;
            }
        }
        Ok(())
    }

    fn execute(
        &mut self,
        step: usize,
        s: &CampaignStep,
        state: &mut State,
    ) -> Result<StepOutcome, CampaignError> {
        let label = StepLabel::Step(step);
        match s {
            CampaignStep::PlaceProbe { position } => {
                self.devices
                    .operator
                    .perform(&OperatorInstruction::PlaceProbe { position: *position })
                    .map_err(device_err(label, format!("placing the probe plate at position {position}")))?;
                state.placement = Some(*position);
                Ok(StepOutcome::ProbePlaced { position: *position })
            }
            CampaignStep::ZeroProbe { position } => {
                let d = &mut self.devices;
                d.operator
                    .perform(&OperatorInstruction::SeatMasterBall { position: *position })
                    .map_err(device_err(label, "seating the master ball"))?;
                d.probe.preset_master().map_err(device_err(label, "presetting the gauges"))?;
                d.operator
                    .perform(&OperatorInstruction::RemoveMasterBall)
                    .map_err(device_err(label, "removing the master ball"))?;
                Ok(StepOutcome::ProbeZeroed { position: *position })
            }
            CampaignStep::Move { path } => {
                for q in path {
                    self.move_to(label, q, state)?;
                }
                Ok(StepOutcome::Moved)
            }
            CampaignStep::Measure { position, tcp } => self.measure(step, *position, *tcp, state),
            CampaignStep::Track { tcp } => self.track(step, *tcp, state),
        }
    }

    /// One tracker reading of target `tcp` at the current pose, the controller model's
    /// prediction given as the tracker's hint; retried and skipped as the configuration says.
    fn track(&mut self, step: usize, tcp: u32, state: &State) -> Result<StepOutcome, CampaignError> {
        let label = StepLabel::Step(step);
        let hint = self.controller.tcp_position(&state.joints, tcp).ok();
        let tracker = self.devices.tracker.as_mut().ok_or(CampaignError::NoTracker { step })?;
        let attempts = self.config.tracker_retries.saturating_add(1);
        let mut attempt = 0;
        let error = loop {
            attempt += 1;
            match tracker.measure_near_mm(tcp, hint.as_ref()) {
                Ok(p) => return Ok(StepOutcome::Tracked { tcp, xyz_mm: [p.x, p.y, p.z] }),
                Err(e) if attempt < attempts && retryable(e.kind()) => continue,
                Err(e) => break e,
            }
        };
        let action =
            format!("tracking target {tcp} ({attempt} attempt{})", if attempt == 1 { "" } else { "s" });
        if self.config.skip_failed_tracks && retryable(error.kind()) {
            return Ok(StepOutcome::Skipped { reason: format!("{action}: {error}") });
        }
        Err(CampaignError::Device { step: label, action, source: error })
    }

    fn measure(
        &mut self,
        step: usize,
        position: u32,
        tcp: u32,
        state: &mut State,
    ) -> Result<StepOutcome, CampaignError> {
        let label = StepLabel::Step(step);
        let d = &mut self.devices;
        let result = auto_center(
            &mut *d.arm,
            d.guide.as_deref_mut().map(|g| g as &mut dyn LinearAxis),
            &mut *d.probe,
            self.controller,
            position,
            &state.dir,
            &self.config.centering,
        );
        match result {
            Ok(o) => {
                state.dir = o.approach_dir;
                if let Some(from) = o.last_motion_from {
                    state.arm_from = from.values();
                }
                state.joints = self.read_joints(label)?;
                let g = o.final_reading.gauges_mm;
                let c = o.final_reading.offset_mm;
                Ok(StepOutcome::Measured {
                    position,
                    tcp,
                    readings_mm: g,
                    offset_mm: [c.x, c.y, c.z],
                    offset_world_mm: Some(o.final_offset_world_mm.into()),
                    iterations: o.iterations,
                    composite_history_mm: o.composite_history_mm,
                })
            }
            Err(source) if self.config.skip_failed_measurements => {
                let reason = format!("auto-centering TCP {tcp} at position {position}: {source}");
                // back to the approach pose (clearing a controller fault first)
                let approach = state.joints;
                let status = d.arm.status().map_err(device_err(label, "reading the arm status"))?;
                if status.error.is_some() {
                    d.arm.reset_error().map_err(device_err(label, "resetting the arm error"))?;
                }
                self.move_to(label, &approach, state)?;
                Ok(StepOutcome::Skipped { reason })
            }
            Err(source) => Err(CampaignError::Centering { step, position, tcp, source }),
        }
    }
}

/// Tracker faults worth another try: the SMR out of sight, silence, garbage, a device fault.
/// A cancelled (operator) or gone (link) tracker is not.
fn retryable(kind: ErrorKind) -> bool {
    matches!(
        kind,
        ErrorKind::OutOfRange
            | ErrorKind::Timeout
            | ErrorKind::Protocol
            | ErrorKind::DeviceFault { .. }
            | ErrorKind::Busy
    )
}

/// Signs of the arm joints that changed between `before` and `after` (cell joint vectors).
fn update_dir(layout: &JointLayout, dir: &mut Vec<i8>, before: &JointVector, after: &JointVector) {
    let (a, b) = (layout.arm(before), layout.arm(after));
    dir.resize(a.len(), 0);
    for (d, (a, b)) in dir.iter_mut().zip(a.as_slice().iter().zip(b.as_slice())) {
        if b != a {
            *d = if b > a { 1 } else { -1 };
        }
    }
}

fn describe(step: &CampaignStep) -> String {
    match step {
        CampaignStep::PlaceProbe { position } => format!("placing the probe at position {position}"),
        CampaignStep::ZeroProbe { position } => format!("zeroing the probe at position {position}"),
        CampaignStep::Move { path } => format!("moving ({} waypoints)", path.len()),
        CampaignStep::Measure { position, tcp } => format!("centring TCP {tcp} at position {position}"),
        CampaignStep::Track { tcp } => format!("tracking target {tcp}"),
    }
}

/// Writes `measurements` to `path` through a temporary file and a rename, so a crash never
/// leaves a half-written CSV.
fn write_csv_atomically(
    path: &Path,
    measurements: &[Measurement],
    kinds: &[JointKind],
    noise: &vatcal_io::metadata::NoiseMetadata,
) -> Result<(), CampaignError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    vatcal_io::write_measurements_with_noise(&tmp, measurements, kinds, noise)?;
    std::fs::rename(&tmp, path)
        .map_err(|source| vatcal_io::IoError::File { path: path.to_path_buf(), cause: source }.into())
}

/// Writes the measurements of a (possibly unfinished) journal of the canonical
/// Meca500-on-guide cell as a measurements CSV (`position,tcp,q1..q7,time_s[,temperature_c],
/// dir2..dir7`, mm/deg; tracker rows with `x,y,z`); [`export_measurements_for`] writes any
/// chain. Returns the number of measurements written.
///
/// # Errors
/// The journal cannot be read or the CSV written.
pub fn export_measurements(journal: impl AsRef<Path>, csv: impl AsRef<Path>) -> Result<usize, CampaignError> {
    export_measurements_for(journal, csv, &vatcal_io::MECA500_ON_GUIDE_KINDS)
}

/// [`export_measurements`] for a chain with joints `kinds` (`model.joint_kinds()`):
/// `q1..qN` (mm for prismatic, degrees for revolute joints) and `dir{j}` of the revolute joints.
///
/// # Errors
/// The journal cannot be read or the CSV written.
pub fn export_measurements_for(
    journal: impl AsRef<Path>,
    csv: impl AsRef<Path>,
    kinds: &[JointKind],
) -> Result<usize, CampaignError> {
    let j = Journal::open(journal)?;
    let m = j.measurements();
    vatcal_io::write_measurements_for(csv, &m, kinds)?;
    Ok(m.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(times_s: &[f64], resumed_at: Option<usize>) -> CampaignReport {
        let records = times_s
            .iter()
            .enumerate()
            .map(|(step, &time_s)| StepRecord {
                step,
                time_s,
                temperature_c: None,
                state: CellState {
                    joints: JointVector::default(),
                    arm_from: JointVector::default(),
                    guide_from_mm: None,
                    dir: Vec::new(),
                    placement: None,
                },
                outcome: StepOutcome::Moved,
                resumed: resumed_at == Some(step),
            })
            .collect();
        CampaignReport {
            measurements: Vec::new(),
            records,
            resumed_at_step: resumed_at,
            torn_bytes_dropped: 0,
            skipped: 0,
        }
    }

    #[test]
    fn device_time_leaves_out_the_stop_and_restart_of_a_resumed_run() {
        // steps of 10, 12, 11 s; an uninterrupted run: the last record's time
        let uninterrupted = report(&[10.0, 22.0, 33.0, 45.0], None);
        assert_eq!(uninterrupted.device_s(), 45.0);
        // the same run stopped after step 1 and resumed an hour later: step 2 is counted at the
        // median of the other steps (10, 12, 12 s: 12 s), not at the hour
        let resumed = report(&[10.0, 22.0, 3633.0, 3645.0], Some(2));
        assert!((resumed.device_s() - (10.0 + 12.0 + 12.0 + 12.0)).abs() < 1e-12, "{}", resumed.device_s());
        assert!((resumed.device_s() - uninterrupted.device_s()).abs() < 2.0);
        assert_eq!(report(&[], None).device_s(), 0.0);
    }
}
