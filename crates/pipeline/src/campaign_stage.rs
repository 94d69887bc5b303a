//! The `campaign` stage: the planned probe measurements on any [`DeviceSet`] with TriCal
//! auto-centering, the crash-safe journal (`campaign.journal`) and `measurements.csv` (also
//! what `vatcal campaign` runs on the real cell).
//!
//! Input: the devices, the nominal model and the plan folder's tour; output: the
//! [`CampaignReport`] (every measurement and journal record).

use vatcal_campaign::{CampaignConfig, CampaignPlan, CampaignReport};
use vatcal_kinematics::Model;

use crate::campaign_runner::run_campaign;
use crate::folders::RunFolder;
use crate::{DeviceSet, PipelineError, Progress, Stage};

/// Runs `tour` on `devices`, journaling into the run folder's `campaign.journal` (a journal
/// of the same plan is resumed where it stopped: nothing lost, nothing repeated), reporting
/// the start of [`Stage::Campaign`] and every step to `progress`, and writes
/// `measurements.csv` at the end.
///
/// # Errors
/// The campaign's error (the journal keeps every completed step: run again to resume).
pub fn campaign_stage(
    devices: &mut dyn DeviceSet,
    nominal: &Model,
    tour: &CampaignPlan,
    folder: &RunFolder,
    config: CampaignConfig,
    progress: &mut dyn Progress,
) -> Result<CampaignReport, PipelineError> {
    progress.stage_started(Stage::Campaign, Some(tour.steps.len()));
    let journal = folder.journal();
    let report = run_campaign(devices, nominal, tour, &journal, config, Stage::Campaign, None, progress)?;
    folder.write_measurements(&report.measurements, nominal.joint_kinds())?;
    Ok(report)
}

/// The devices' time for a campaign: this process's clock readings (`clock_delta_s`) for a
/// campaign run from its start, else the journal's step durations with the stop and restart
/// left out ([`CampaignReport::device_s`]).
pub fn device_span(report: &CampaignReport, clock_delta_s: f64) -> f64 {
    match report.resumed_at_step {
        None => clock_delta_s,
        Some(_) if report.records.is_empty() => clock_delta_s,
        Some(_) => report.device_s(),
    }
}
