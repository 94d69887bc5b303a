#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Runs the measurement campaign of the paper (§2.4, §4.3) on **any** devices implementing the
//! traits of `vatcal-hardware-traits` — real drivers or the virtual cell of `vatcal-sim`:
//!
//! * [`auto_center`] — TriCal auto-centering: read the probe offset, move the TCP by its
//!   opposite, repeat until the composite error is below 5 µm; guide stationary; capped steps,
//!   abort on growing error, range or iteration cap ([`CenteringError`]).
//! * [`CampaignPlan`] / [`CampaignStep`] — what to do: place the probe plate, zero it, move
//!   along joint-space waypoints, measure (auto-centre and record), track.
//! * [`Journal`] — crash-safe, append-only, one checksummed record per line, `fsync`ed; a torn
//!   last record is dropped on resume, anything else damaged is an error.
//! * [`Campaign`] — executes a plan, journals every step, resumes after a crash exactly where it
//!   stopped (nothing lost, nothing repeated), asks the [`Operator`](vatcal_hardware_traits::Operator)
//!   to re-place the plate, shows a progress bar with ETA, returns the measurements
//!   (`position,tcp,q1..q7,time_s[,temperature_c],dir2..dir7` once written with `vatcal_io::write_measurements`).
//! * [`validation`] — the laser-tracker validation campaign of the paper's §5: random poses
//!   over the workspace and a six-dimensional printing path commanded by each model under test,
//!   planned as campaign steps, run by the same [`Campaign`] runner, evaluated (errors,
//!   statistics, lever effect) and plotted.
//!
//! Units: mm and rad in every API; the journal stores internal units bit-exactly; files written
//! for users (the measurements CSV) use mm and degrees.

mod centering;
mod checksum;
mod console;
mod journal;
mod plan;
mod runner;
pub mod validation;

pub use centering::{CenteringConfig, CenteringError, CenteringOutcome, auto_center};
pub use checksum::fnv1a64;
pub use console::ConsoleOperator;
pub use journal::{
    CellState, JOURNAL_FORMAT, JOURNAL_VERSION, Journal, JournalError, JournalHeader, StepOutcome, StepRecord,
};
pub use plan::{CampaignPlan, CampaignPlanError, CampaignPlanOptions, CampaignStep, TourFileError};
pub use runner::{
    Campaign, CampaignConfig, CampaignError, CampaignReport, CellDevices, StepLabel, WarmUp,
    export_measurements, export_measurements_for,
};
