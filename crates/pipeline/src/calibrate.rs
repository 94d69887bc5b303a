//! The run as resumable stages (`vatcal calibrate`, and `vatcal demo` on the virtual cell).
//!
//! [`calibrate`] executes the stages of [`Stage::ALL`] — `plan`, `campaign`, `identify`,
//! `discovery`, `validation`, `compensation` — on any [`DeviceSource`], writing one run
//! folder. Every stage's state is kept in the folder's [`STAGES_FILE`] (`stages.json`:
//! `running` or `done`, attempts, wall time and device-clock time), and every stage reads its
//! inputs from the folder:
//!
//! | stage | reads | writes |
//! |---|---|---|
//! | `plan` | the nominal cell | `plan/` (`tour.csv`, …) |
//! | `campaign` | `plan/tour.csv` | `campaign.journal`, `measurements.csv` |
//! | `identify` | `campaign.journal` | `calibrated.toml` |
//! | `discovery` | `campaign.journal`, the calibrated model | `discovery_plan/`, `discovery.journal`, `discovery_measurements.csv`, effect plots |
//! | `validation` | the models (nominal, calibrated, discovered), where the last campaign left the arm | `tracker-registration.json` ([`crate::registration`], unless the devices skip it), `validation.journal` |
//! | `compensation` | `validation.journal`, the compensated printing path | `report.json`, `summary.md` (and `.html`), CSVs, SVG plots, `timing.json` |
//!
//! The journals are the only measured data; everything derived from them (the plan, the
//! identification, the discovery loop, the validation's evaluation) is deterministic and is
//! recomputed, bit for bit, when a later stage needs it and its stage is already `done`.
//!
//! * **Fresh run** (the `plan` stage selected, no resume): the folder's journals and stage
//!   state are removed first.
//! * **Resume** ([`CalibrateOptions::resume`]): `done` stages are skipped (their results
//!   recomputed from the folder), a stage left `running` by a crash continues its journal — the
//!   campaign runner restores the cell into the last recorded state and goes on with the next
//!   step, so nothing is lost or measured twice.
//! * **A stage on its own** (a subset of stages, no resume): each selected stage is run again
//!   (its journal removed first: it measures afresh), every later stage's `done` is cleared,
//!   and every earlier stage must be `done` (the error names it). `discovery` is optional: when
//!   it is neither selected nor done, the validation measures the nominal and the calibrated
//!   model only.

use std::path::Path;

use vatcal_identification::Identification;

use crate::book::Book;
use crate::discovery_stage::DiscoveryStageOptions;
use crate::report::ReportSetup;
use crate::steps::{self, Run};
use crate::{DeviceSet, PipelineError, Progress, RunOptions, RunOutcome, Stage};

pub use crate::cell_setup::{CELL_REPORT_FORMAT, CellRunSetup};
pub use crate::devices::{DeviceSource, Lent};
pub use crate::folders::STAGES_FILE;
pub use crate::outcome::CalibrateOutcome;
pub use crate::state::{CalibrateOptions, STAGES_FORMAT, StageEntry, StageStatus, StagesFile};

/// Runs the selected stages of a calibration on the devices of `devices` into the run
/// folder `out` (module docs: fresh run, resume, single stages). `discovery`, when given,
/// enables the discovery stage. `setup` describes the cell for the report.
///
/// Each stage takes the outputs of the stages before it and returns its own (`crate::steps`);
/// this function only sequences them and stops after the last selected one.
///
/// # Errors
/// Invalid sizes or stages (checked before anything runs), a needed stage not done, a run
/// folder of other options, any stage's error (the stage stays `running`: run again with
/// `resume`).
pub fn calibrate<S: ReportSetup>(
    opts: &RunOptions,
    discovery: Option<&DiscoveryStageOptions>,
    cal: &CalibrateOptions,
    devices: &mut dyn DeviceSource,
    setup: impl FnOnce(&Identification) -> S,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<CalibrateOutcome<S>, PipelineError> {
    opts.sizes.check()?;
    let Some(&last) = cal.stages.iter().max() else {
        return Err(PipelineError::Option { option: "stages".into(), reason: "no stage selected".into() });
    };
    let run = Run::new(opts, discovery, out)?;
    let count = discovery.map(|d| d.count);
    let mut book = Book::open(opts, count, cal, &run.folder, run.nominal.joint_kinds(), progress)?;
    let (plan, params) = steps::plan(&run, &mut book)?;
    if last == Stage::Plan {
        return Ok(book.outcome(None, None));
    }
    let measured = steps::campaign(&run, &mut book, devices)?;
    if last == Stage::Campaign {
        return Ok(book.outcome(None, None));
    }
    let fit = steps::identify(&run, &mut book, &measured, &params)?;
    if last == Stage::Identify {
        return Ok(book.outcome(None, Some(fit)));
    }
    let discovered = steps::discovery(&run, &mut book, devices, &fit, &measured)?;
    if last == Stage::Discover {
        return Ok(book.outcome(None, Some(fit)));
    }
    let validated = steps::validation(&run, &mut book, devices, &fit, discovered.as_ref(), &measured)?;
    if last == Stage::Validate {
        return Ok(book.outcome(None, Some(fit)));
    }
    steps::report(&run, book, setup(&fit), plan, measured, fit, discovered, validated)
}

/// Runs the whole calibration — plan, measurement campaign, identification, validation,
/// report — on `devices`, writing the report folder `out` (created if missing; its journals
/// are removed first so the run starts afresh). `setup` describes the cell for the report,
/// from the identification.
///
/// # Errors
/// Invalid sizes (checked before anything runs), any stage's error, or a file that cannot be
/// written.
pub fn run<S: ReportSetup>(
    opts: &RunOptions,
    devices: &mut dyn DeviceSet,
    setup: impl FnOnce(&Identification) -> S,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<RunOutcome<S>, PipelineError> {
    run_with_discovery(opts, None, devices, setup, out, progress)
}

/// [`run`] with, when `discovery` is given, the discovery stage
/// ([`crate::discovery_stage::discovery_stage`]) between the identification and the validation: the
/// discovered model (and the true-structure model, when the oracle is given) are validated
/// beside the nominal and the calibrated one, `report.json` gains a `discovery` object and the
/// summary a discovery section.
///
/// # Errors
/// As [`run`], and the discovery stage's errors.
pub fn run_with_discovery<S: ReportSetup>(
    opts: &RunOptions,
    discovery: Option<&DiscoveryStageOptions>,
    devices: &mut dyn DeviceSet,
    setup: impl FnOnce(&Identification) -> S,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<RunOutcome<S>, PipelineError> {
    let mut source = Lent(devices);
    let outcome =
        calibrate(opts, discovery, &CalibrateOptions::default(), &mut source, setup, out, progress)?;
    outcome.run.ok_or_else(|| PipelineError::Option {
        option: "stages".into(),
        reason: "the run stopped before the report".into(),
    })
}
