//! The campaign runner every measuring stage shares: a campaign plan on the devices, journaled,
//! with progress reports (steps, measurements, time left).

use std::path::Path;

use vatcal_campaign::{Campaign, CampaignConfig, CampaignPlan, CampaignReport, Journal, StepRecord};
use vatcal_kinematics::Model;

use crate::progress::StepCounter;
use crate::{DeviceSet, PipelineError, Progress, Stage};

/// Runs a campaign plan with progress reporting (steps, measurements, time left); with
/// `tank_from_tracker` (a tracker registration) every tracker reading is mapped into the tank
/// frame before it is journaled.
#[allow(clippy::too_many_arguments)] // the campaign's inputs
pub(crate) fn run_campaign(
    devices: &mut dyn DeviceSet,
    nominal: &Model,
    plan: &CampaignPlan,
    journal: &Path,
    config: CampaignConfig,
    stage: Stage,
    tank_from_tracker: Option<&vatcal_core::Frame>,
    progress: &mut dyn Progress,
) -> Result<CampaignReport, PipelineError> {
    let mut counter = StepCounter::new(plan.steps.len(), plan.measurement_count());
    if journal.exists()
        && let Ok(j) = Journal::open(journal)
    {
        counter.resumed(j.next_step(), j.measurements().len());
    }
    let observer = |record: &StepRecord| {
        let p = counter.record(record.step, record.measurement().is_some());
        progress.step_done(stage, p);
    };
    let mut cell = devices.devices();
    let mut registered = match (tank_from_tracker, cell.tracker.take()) {
        (Some(frame), Some(t)) => Some(vatcal_hardware_traits::RegisteredTracker::new(t, *frame)),
        (_, t) => {
            cell.tracker = t;
            None
        }
    };
    if let Some(r) = registered.as_mut() {
        cell.tracker = Some(r);
    }
    let report = Campaign::new(cell, nominal, config).on_record(observer).run(plan, journal)?;
    Ok(report)
}
