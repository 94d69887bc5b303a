//! The devices a run measures with: anything that lends a cell's devices ([`DeviceSet`]),
//! connected only when a stage that moves them runs ([`DeviceSource`]).

use vatcal_campaign::CellDevices;

use crate::PipelineError;

/// Anything that can lend the devices of one cell to a campaign, as often as needed (the
/// measurement campaign, then the validation on the same session).
pub trait DeviceSet {
    /// The devices, borrowed for one campaign.
    fn devices(&mut self) -> CellDevices<'_>;

    /// How the validation stage brings the tracker's readings into the tank frame (default
    /// [`TrackerRegistrationMode::Skip`]: an in-process tracker that reports in the tank frame).
    fn tracker_registration(&self) -> TrackerRegistrationMode {
        TrackerRegistrationMode::Skip
    }
}

/// How the validation stage relates the tracker's frame to the tank frame, before its first
/// tracker measurement (`vatcal_campaign::validation::register_tracker`, paper §5: the SMR
/// seated in the probe's nest at each calibration position).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackerRegistrationMode {
    /// the tracker reports in its own frame: register it (measure the nest at every
    /// calibration position, fit `tank ← tracker`) and map every validation reading through the
    /// fit
    Register,
    /// the tracker reports in the tank frame already (its software is registered): measure the
    /// nest at every calibration position and report how far the readings are from the known
    /// positions, readings used as they are
    Check,
    /// no registration measurement (the in-process virtual tracker of `vatcal demo`, which
    /// reports in the tank frame with its simulated registration error)
    Skip,
}

/// Where the devices of a run come from: connected only when a stage that moves them runs
/// ([`crate::Stage::uses_devices`]), so a run that only recomputes offline stages needs no cell.
/// Every [`DeviceSet`] is one (already connected).
pub trait DeviceSource {
    /// The connected devices.
    ///
    /// # Errors
    /// The devices cannot be connected.
    fn open(&mut self) -> Result<&mut dyn DeviceSet, PipelineError>;
}

impl<T: DeviceSet> DeviceSource for T {
    fn open(&mut self) -> Result<&mut dyn DeviceSet, PipelineError> {
        Ok(self)
    }
}

/// Devices lent by a caller that holds them as a trait object.
pub struct Lent<'a>(pub &'a mut dyn DeviceSet);

impl std::fmt::Debug for Lent<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Lent")
    }
}

impl DeviceSource for Lent<'_> {
    fn open(&mut self) -> Result<&mut dyn DeviceSet, PipelineError> {
        Ok(&mut *self.0)
    }
}
