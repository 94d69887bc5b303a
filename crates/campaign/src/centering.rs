//! Auto-centering (paper §2.4): drive a ball onto the probe origin with the robot alone.
//!
//! Read the probe offset `c` (probe frame, nominal gauge axes), command the TCP by `−c`
//! (mapped into the world through the placement's nominal orientation, then into the flange
//! frame through the controller's nominal model), repeat until the composite error `|c|` is
//! below the tolerance (5 µm). The guide (if the cell has one) is never moved. Any serial
//! chain: the cell's joints split into the optional guide and the arm by
//! [`JointLayout`](vatcal_hardware_traits::JointLayout). Because the gauges read zero only
//! when the ball is centred, neither the gauge axes nor the robot's model need to be exact: they
//! only set the contraction rate (background §7.4).
//!
//! Backlash: a joint with lost motion sits on one side or the other of its gear play depending
//! on the direction it last moved. A small linear correction reverses some joints, so the
//! arm jumps by the play and the loop limit-cycles above the tolerance. Every correction
//! therefore ends with each joint approaching its target from the side of the pose's planned
//! approach (the `approach` directions): a joint that the linear move reversed is taken past
//! its target by [`CenteringConfig::approach_overshoot_rad`] and brought back (two joint
//! moves), as a metrology engineer does on a machine with backlash.
//!
//! Safety: each step is capped in length, the loop stops with a typed error if the error grows
//! (beyond the first reading, or on two consecutive moves, with a noise allowance), if a
//! reading leaves the gauge range (or comes within a margin of it), or after an iteration cap.

use nalgebra::Vector3;
use vatcal_hardware_traits::{
    ArmJoints, ErrorKind, JointLayout, LinearAxis, LinearFrame, MotionOptions, Probe3d, ProbeReading,
    RobotArm,
};
use vatcal_kinematics::Model;

/// Settings of [`auto_center`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CenteringConfig {
    /// stop when the composite error is below this \[mm\] (paper: 0.005)
    pub tolerance_mm: f64,
    /// maximum number of corrective moves
    pub max_iterations: usize,
    /// a corrective move longer than this is shortened to it (same direction) \[mm\]
    pub max_step_mm: f64,
    /// noise allowance of the divergence test \[mm\] (robot repeatability + gauge error): abort
    /// when the composite error exceeds the first reading by more than this, or grows by more
    /// than this on two consecutive moves
    pub growth_allowance_mm: f64,
    /// abort when any gauge reading comes within this margin of the probe's range \[mm\]
    pub range_margin_mm: f64,
    /// speed and timeout of the corrective moves
    pub motion: MotionOptions,
    /// after a linear correction, every joint it moved against its approach direction is
    /// taken this far past its target and brought back, so each joint ends on the backlash side
    /// of the pose's planned approach \[rad\]; 0 disables it (the linear move alone). It must
    /// exceed the joints' lost motion (strain-wave gears: ≤ 1 arcmin = 0.29 mrad)
    pub approach_overshoot_rad: f64,
}

impl Default for CenteringConfig {
    /// 5 µm tolerance, 12 iterations, 2 mm step cap, 10 µm growth allowance, 0.25 mm range
    /// margin, 10 % speed with a 30 s timeout, 0.3 mrad (≈ 1 arcmin) approach overshoot.
    fn default() -> Self {
        Self {
            tolerance_mm: 0.005,
            max_iterations: 12,
            max_step_mm: 2.0,
            growth_allowance_mm: 0.010,
            range_margin_mm: 0.25,
            motion: MotionOptions { speed_fraction: 0.1, timeout: std::time::Duration::from_secs(30) },
            approach_overshoot_rad: 3e-4,
        }
    }
}

/// Why auto-centering stopped without converging. Every variant leaves the arm where the last
/// command put it; nothing else moves.
#[derive(Debug, thiserror::Error)]
pub enum CenteringError {
    /// The probe has no orientation for this calibration position.
    #[error("the probe has no placement configured for calibration position {position}")]
    NoPlacement {
        /// calibration position
        position: u32,
    },
    /// A reading is outside the gauge range or within the safety margin of it: the ball is
    /// not (or no longer) in the probe.
    #[error("ball not in the probe's safe range (±{range_mm} mm less a {margin_mm} mm margin): {detail}")]
    OutOfRange {
        /// the readings (empty when the probe itself refused to read)
        readings_mm: Vec<f64>,
        /// probe range \[mm\]
        range_mm: f64,
        /// safety margin \[mm\]
        margin_mm: f64,
        /// the readings or the probe's own message
        detail: String,
    },
    /// The composite error grew beyond the first reading, or on two consecutive moves: the
    /// loop diverges (wrong placement orientation, wrong frame, a fault in the arm).
    #[error(
        "the composite error grew from {previous_mm:.4} mm to {current_mm:.4} mm after corrective move {iteration}: the loop diverges, stopped"
    )]
    ErrorGrew {
        /// before the move \[mm\]
        previous_mm: f64,
        /// after the move \[mm\]
        current_mm: f64,
        /// 1-based index of the move that made it grow
        iteration: usize,
    },
    /// The iteration cap was reached.
    #[error("not centred after {iterations} corrective moves: composite error still {composite_mm:.4} mm")]
    IterationCap {
        /// moves made
        iterations: usize,
        /// last composite error \[mm\]
        composite_mm: f64,
    },
    /// A device failed.
    #[error(transparent)]
    Device(#[from] vatcal_hardware_traits::Error),
}

/// Result of a converged auto-centering.
#[derive(Debug, Clone, PartialEq)]
pub struct CenteringOutcome {
    /// the last reading (below the tolerance); an option worth keeping is to correct the
    /// target by its offset instead of treating it as noise
    pub final_reading: ProbeReading,
    /// the final offset in world axes (through the nominal placement orientation) \[mm\]
    pub final_offset_world_mm: Vector3<f64>,
    /// corrective moves made
    pub iterations: usize,
    /// composite error of every reading, first to last \[mm\]
    pub composite_history_mm: Vec<f64>,
    /// the corrective moves commanded, in world axes \[mm\]
    pub steps_world_mm: Vec<Vector3<f64>>,
    /// arm joints read before each corrective move, then the final joints
    /// (`iterations + 1` entries) \[rad\]
    pub joint_trace: Vec<ArmJoints>,
    /// sign of the last motion of each arm joint (J1.., the cell joints of
    /// [`JointLayout::arm_cell_joints`]) when the ball was centred: the `approach` given to
    /// [`auto_center`], updated by every motion it made (0 = never moved). These are the
    /// measurement's `dir{j}` (`dir2..dir7` on the canonical cell)
    pub approach_dir: Vec<i8>,
    /// arm motions made: the corrective linear moves plus the joint moves that restored the
    /// approach side (two per correction that reversed a joint)
    pub arm_motions: usize,
    /// the joints the last arm motion started from (`None` when nothing moved) \[rad\]
    pub last_motion_from: Option<ArmJoints>,
}

/// Auto-centres the ball in the probe at calibration position `position`.
///
/// `controller` is the kinematic model the robot controller uses (the nominal one): it maps
/// the world correction into the flange frame at the current joints, so the arm's
/// [`LinearFrame::Tool`] move realises it as well as the controller can. `guide` is the cell's
/// guide (`None` for a chain without one, see [`JointLayout`]); it is only read.
///
/// `approach` is the sign of the last motion of each arm joint (J1.., one per arm joint; a
/// shorter slice reads as 0) when the arm arrived at the approach pose (`+1`, `-1`, or 0 when
/// unknown: the joint's first correction then sets it). Every correction ends with each joint
/// arriving from that side (see [`CenteringConfig::approach_overshoot_rad`]).
///
/// # Errors
/// [`CenteringError`]; an arm or a guide that does not fit the controller model's joints is a
/// [`CenteringError::Device`] error of kind `OutOfRange` naming the joint counts.
pub fn auto_center(
    arm: &mut dyn RobotArm,
    guide: Option<&mut dyn LinearAxis>,
    probe: &mut dyn Probe3d,
    controller: &Model,
    position: u32,
    approach: &[i8],
    config: &CenteringConfig,
) -> Result<CenteringOutcome, CenteringError> {
    let placement = probe.placement(position).ok_or(CenteringError::NoPlacement { position })?;
    let range_mm = probe.range_mm();
    let layout = JointLayout::of(controller.joint_kinds());
    let guide_mm = match guide {
        Some(g) => Some(g.position_mm()?),
        None => None,
    };
    let n_arm = layout.arm_joint_count();
    let mut history: Vec<f64> = Vec::new();
    let mut steps: Vec<Vector3<f64>> = Vec::new();
    let mut trace: Vec<ArmJoints> = Vec::new();
    let mut preferred: Vec<i8> = (0..n_arm).map(|j| approach.get(j).copied().unwrap_or(0)).collect();
    let mut dir = preferred.clone();
    let mut arm_motions = 0;
    let mut last_motion_from = None;
    let limits = controller.joint_limits();
    loop {
        let reading = read_safely(probe, range_mm, config.range_margin_mm)?;
        let composite = reading.composite_mm();
        if let Some(previous) = diverging(&history, composite, config.growth_allowance_mm) {
            return Err(CenteringError::ErrorGrew {
                previous_mm: previous,
                current_mm: composite,
                iteration: steps.len(),
            });
        }
        history.push(composite);
        let offset_world = placement.to_world(&reading.offset_mm);
        if composite < config.tolerance_mm {
            trace.push(arm.joints()?);
            return Ok(CenteringOutcome {
                final_reading: reading,
                final_offset_world_mm: offset_world,
                iterations: steps.len(),
                composite_history_mm: history,
                steps_world_mm: steps,
                joint_trace: trace,
                approach_dir: dir,
                arm_motions,
                last_motion_from,
            });
        }
        if steps.len() >= config.max_iterations {
            return Err(CenteringError::IterationCap { iterations: steps.len(), composite_mm: composite });
        }
        let mut step_world = -offset_world;
        let length = step_world.norm();
        if length > config.max_step_mm {
            step_world *= config.max_step_mm / length;
        }
        let joints = arm.joints()?;
        trace.push(joints);
        let q = layout.join(guide_mm, &joints)?;
        let flange = controller.chain(&q).flange();
        let step_tool = flange.r.transpose() * step_world;
        arm.move_linear_relative_and_wait(&step_tool, LinearFrame::Tool, &config.motion)?;
        steps.push(step_world);
        arm_motions += 1;
        last_motion_from = Some(joints);
        let after = arm.joints()?;
        layout.check_arm(&after)?;
        // joints the linear move reversed: past the target, then back onto it from the side
        // of the planned approach
        let mut pre = after;
        for j in 0..n_arm {
            let moved = after[j] - joints[j];
            if moved == 0.0 {
                continue;
            }
            let sign: i8 = if moved > 0.0 { 1 } else { -1 };
            dir[j] = sign;
            if preferred[j] == 0 {
                preferred[j] = sign;
            }
            if sign != preferred[j] && config.approach_overshoot_rad > 0.0 {
                let (lo, hi) = limits[layout.cell_joint(j) - 1];
                pre[j] = (after[j] - f64::from(preferred[j]) * config.approach_overshoot_rad).clamp(lo, hi);
            }
        }
        if pre != after {
            arm.move_joints_and_wait(&pre, &config.motion)?;
            arm.move_joints_and_wait(&after, &config.motion)?;
            arm_motions += 2;
            last_motion_from = Some(pre);
            for (d, (p, a)) in dir.iter_mut().zip(pre.as_slice().iter().zip(after.as_slice())) {
                if p != a {
                    *d = if a > p { 1 } else { -1 };
                }
            }
        }
    }
}

/// The loop diverges when the new error is worse than the first one, or when it grew on two
/// consecutive moves (each time by more than `allowance`). A single growth below the start is
/// tolerated: joint backlash makes a tiny correction that reverses a joint jump once, and the
/// next correction recovers. Returns the error the growth is measured from.
fn diverging(history: &[f64], current: f64, allowance: f64) -> Option<f64> {
    let first = *history.first()?;
    if current > first + allowance {
        return Some(first);
    }
    match history {
        [.., before, previous] if current > previous + allowance && *previous > before + allowance => {
            Some(*previous)
        }
        _ => None,
    }
}

/// Reads the probe; out-of-range readings (from the probe or within the margin) become
/// [`CenteringError::OutOfRange`].
fn read_safely(
    probe: &mut dyn Probe3d,
    range_mm: f64,
    margin_mm: f64,
) -> Result<ProbeReading, CenteringError> {
    let reading = match probe.read() {
        Ok(r) => r,
        Err(e) if e.kind() == ErrorKind::OutOfRange => {
            return Err(CenteringError::OutOfRange {
                readings_mm: Vec::new(),
                range_mm,
                margin_mm,
                detail: e.to_string(),
            });
        }
        Err(e) => return Err(e.into()),
    };
    if reading.gauges_mm.iter().any(|g| g.abs() > range_mm - margin_mm) {
        let detail = format!("readings {:?} mm", reading.gauges_mm);
        return Err(CenteringError::OutOfRange {
            readings_mm: reading.gauges_mm.to_vec(),
            range_mm,
            margin_mm,
            detail,
        });
    }
    Ok(reading)
}

#[cfg(test)]
mod tests {
    use super::diverging;

    #[test]
    fn divergence_rule() {
        let a = 0.01;
        assert_eq!(diverging(&[], 5.0, a), None, "first reading");
        assert_eq!(diverging(&[1.0], 1.5, a), Some(1.0), "worse than the start");
        assert_eq!(diverging(&[1.0, 0.02], 0.2, a), None, "one jump below the start is tolerated");
        assert_eq!(diverging(&[1.0, 0.02, 0.2], 0.5, a), Some(0.2), "two growths in a row");
        assert_eq!(diverging(&[1.0, 0.02, 0.2], 0.01, a), None, "recovered");
        assert_eq!(diverging(&[1.0, 0.004], 0.012, a), None, "noise within the allowance");
    }
}
