//! The tracker registration of the validation stage (paper §5): before the first validation
//! reading, the tracker's SMR is seated in the probe's trihedral nest at every calibration
//! position and measured ([`register_tracker_resuming`]; the readings are journaled, so a
//! resumed run does not measure a nest again). A tracker in its own frame is registered —
//! the rigid fit `tank ← tracker` maps every validation reading; a tracker that reports in the
//! tank frame already is checked — the readings are used as they are and the residuals say how
//! far its registration is from the cell's positions ([`TrackerRegistrationMode`]).
//!
//! The result is kept in the run folder ([`TRACKER_REGISTRATION_FILE`]): a resumed validation
//! reuses it (the nest is not measured again) and the report's "Tracker registration" section
//! reads it. Until the fit is saved, every nest reading is journaled
//! ([`TRACKER_READINGS_FILE`]): a registration interrupted between two readings continues with
//! the next calibration position.

use std::path::Path;

use serde::{Deserialize, Serialize};
use vatcal_campaign::validation::{TrackerRegistration, TrackerRegistrationError, register_tracker_resuming};
use vatcal_core::Frame;
use vatcal_kinematics::Model;

use crate::{DeviceSet, PipelineError, TrackerRegistrationMode};

pub use crate::folders::{TRACKER_READINGS_FILE, TRACKER_REGISTRATION_FILE};

/// The tracker registration of a run (`report.json`'s `tracker_registration`, the file
/// [`TRACKER_REGISTRATION_FILE`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegistrationReport {
    /// `register` (fitted `tank ← tracker`, applied to every reading) or `check` (the tracker
    /// reports in the tank frame: transform the identity, residuals of the readings as they are)
    pub mode: String,
    /// the nest measurements (per calibration position: known tank point, tracker reading,
    /// residual), the transform and the residual RMS and maximum
    #[serde(flatten)]
    pub registration: TrackerRegistration,
}

impl RegistrationReport {
    /// The transform applied to the validation's readings: `None` for a check.
    pub fn tank_from_tracker(&self) -> Option<Frame> {
        (self.mode == "register").then(|| self.registration.tank_from_tracker())
    }

    /// Reads the registration of the run folder `out`, `Ok(None)` when there is none.
    ///
    /// # Errors
    /// The file exists and cannot be read or parsed (the message names it, line and column).
    pub fn load(out: &Path) -> Result<Option<Self>, PipelineError> {
        let path = out.join(TRACKER_REGISTRATION_FILE);
        if !path.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path)
            .map_err(|source| PipelineError::Io { path: path.clone(), source })?;
        serde_json::from_str(&text)
            .map(Some)
            .map_err(|e| PipelineError::Folder { path, reason: e.to_string() })
    }

    fn save(&self, out: &Path) -> Result<(), PipelineError> {
        let path = out.join(TRACKER_REGISTRATION_FILE);
        let tmp = out.join(format!("{TRACKER_REGISTRATION_FILE}.tmp"));
        std::fs::write(&tmp, serde_json::to_string_pretty(self)? + "\n")
            .map_err(|source| PipelineError::Io { path: tmp.clone(), source })?;
        std::fs::rename(&tmp, &path).map_err(|source| PipelineError::Io { path, source })
    }

    /// The report's Markdown section.
    pub fn markdown(&self) -> String {
        use std::fmt::Write as _;
        let r = &self.registration;
        let mut m = String::from("## Tracker registration (`tracker-registration.json`)\n\n");
        let _ = writeln!(
            m,
            "{} (paper §5: the SMR seated in the probe's trihedral nest at each calibration position, \
             measured by the tracker).\n",
            if self.mode == "register" {
                "The tracker reports in its own frame: `tank ← tracker` is the rigid least-squares fit of the nest \
                 readings to the calibration positions, and every validation reading is mapped through it"
            } else {
                "The tracker reports in the tank frame (its software is registered): the nest readings are \
                 compared with the calibration positions as they are, and the validation uses the readings unchanged"
            }
        );
        m.push_str(
            "| position | tank x, y, z [mm] | tracker x, y, z [mm] | residual [µm] |\n|---|---|---|---|\n",
        );
        for p in &r.points {
            let _ = writeln!(
                m,
                "| {} | {:.3}, {:.3}, {:.3} | {:.3}, {:.3}, {:.3} | {:.1} |",
                p.position,
                p.tank_mm[0],
                p.tank_mm[1],
                p.tank_mm[2],
                p.tracker_mm[0],
                p.tracker_mm[1],
                p.tracker_mm[2],
                p.residual_mm * 1e3
            );
        }
        let _ = writeln!(
            m,
            "\nresidual RMS {:.1} µm, max {:.1} µm; `tank ← tracker`: rotation {:?}, translation {:.3?} mm\n",
            r.rms_residual_mm * 1e3,
            r.max_residual_mm * 1e3,
            r.rotation.map(|row| row.map(|v| (v * 1e6).round() / 1e6)),
            r.translation_mm
        );
        m
    }
}

/// The registration step of the validation stage on `devices` (module docs): the folder's
/// registration when there is one (a resumed validation), else measured now and saved; `None`
/// with [`TrackerRegistrationMode::Skip`].
///
/// # Errors
/// The devices have no tracker; the operator or the tracker fails (after `retries` retries
/// per reading); the nest readings do not determine a transform; the file cannot be written.
pub fn registration_step(
    devices: &mut dyn DeviceSet,
    controller: &Model,
    out: &Path,
    retries: u32,
) -> Result<Option<RegistrationReport>, PipelineError> {
    let mode = devices.tracker_registration();
    if mode == TrackerRegistrationMode::Skip {
        return Ok(None);
    }
    if let Some(found) = RegistrationReport::load(out)? {
        return Ok(Some(found));
    }
    let cell = devices.devices();
    let Some(tracker) = cell.tracker else {
        return Err(TrackerRegistrationError::Positions("the devices have no tracker".into()).into());
    };
    let partial = out.join(TRACKER_READINGS_FILE);
    let mut taken = load_readings(&partial)?;
    let already = taken.clone();
    let mut journal = |position: u32, reading: nalgebra::Vector3<f64>| {
        taken.push((position, reading));
        save_readings(&partial, &taken)
    };
    let fitted =
        register_tracker_resuming(tracker, cell.operator, controller, &[], retries, &already, &mut journal)?;
    let report = match mode {
        TrackerRegistrationMode::Check => {
            RegistrationReport { mode: "check".into(), registration: fitted.checked() }
        }
        _ => RegistrationReport { mode: "register".into(), registration: fitted },
    };
    report.save(out)?;
    if partial.exists() {
        std::fs::remove_file(&partial)
            .map_err(|source| PipelineError::Io { path: partial.clone(), source })?;
    }
    Ok(Some(report))
}

#[derive(Serialize, Deserialize)]
struct NestReading {
    position: u32,
    tracker_mm: [f64; 3],
}

fn load_readings(path: &Path) -> Result<Vec<(u32, nalgebra::Vector3<f64>)>, PipelineError> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text = std::fs::read_to_string(path)
        .map_err(|source| PipelineError::Io { path: path.to_path_buf(), source })?;
    let readings: Vec<NestReading> = serde_json::from_str(&text)
        .map_err(|e| PipelineError::Folder { path: path.to_path_buf(), reason: e.to_string() })?;
    Ok(readings.into_iter().map(|r| (r.position, r.tracker_mm.into())).collect())
}

/// Writes the readings atomically (temporary file, `fsync`, rename).
fn save_readings(
    path: &Path,
    readings: &[(u32, nalgebra::Vector3<f64>)],
) -> Result<(), TrackerRegistrationError> {
    use std::io::Write as _;
    let list: Vec<NestReading> =
        readings.iter().map(|(p, v)| NestReading { position: *p, tracker_mm: [v.x, v.y, v.z] }).collect();
    let file_err = |e: &dyn std::fmt::Display| TrackerRegistrationError::File {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let text = serde_json::to_string_pretty(&list).map_err(|e| file_err(&e))?;
    let tmp = path.with_extension("json.tmp");
    let mut f = std::fs::File::create(&tmp).map_err(|e| file_err(&e))?;
    f.write_all(text.as_bytes()).and_then(|()| f.sync_all()).map_err(|e| file_err(&e))?;
    std::fs::rename(&tmp, path).map_err(|e| file_err(&e))
}
