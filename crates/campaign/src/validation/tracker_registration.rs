//! Registration of the laser tracker to the tank (world) frame, as the paper does it (§5): "we
//! placed a 1-inch SMR in the TriCal trihedral nest and inspected the three calibration
//! positions using the laser tracker. Consequently, the measurements with the laser tracker
//! were reported in the same world reference frame as in the proposed calibration procedure."
//!
//! The step, [`register_tracker`]: for every calibration position `n` of the cell, the operator
//! places the probe plate at `n` ([`OperatorInstruction::PlaceProbe`]) and seats the tracker's
//! SMR in the probe's trihedral nest ([`OperatorInstruction::SeatNestSmr`]), whose centre is the
//! probe origin — the calibration position, known in the tank frame from the cell file; the
//! tracker measures it ([`PROBE_NEST_TARGET`]) in its own frame. The rigid transform
//! `tank ← tracker` that best maps the measured points onto the known ones is the
//! least-squares fit of [`fit_rigid_transform`] (Kabsch, SVD). Its residuals — the distance
//! between each known position and its registered measurement — are the registration's own
//! error estimate (the paper: "as much as 20 µm of measurement errors in measuring the world
//! reference frame"); they go into the validation report.
//!
//! [`TrackerRegistration::register`] then wraps the tracker in a [`RegisteredTracker`], which
//! maps every later reading into the tank frame. The result is saved as JSON
//! ([`TrackerRegistration::save`]) in the run folder, so a resumed validation reuses it.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use vatcal_core::Frame;
use vatcal_hardware_traits::{
    Operator, OperatorInstruction, PROBE_NEST_TARGET, PositionTracker, RegisteredTracker,
};
use vatcal_kinematics::Model;

use super::registration::{RegistrationError, fit_rigid_transform};

/// Why the tracker cannot be registered.
#[derive(Debug, thiserror::Error)]
pub enum TrackerRegistrationError {
    /// The cell has fewer than three calibration positions, or one is unknown.
    #[error("tracker registration: {0}")]
    Positions(String),
    /// The operator or the tracker failed at a calibration position (after the retries).
    #[error("tracker registration at calibration position {position}: {source}")]
    Device {
        /// calibration position
        position: u32,
        /// the device error
        source: vatcal_hardware_traits::Error,
    },
    /// The measured points do not determine a transform.
    #[error("tracker registration: {0}")]
    Fit(#[from] RegistrationError),
    /// The registration file cannot be read or written.
    #[error("{path}: {message}")]
    File {
        /// the file
        path: PathBuf,
        /// what went wrong
        message: String,
    },
}

/// One registration measurement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegistrationPoint {
    /// calibration position id
    pub position: u32,
    /// the probe origin in the tank frame (cell file) \[mm\]
    pub tank_mm: [f64; 3],
    /// the nest SMR as the tracker measured it, tracker frame \[mm\]
    pub tracker_mm: [f64; 3],
    /// distance between `tank_mm` and the registered measurement \[mm\]
    pub residual_mm: f64,
}

/// The registration `tank ← tracker` and the measurements it was fitted to.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackerRegistration {
    /// the measurements, one per calibration position
    pub points: Vec<RegistrationPoint>,
    /// rotation of `tank ← tracker`, row by row
    pub rotation: [[f64; 3]; 3],
    /// translation of `tank ← tracker` \[mm\]
    pub translation_mm: [f64; 3],
    /// root-mean-square residual \[mm\]
    pub rms_residual_mm: f64,
    /// largest residual \[mm\]
    pub max_residual_mm: f64,
}

impl TrackerRegistration {
    /// Fits `tank ← tracker` to `(position, tank point, tracker point)` triples (at least three,
    /// not collinear).
    ///
    /// # Errors
    /// Fewer than three points, collinear or non-finite points.
    pub fn fit(points: &[(u32, Vector3<f64>, Vector3<f64>)]) -> Result<Self, RegistrationError> {
        let tracker: Vec<_> = points.iter().map(|p| p.2).collect();
        let tank: Vec<_> = points.iter().map(|p| p.1).collect();
        let frame = fit_rigid_transform(&tracker, &tank)?;
        let points: Vec<_> = points
            .iter()
            .map(|(position, tank, tracker)| RegistrationPoint {
                position: *position,
                tank_mm: (*tank).into(),
                tracker_mm: (*tracker).into(),
                residual_mm: (frame.transform_point(tracker) - tank).norm(),
            })
            .collect();
        let n = points.len() as f64;
        let rms = (points.iter().map(|p| p.residual_mm.powi(2)).sum::<f64>() / n).sqrt();
        let max = points.iter().map(|p| p.residual_mm).fold(0.0, f64::max);
        let r = frame.r;
        Ok(Self {
            points,
            rotation: [
                [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            ],
            translation_mm: frame.p.into(),
            rms_residual_mm: rms,
            max_residual_mm: max,
        })
    }

    /// The same measurements taken as they are (`tank ← tracker` the identity): the check of a
    /// tracker that reports in the tank frame already (its software is registered) — each
    /// residual is then how far the tracker's reading of the nest is from the known position.
    pub fn checked(&self) -> Self {
        let points: Vec<_> = self
            .points
            .iter()
            .map(|p| RegistrationPoint {
                residual_mm: (Vector3::from(p.tracker_mm) - Vector3::from(p.tank_mm)).norm(),
                ..p.clone()
            })
            .collect();
        let n = points.len().max(1) as f64;
        Self {
            rms_residual_mm: (points.iter().map(|p| p.residual_mm.powi(2)).sum::<f64>() / n).sqrt(),
            max_residual_mm: points.iter().map(|p| p.residual_mm).fold(0.0, f64::max),
            points,
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation_mm: [0.0; 3],
        }
    }

    /// The transform `tank ← tracker`.
    pub fn tank_from_tracker(&self) -> Frame {
        let r = self.rotation;
        Frame {
            r: Matrix3::new(r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2]),
            p: Vector3::from(self.translation_mm),
        }
    }

    /// `tracker` with its readings mapped into the tank frame.
    pub fn register<T: PositionTracker>(&self, tracker: T) -> RegisteredTracker<T> {
        RegisteredTracker::new(tracker, self.tank_from_tracker())
    }

    /// One line for a report: points, RMS and largest residual in µm.
    pub fn summary(&self) -> String {
        format!(
            "tracker registered to the tank on {} calibration positions: residual RMS {:.1} µm, max {:.1} µm",
            self.points.len(),
            self.rms_residual_mm * 1e3,
            self.max_residual_mm * 1e3
        )
    }

    /// Writes the registration as JSON (through a temporary file and a rename).
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), TrackerRegistrationError> {
        let path = path.as_ref();
        let file_err = |message: String| TrackerRegistrationError::File { path: path.into(), message };
        let text = serde_json::to_string_pretty(self).map_err(|e| file_err(e.to_string()))?;
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".tmp");
        std::fs::write(&tmp, text + "\n").map_err(|e| file_err(e.to_string()))?;
        std::fs::rename(&tmp, path).map_err(|e| file_err(e.to_string()))
    }

    /// Reads a registration written by [`TrackerRegistration::save`].
    ///
    /// # Errors
    /// The file cannot be read or is not a registration (the message names line and column).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, TrackerRegistrationError> {
        let path = path.as_ref();
        let file_err = |message: String| TrackerRegistrationError::File { path: path.into(), message };
        let text = std::fs::read_to_string(path).map_err(|e| file_err(e.to_string()))?;
        serde_json::from_str(&text).map_err(|e| file_err(e.to_string()))
    }
}

/// Runs the registration step (see the module docs) on the calibration positions `positions`
/// of `controller` (all of them when empty): the operator places the plate and seats the SMR,
/// the tracker measures the nest (a failed reading is tried again up to `retries` times), the
/// operator removes the SMR at the end.
///
/// # Errors
/// Fewer than three positions or an unknown one; the operator or the tracker fails at a
/// position; the points do not determine a transform.
pub fn register_tracker(
    tracker: &mut dyn PositionTracker,
    operator: &mut dyn Operator,
    controller: &Model,
    positions: &[u32],
    retries: u32,
) -> Result<TrackerRegistration, TrackerRegistrationError> {
    register_tracker_resuming(tracker, operator, controller, positions, retries, &[], &mut |_, _| Ok(()))
}

/// [`register_tracker`] continuing an interrupted registration: the nest readings `taken`
/// (`(position, tracker reading [mm])`, e.g. from a journal) are used as they are and their
/// positions are not measured again; every new reading is handed to `on_reading` (which
/// journals it) before the next position is measured.
///
/// # Errors
/// As [`register_tracker`]; `on_reading`'s error stops the registration.
pub fn register_tracker_resuming(
    tracker: &mut dyn PositionTracker,
    operator: &mut dyn Operator,
    controller: &Model,
    positions: &[u32],
    retries: u32,
    taken: &[(u32, Vector3<f64>)],
    on_reading: &mut dyn FnMut(u32, Vector3<f64>) -> Result<(), TrackerRegistrationError>,
) -> Result<TrackerRegistration, TrackerRegistrationError> {
    let positions = if positions.is_empty() { controller.position_ids() } else { positions.to_vec() };
    if positions.len() < 3 {
        return Err(TrackerRegistrationError::Positions(format!(
            "needs at least 3 calibration positions, the cell has {}",
            positions.len()
        )));
    }
    let mut points = Vec::with_capacity(positions.len());
    for position in positions {
        let tank = controller.position(position).ok_or_else(|| {
            TrackerRegistrationError::Positions(format!("the cell has no calibration position {position}"))
        })?;
        if let Some((_, measured)) = taken.iter().find(|(p, _)| *p == position) {
            points.push((position, tank, *measured));
            continue;
        }
        let device = |source| TrackerRegistrationError::Device { position, source };
        operator.perform(&OperatorInstruction::PlaceProbe { position }).map_err(device)?;
        operator.perform(&OperatorInstruction::SeatNestSmr { position }).map_err(device)?;
        let mut attempt = 0;
        let measured = loop {
            attempt += 1;
            match tracker.measure_mm(PROBE_NEST_TARGET) {
                Ok(p) => break p,
                Err(e)
                    if attempt <= retries
                        && !matches!(
                            e.kind(),
                            vatcal_hardware_traits::ErrorKind::Cancelled
                                | vatcal_hardware_traits::ErrorKind::Disconnected
                        ) => {}
                Err(e) => return Err(device(e.context(format_args!("nest SMR, attempt {attempt}")))),
            }
        };
        on_reading(position, measured)?;
        points.push((position, tank, measured));
    }
    operator.perform(&OperatorInstruction::RemoveNestSmr).map_err(|source| {
        TrackerRegistrationError::Device { position: points.last().map_or(0, |p| p.0), source }
    })?;
    Ok(TrackerRegistration::fit(&points)?)
}
