//! Measurements: what the cell recorded, in internal units.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::units::{JointVector, MAX_JOINTS};

/// Joint-motion directions of the canonical 7-joint Meca500-on-guide cell from the six arm
/// directions (J1..J6 = cell joints 2..7): index `i - 1` holds joint i, the guide (joint 1)
/// gets 0.
pub fn dirs_from_meca500_arm(arm: [i8; 6]) -> [i8; MAX_JOINTS] {
    let mut d = [0; MAX_JOINTS];
    d[1..7].copy_from_slice(&arm);
    d
}

/// Optional per-sample data that some effects need.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MeasurementContext {
    /// sign (+1/-1, 0 = unknown) of the last motion of each joint before the record
    /// (`dir{i}` columns, revolute joints only); index `i - 1` is joint i, unused entries 0
    pub dir: Option<[i8; MAX_JOINTS]>,
    /// seconds since the campaign start
    pub time_s: Option<f64>,
    /// temperature \[°C\]
    pub temperature_c: Option<f64>,
}

impl MeasurementContext {
    /// Motion direction of joint `joint` (1-based): +1, -1, or 0 when unknown / not recorded.
    #[inline]
    pub fn dir_of(&self, joint: u8) -> i8 {
        match (self.dir, (joint as usize).checked_sub(1)) {
            (Some(d), Some(k)) if k < MAX_JOINTS => d[k],
            _ => 0,
        }
    }
}

/// What a measurement observed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Target {
    /// The TCP sat on the probe origin at calibration position `position` (residual
    /// `calibration_position - FK`).
    Probe {
        /// calibration position id
        position: u32,
    },
    /// The TCP was measured at `xyz_mm` in the world frame (residual `measured - FK`).
    Tracker {
        /// measured world position \[mm\]
        xyz_mm: Vector3<f64>,
    },
}

/// One measurement: joints, which TCP, what was observed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// TCP id
    pub tcp: u32,
    /// joints (internal units)
    pub q: JointVector,
    /// what was observed
    pub target: Target,
    /// optional per-sample data
    pub context: MeasurementContext,
    /// probe measurements: the final centring offset read by the gauges, in world axes
    /// (ball centre − probe origin, at most the centring tolerance, ~5 µm) \[mm\]. The observed
    /// target is then `calibration position + offset` instead of the position itself. `None`
    /// (or a tracker measurement) = no offset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe_offset_mm: Option<Vector3<f64>>,
}

impl Measurement {
    /// A probe measurement without context data.
    pub fn probe(position: u32, tcp: u32, q: JointVector) -> Self {
        Self {
            tcp,
            q,
            target: Target::Probe { position },
            context: MeasurementContext::default(),
            probe_offset_mm: None,
        }
    }

    /// A tracker measurement without context data.
    pub fn tracker(tcp: u32, q: JointVector, xyz_mm: Vector3<f64>) -> Self {
        Self {
            tcp,
            q,
            target: Target::Tracker { xyz_mm },
            context: MeasurementContext::default(),
            probe_offset_mm: None,
        }
    }

    /// The same probe measurement with the final centring offset `offset_mm` (world axes)
    /// recorded: the observed target becomes `calibration position + offset_mm`.
    pub fn with_probe_offset(mut self, offset_mm: Vector3<f64>) -> Self {
        self.probe_offset_mm = Some(offset_mm);
        self
    }

    /// What to add to the model's residual ([`Target`]: `position − FK` / `measured − FK`) to
    /// get the residual against the observed target: the recorded centring offset of a probe
    /// measurement, zero otherwise \[mm\].
    pub fn target_offset_mm(&self) -> Vector3<f64> {
        match (self.target, self.probe_offset_mm) {
            (Target::Probe { .. }, Some(o)) => o,
            _ => Vector3::zeros(),
        }
    }

    /// Calibration position id for probe measurements.
    pub fn position(&self) -> Option<u32> {
        match self.target {
            Target::Probe { position } => Some(position),
            Target::Tracker { .. } => None,
        }
    }
}
