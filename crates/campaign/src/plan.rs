//! What a campaign does: an ordered list of [`CampaignStep`]s.
//!
//! Until the planning crate's tour file exists, plans are built from a list of measurement
//! poses in tour order ([`CampaignPlan::from_poses`], e.g. the rows of a candidate or selection
//! CSV read with `vatcal_io::read_candidates`), or written by hand.

use serde::{Deserialize, Serialize};
use vatcal_core::{JointVector, Measurement, Target};
use vatcal_kinematics::Model;

use crate::checksum::fnv1a64;

/// One step of a measurement campaign (internal units: q1 mm, q2..q7 rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "step", rename_all = "snake_case")]
pub enum CampaignStep {
    /// The operator places the probe plate at calibration position `position` (the arm must
    /// be clear of the probe).
    PlaceProbe {
        /// calibration position id
        position: u32,
    },
    /// Zero the probe with the master ball: the operator seats it, the gauges are preset, the
    /// operator removes it (the arm must be clear of the probe).
    ZeroProbe {
        /// calibration position the plate is at
        position: u32,
    },
    /// Move through joint-space waypoints (each reached in turn: guide and arm together). The
    /// last waypoint of the move before a [`CampaignStep::Measure`] is the approach pose: the
    /// nominal TCP on the probe origin.
    Move {
        /// waypoints
        path: Vec<JointVector>,
    },
    /// Auto-centre ball `tcp` on the probe (plate at `position`) and record the joints.
    Measure {
        /// calibration position the plate is at
        position: u32,
        /// TCP (ball) id
        tcp: u32,
    },
    /// Measure the world position of target `tcp` with the tracker and record it with the
    /// joints.
    Track {
        /// TCP / SMR id
        tcp: u32,
    },
}

/// Why a plan is rejected before anything moves.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// The plan has no steps.
    #[error("the plan has no steps")]
    Empty,
    /// A waypoint is outside the joint limits or not finite.
    #[error("step {step}: waypoint {waypoint}: joint q{joint} = {value} is outside its limits")]
    Limits {
        /// step index (0-based)
        step: usize,
        /// waypoint index (0-based)
        waypoint: usize,
        /// cell joint 1..=7
        joint: usize,
        /// value (mm for q1, rad otherwise)
        value: f64,
    },
    /// A move has no waypoints.
    #[error("step {step}: a move needs at least one waypoint")]
    EmptyMove {
        /// step index
        step: usize,
    },
    /// An id does not exist in the model.
    #[error("step {step}: unknown {what} id {id}")]
    UnknownId {
        /// step index
        step: usize,
        /// "tcp" or "position"
        what: &'static str,
        /// the id
        id: u32,
    },
    /// A measurement at a position where the plate is not.
    #[error("step {step}: measures at position {position} but the plate is at {placed:?} (add a place_probe step)")]
    PlateNotThere {
        /// step index
        step: usize,
        /// position of the measure step
        position: u32,
        /// where the plate is at that point of the plan
        placed: Option<u32>,
    },
}

/// Options of [`CampaignPlan::from_poses`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlanOptions {
    /// a pose where the arm is clear of the probe; visited before every plate re-placement
    pub clear_pose: Option<JointVector>,
    /// zero the probe with the master ball after every placement
    pub zero_probe: bool,
}

/// An ordered list of steps.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CampaignPlan {
    /// the steps, executed in order
    pub steps: Vec<CampaignStep>,
}

impl CampaignPlan {
    /// A plan from measurement poses in tour order. Probe poses (`Target::Probe`): a plate
    /// placement whenever the position changes (preceded by a move to `clear_pose` if given,
    /// followed by zeroing if asked), then a straight joint move to the pose and a
    /// measurement. Tracker poses: a move and a tracker measurement.
    pub fn from_poses(poses: &[Measurement], options: &PlanOptions) -> Self {
        let mut steps = Vec::new();
        let mut placed = None;
        for m in poses {
            if let Target::Probe { position } = m.target
                && placed != Some(position)
            {
                if let Some(clear) = options.clear_pose {
                    steps.push(CampaignStep::Move { path: vec![clear] });
                }
                steps.push(CampaignStep::PlaceProbe { position });
                if options.zero_probe {
                    steps.push(CampaignStep::ZeroProbe { position });
                }
                placed = Some(position);
            }
            steps.push(CampaignStep::Move { path: vec![m.q] });
            steps.push(match m.target {
                Target::Probe { position } => CampaignStep::Measure { position, tcp: m.tcp },
                Target::Tracker { .. } => CampaignStep::Track { tcp: m.tcp },
            });
        }
        Self { steps }
    }

    /// Number of steps that record a measurement.
    pub fn measurement_count(&self) -> usize {
        self.steps
            .iter()
            .filter(|s| matches!(s, CampaignStep::Measure { .. } | CampaignStep::Track { .. }))
            .count()
    }

    /// A fingerprint of the plan (FNV-1a 64 of its JSON form): a journal only resumes the plan
    /// it was started with.
    pub fn fingerprint(&self) -> u64 {
        fnv1a64(serde_json::to_string(self).unwrap_or_default().as_bytes())
    }

    /// Checks the plan against the model: waypoints inside the joint limits, known ids, every
    /// measurement at the position where the plate is.
    pub fn validate(&self, model: &Model) -> Result<(), PlanError> {
        if self.steps.is_empty() {
            return Err(PlanError::Empty);
        }
        let (tcps, positions) = (model.tcp_ids(), model.position_ids());
        let known = |step: usize, what: &'static str, id: u32, ids: &[u32]| {
            if ids.contains(&id) { Ok(()) } else { Err(PlanError::UnknownId { step, what, id }) }
        };
        let mut placed = None;
        for (step, s) in self.steps.iter().enumerate() {
            match s {
                CampaignStep::PlaceProbe { position } => {
                    known(step, "position", *position, &positions)?;
                    placed = Some(*position);
                }
                CampaignStep::ZeroProbe { position } | CampaignStep::Measure { position, .. }
                    if placed != Some(*position) =>
                {
                    return Err(PlanError::PlateNotThere { step, position: *position, placed });
                }
                CampaignStep::ZeroProbe { .. } => {}
                CampaignStep::Measure { tcp, .. } | CampaignStep::Track { tcp } => known(step, "tcp", *tcp, &tcps)?,
                CampaignStep::Move { path } => {
                    if path.is_empty() {
                        return Err(PlanError::EmptyMove { step });
                    }
                    for (waypoint, q) in path.iter().enumerate() {
                        let bad = model.limit_violation(q).map(|(joint, value, ..)| (joint, value)).or_else(|| {
                            q.0.iter().position(|v| !v.is_finite()).map(|k| (k + 1, q.0[k]))
                        });
                        if let Some((joint, value)) = bad {
                            return Err(PlanError::Limits { step, waypoint, joint, value });
                        }
                    }
                }
            }
        }
        Ok(())
    }
}
