//! The backend hooks that couple the protocol simulators to the one virtual world.

use std::sync::atomic::Ordering;
use std::sync::atomic::{AtomicBool, AtomicI64};
use std::sync::{Arc, Weak};
use std::time::Duration;

use nalgebra::Vector3;
use vatcal_core::Frame;
use vatcal_drivers_meca500::codec::Six;
use vatcal_drivers_meca500::sim::{ArmBackend, Meca500Sim};
use vatcal_drivers_sylvac::sim::PlungerSource;
use vatcal_drivers_tracker::sim::{SimFault, TargetSource};
use vatcal_drivers_zaber::sim::{AxisBackend, ZaberSim};
use vatcal_hardware_traits::{ArmJoints, ErrorKind, LinearFrame};
use vatcal_sim::VirtualCell;

/// Meca500 simulator → world: motions, and relative linear moves solved on the nominal model.
#[derive(Debug)]
pub(crate) struct ArmCoupling {
    pub cell: VirtualCell,
}

impl ArmBackend for ArmCoupling {
    fn motion_started(&self, from_deg: &Six, to_deg: &Six) {
        self.cell.external_motion_started(
            &ArmJoints::from_deg_array(*from_deg),
            &ArmJoints::from_deg_array(*to_deg),
        );
    }

    fn linear_relative(
        &self,
        from_deg: &Six,
        translation_mm: &Vector3<f64>,
        frame: LinearFrame,
    ) -> Option<Result<Six, (u16, String)>> {
        let from = ArmJoints::from_deg_array(*from_deg);
        Some(self.cell.external_linear_target(&from, translation_mm, frame).and_then(|q| {
            // the simulated cell's arm has six joints (checked at start)
            Six::try_from(q.to_deg().as_slice()).map_err(|_| {
                (vatcal_sim::external::CODE_JOINT_LIMIT, format!("{} joints for a Meca500", q.len()))
            })
        }))
    }
}

/// Zaber simulator → world: guide motions.
#[derive(Debug)]
pub(crate) struct GuideCoupling {
    pub cell: VirtualCell,
    pub microstep_mm: f64,
    /// the `maxspeed` of the last motion started (shared with [`GuideLink`])
    pub motion_maxspeed: Arc<AtomicI64>,
}

impl AxisBackend for GuideCoupling {
    fn motion_started(&self, from_microsteps: f64, to_microsteps: f64) {
        self.cell.external_guide_motion_started(
            from_microsteps * self.microstep_mm,
            to_microsteps * self.microstep_mm,
        );
    }

    fn motion_started_at(&self, from_microsteps: f64, to_microsteps: f64, maxspeed: i64) {
        self.motion_maxspeed.store(maxspeed, Ordering::SeqCst);
        self.motion_started(from_microsteps, to_microsteps);
    }
}

/// The Zaber simulator as the gauges see it.
#[derive(Debug, Clone)]
pub(crate) struct GuideLink {
    pub sim: Weak<ZaberSim>,
    pub microstep_mm: f64,
    /// the guide's `maxspeed` at full speed (the driver sets a fraction of it per move)
    pub full_maxspeed: i64,
    /// the `maxspeed` of the last motion started (0: none yet): the speed the world times the
    /// motion with, whatever the setting is when it syncs (the driver sets the full speed back
    /// once a move has ended)
    pub motion_maxspeed: Arc<AtomicI64>,
}

/// World → Sylvac simulator: where the true ball pushes the plunger of one gauge.
#[derive(Debug)]
pub(crate) struct GaugeCoupling {
    cell: VirtualCell,
    index: usize,
    /// the plunger position that reads zero before any preset \[mm\] (mid-travel)
    zero_mm: f64,
    arm: Weak<Meca500Sim>,
    /// `None`: the cell has no guide
    guide: Option<GuideLink>,
    /// fault injection: the gauge reads out of range
    pub out_of_range: AtomicBool,
}

impl GaugeCoupling {
    pub fn new(
        cell: VirtualCell,
        index: usize,
        zero_mm: f64,
        arm: Weak<Meca500Sim>,
        guide: Option<GuideLink>,
    ) -> Self {
        Self { cell, index, zero_mm, arm, guide, out_of_range: AtomicBool::new(false) }
    }

    /// Puts the world where the Meca500 and Zaber simulators are now, with the speeds in
    /// force (the world's virtual clock advances by the motions since the last sync).
    pub fn sync(&self) {
        let Some(arm) = self.arm.upgrade() else { return };
        let guide = match &self.guide {
            Some(link) => match link.sim.upgrade() {
                Some(sim) => Some((sim, link)),
                None => return,
            },
            None => None,
        };
        // each simulator's lock is taken and released before the world's (lock order)
        let arm_state = arm.state();
        let joints = ArmJoints::from_deg_array(arm_state.joints_deg);
        let p = arm_state.params;
        let arm_speed = p.joint_vel_pct.min(p.joint_vel_limit_pct) / 100.0;
        // without a guide the world has no guide joint: its position and speed are unused
        let (guide_mm, guide_speed) = guide.map_or((0.0, 1.0), |(sim, link)| {
            let guide_state = sim.state();
            let maxspeed = match link.motion_maxspeed.load(Ordering::SeqCst) {
                0 => guide_state.maxspeed,
                m => m,
            };
            (
                guide_state.pos_microsteps * link.microstep_mm,
                maxspeed as f64 / link.full_maxspeed.max(1) as f64,
            )
        });
        self.cell.external_sync(&joints, guide_mm, arm_speed, guide_speed);
    }
}

impl PlungerSource for GaugeCoupling {
    fn plunger_mm(&self) -> f64 {
        if self.out_of_range.load(Ordering::SeqCst) {
            return -1.0;
        }
        self.sync();
        // nothing on the plunger: it rests on its stop, fully extended
        self.cell.external_plunger_mm(self.index).map_or(0.0, |reading| reading + self.zero_mm)
    }

    fn reading_noise_mm(&self) -> f64 {
        self.cell.external_reading_noise_mm(self.index)
    }
}

/// World → tracker simulator: the in-process tracker's reading of the true SMR (registration
/// error, SMR-nest offsets, noise, line-of-sight losses), expressed in the tracker's own frame.
#[derive(Debug)]
pub(crate) struct TrackerCoupling {
    pub cell: VirtualCell,
    /// puts the world where the arm and guide simulators are (the gauges' sync)
    pub sync: Arc<GaugeCoupling>,
    /// tracker ← world
    pub tracker_from_world: Frame,
    /// wall time of one reading
    pub read_time: Duration,
}

impl TargetSource for TrackerCoupling {
    fn measure_mm(&self, target: u32) -> Result<Vector3<f64>, SimFault> {
        self.sync.sync();
        match self.cell.external_track_mm(target) {
            Ok(p) => Ok(self.tracker_from_world.transform_point(&p)),
            Err(e) if e.kind() == ErrorKind::OutOfRange && e.message().starts_with("unknown target") => {
                Err(SimFault::UnknownTarget(e.message().to_owned()))
            }
            // a lost line of sight, or the nest SMR without a placed plate: nothing to see
            Err(e) if e.kind() == ErrorKind::OutOfRange => Err(SimFault::LineOfSight(e.message().to_owned())),
            Err(e) => Err(SimFault::Device(e.to_string())),
        }
    }

    fn measure_duration(&self) -> Option<Duration> {
        Some(self.read_time)
    }
}
