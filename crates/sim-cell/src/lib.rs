#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! The whole virtual cell over TCP (`vatcal sim-cell`): one process serves
//!
//! | port (default) | device | simulator |
//! |---|---|---|
//! | 10000, 10001 | Meca500 control and monitoring | `vatcal_drivers_meca500::sim` |
//! | 55550 | Zaber ASCII (the guide; none when the cell has no guide) | `vatcal_drivers_zaber::sim` |
//! | 55561, 55562, 55563 | Sylvac gauges 1–3 of the TriCal | `vatcal_drivers_sylvac::sim` |
//! | 55580 | the laser tracker (tracker line protocol) | `vatcal_drivers_tracker::sim` |
//! | 55570 | cell control (the operator), see [`control`] | this crate |
//!
//! The cell is the canonical Meca500 on its guide by default, or any cell whose arm has six
//! revolute joints, with or without a prismatic guide as joint 1 ([`SimCellOptions::for_nominal`],
//! `vatcal sim-cell --model`): the arm is served behind the Meca500 protocol (joint-space
//! commands and relative linear moves, solved on the cell's own nominal model; the pose commands
//! and the reported pose keep the Meca500's own kinematics), and a cell without a guide has no
//! Zaber server.
//!
//! Everything is served from **one shared virtual world**, a [`VirtualCell`] of `vatcal-sim`: the protocol
//! simulators keep their queues, timing and protocol states, and a small backend hook couples
//! each to the world —
//!
//! * the Meca500 simulator tells the world about every motion (backlash direction,
//!   repeatability draw, noise epoch) and lets the cell's **nominal** model solve relative
//!   linear moves, exactly as the in-process [`vatcal_sim::SimArm`] does;
//! * the Zaber simulator tells the world about every guide motion;
//! * each Sylvac simulator asks the world where its plunger is: the world is put at the joints
//!   the Meca500 and Zaber simulators report, and the **true** ball is read against the
//!   **true** probe plate at the current placement, along the gauge's true (tilted) axis, with
//!   the noise budget of the in-process gauges;
//! * the tracker simulator asks the world, at every `MEASURE`, what the in-process tracker
//!   would read (the true SMR with the registration error, SMR-nest offsets, noise and
//!   line-of-sight losses of [`SimConfig`]), and reports it in the tracker's own frame
//!   ([`SimCellOptions::tracker_pose`]): the validation campaign registers it to the tank
//!   frame by measuring the SMR in the probe's nest at the calibration positions;
//! * the cell-control port moves the plate (the operator) and tells the cell's time (`TIME?`) and temperature (`TEMP?`).
//!
//! The world's physics (thermal drift, the time of its context) follows the cell's **virtual
//! clock**, advanced by the durations the in-process devices would take for the same motions,
//! readings and re-placements ([`VirtualCell::external_sync`]), never by the wall clock: the
//! time scale only paces the simulators.
//!
//! The hidden truth is a parameter ([`SimCellOptions::truth`]); by default it is the one of
//! `vatcal demo --seed S`, `perturbed_truth(nominal, S, &ErrorBudget::realistic())` on the
//! built-in cell, with the demo's probe imperfections and noise budget
//! ([`SimConfig::paper_for`]). With the noise off a campaign over TCP records what the
//! in-process demo records, up to the wire's precision (9 decimals of a degree for the arm,
//! one microstep of the guide, the gauges' display resolution).
//!
//! Fault injection for end-to-end tests: [`SimCell::drop_connections`],
//! [`SimCell::set_stalled`], [`SimCell::robot_error`], [`SimCell::set_estop`],
//! [`SimCell::set_gauge_out_of_range`], [`SimCell::guide_stall`].

pub mod control;
mod coupling;
mod error;

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::Arc;
use std::sync::atomic::Ordering;

use vatcal_core::{CellFile, Frame};
use vatcal_drivers_meca500::sim::{Meca500Sim, SimConfig as MecaConfig};
use vatcal_drivers_sylvac::sim::{SimConfig as SylvacConfig, SylvacSim};
use vatcal_drivers_tracker::sim::{SimConfig as TrackerConfig, TrackerSim};
use vatcal_drivers_zaber::sim::{SimConfig as ZaberConfig, ZaberSim};
use vatcal_hardware_traits::JointLayout;
use vatcal_hardware_traits::sim_server::SimServer;
use vatcal_kinematics::Model;
use vatcal_sim::truth::{ErrorBudget, TruthSpec, perturbed_truth};
use vatcal_sim::{CellPhysics, NoiseBudget, SimConfig, VirtualCell};

pub use error::SimCellError;

use crate::coupling::{ArmCoupling, GaugeCoupling, GuideCoupling, GuideLink, TrackerCoupling};

/// The canonical nominal cell (`fixtures/meca500-zaber.toml`), built in so that `vatcal
/// sim-cell` runs from any directory (the same file as `vatcal demo`'s built-in cell).
pub const BUILT_IN_CELL: &str = vatcal_core::CANONICAL_CELL_TOML;

/// The TCP ports of the cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ports {
    /// Meca500 control port
    pub meca500_control: u16,
    /// Meca500 monitoring port
    pub meca500_monitoring: u16,
    /// Zaber ASCII port (unused when the cell has no guide)
    pub zaber: u16,
    /// Sylvac gauges 1, 2, 3
    pub gauges: [u16; 3],
    /// cell-control port (the operator)
    pub control: u16,
    /// laser tracker (tracker line protocol)
    pub tracker: u16,
}

impl Ports {
    /// Every port ephemeral (0): for tests that run several cells at once.
    pub fn ephemeral() -> Self {
        Self { meca500_control: 0, meca500_monitoring: 0, zaber: 0, gauges: [0; 3], control: 0, tracker: 0 }
    }
}

impl Default for Ports {
    /// The devices' usual ports: 10000, 10001, 55550, 55561–55563, 55570, and 55580 for the
    /// tracker.
    fn default() -> Self {
        Self {
            meca500_control: 10000,
            meca500_monitoring: 10001,
            zaber: 55550,
            gauges: [55561, 55562, 55563],
            control: 55570,
            tracker: 55580,
        }
    }
}

/// Options of [`SimCell::start`].
#[derive(Debug, Clone)]
pub struct SimCellOptions {
    /// address every port binds (default 127.0.0.1)
    pub bind: IpAddr,
    /// the ports
    pub ports: Ports,
    /// seed of the probe imperfections and of the noise (and of the default truth)
    pub seed: u64,
    /// what the robot controller believes (and where the probe placements are configured): an
    /// arm of six revolute joints, with or without a prismatic guide as joint 1
    pub nominal: Model,
    /// the hidden true cell
    pub truth: Model,
    /// what the truth's world has beyond its model (temperature channel, tracker
    /// systematics); [`CellPhysics::default`]: none
    pub physics: CellPhysics,
    /// simulated device noise (robot, guide, tool changer and gauge repeatability); probe
    /// imperfections stay, they are part of the truth
    pub noise: bool,
    /// every duration of the simulators is divided by this (1 = real time); the physics
    /// follows the virtual clock whatever the scale
    pub time_scale: f64,
    /// decimals of the gauges' display in mm (the S_Dial WORK Nano shows 4: 0.1 µm)
    pub gauge_decimals: usize,
    /// where the laser tracker stands: `world ← tracker` (its readings are in its own frame;
    /// [`Frame::identity`] for a tracker whose software is registered to the tank already).
    /// Default: [`default_tracker_pose`]
    pub tracker_pose: Frame,
    /// probability that a tracker measurement finds no line of sight to its SMR
    /// ([`vatcal_sim::SimFaults::tracker_line_of_sight_loss`]; default 0)
    pub tracker_line_of_sight_loss: f64,
}

/// The simulated tracker's default stand, `world ← tracker`: 2.5 m from the tank, turned 150°
/// about the vertical and tilted 1° about x, its origin at (2000, −1500, 300) mm in the world
/// (tank) frame. Any pose works: the registration step finds it.
pub fn default_tracker_pose() -> Frame {
    Frame {
        r: vatcal_core::frame::rot_z(150f64.to_radians()) * vatcal_core::frame::rot_x(1f64.to_radians()),
        p: nalgebra::Vector3::new(2000.0, -1500.0, 300.0),
    }
}

impl SimCellOptions {
    /// The cell of `vatcal demo --seed seed`: the built-in nominal cell, truth
    /// `perturbed_truth(nominal, seed, &ErrorBudget::realistic())`, noise on, real time, the
    /// usual ports on 127.0.0.1, 4-decimal gauges.
    ///
    /// # Errors
    /// Only if the built-in cell does not parse (a build defect).
    pub fn paper(seed: u64) -> Result<Self, SimCellError> {
        let cell = CellFile::from_toml_str(BUILT_IN_CELL, "fixtures/meca500-zaber.toml (built in)")?;
        let nominal = Model::from_cell(&cell)?;
        nominal.require_meca500_on_guide("the simulated cell")?;
        Self::for_nominal(nominal, seed)
    }

    /// The cell `nominal` (any arm of six revolute joints, with or without a guide as joint 1)
    /// with the defaults of [`SimCellOptions::paper`]: truth
    /// `perturbed_truth(nominal, seed, &ErrorBudget::realistic())`, noise on, real time, the
    /// usual ports on 127.0.0.1, 4-decimal gauges.
    ///
    /// # Errors
    /// [`SimCellError::Option`] (`nominal`) for a chain the Meca500 protocol cannot serve.
    pub fn for_nominal(nominal: Model, seed: u64) -> Result<Self, SimCellError> {
        check_chain(&nominal)?;
        let truth = perturbed_truth(&nominal, seed, &ErrorBudget::realistic());
        Ok(Self {
            bind: IpAddr::V4(Ipv4Addr::LOCALHOST),
            ports: Ports::default(),
            seed,
            nominal,
            truth,
            physics: CellPhysics::default(),
            noise: true,
            time_scale: 1.0,
            gauge_decimals: 4,
            tracker_pose: default_tracker_pose(),
            tracker_line_of_sight_loss: 0.0,
        })
    }

    /// The cell of `vatcal demo --seed seed --truth spec`: as [`SimCellOptions::paper`], with the
    /// hidden truth (model and cell physics) built by `spec` (the demo's default is
    /// [`TruthSpec::PaperLike`]).
    ///
    /// # Errors
    /// A truth file that cannot be read or does not fit the nominal cell.
    pub fn with_truth(seed: u64, spec: &TruthSpec) -> Result<Self, SimCellError> {
        let mut options = Self::paper(seed)?;
        options.set_truth(spec)?;
        Ok(options)
    }

    /// Replaces the hidden truth by the one `spec` builds for the current nominal cell and seed.
    ///
    /// # Errors
    /// A truth file that cannot be read or does not fit the nominal cell.
    pub fn set_truth(&mut self, spec: &TruthSpec) -> Result<(), SimCellError> {
        let built = spec.build(&self.nominal, self.seed)?;
        self.truth = built.model;
        self.physics = built.physics;
        Ok(())
    }

    /// The virtual-cell configuration these options give: [`SimConfig::paper_for`] the
    /// nominal cell, without device noise if [`SimCellOptions::noise`] is off.
    pub fn sim_config(&self) -> SimConfig {
        let mut config = SimConfig::paper_for(&self.nominal);
        config.physics = self.physics;
        if !self.noise {
            config.noise = NoiseBudget::none();
        }
        config.faults.tracker_line_of_sight_loss = self.tracker_line_of_sight_loss;
        config
    }

    fn check(&self) -> Result<(), SimCellError> {
        check_chain(&self.nominal)?;
        if self.truth.joint_kinds() != self.nominal.joint_kinds() {
            return Err(SimCellError::Option {
                option: "truth".into(),
                reason: format!(
                    "the truth ({}) is not the nominal cell's chain ({})",
                    self.truth.describe_chain(),
                    self.nominal.describe_chain()
                ),
            });
        }
        if !(self.time_scale.is_finite() && self.time_scale > 0.0) {
            return Err(SimCellError::Option {
                option: "time_scale".into(),
                reason: format!("must be a positive number, got {}", self.time_scale),
            });
        }
        if !(0.0..=1.0).contains(&self.tracker_line_of_sight_loss) {
            return Err(SimCellError::Option {
                option: "tracker_line_of_sight_loss".into(),
                reason: format!("must be a probability in 0..=1, got {}", self.tracker_line_of_sight_loss),
            });
        }
        if self.gauge_decimals > 9 {
            return Err(SimCellError::Option {
                option: "gauge_decimals".into(),
                reason: format!("must be at most 9, got {}", self.gauge_decimals),
            });
        }
        Ok(())
    }
}

/// The Meca500 protocol carries six joint values in degrees: the arm must be six revolute
/// joints (after an optional prismatic guide).
fn check_chain(nominal: &Model) -> Result<(), SimCellError> {
    let layout = JointLayout::of(nominal.joint_kinds());
    if layout.arm_joint_count() != 6 || !layout.arm_cell_joints().all(|j| nominal.is_revolute(j)) {
        return Err(SimCellError::Option {
            option: "nominal".into(),
            reason: format!(
                "the simulated cell serves an arm of six revolute joints (with or without a guide as joint 1) \
                 behind the Meca500 protocol; this cell has {}",
                nominal.describe_chain()
            ),
        });
    }
    Ok(())
}

/// The addresses a running [`SimCell`] listens on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimCellAddrs {
    /// Meca500 control
    pub meca500_control: SocketAddr,
    /// Meca500 monitoring
    pub meca500_monitoring: SocketAddr,
    /// Zaber ASCII (`None`: the cell has no guide)
    pub zaber: Option<SocketAddr>,
    /// Sylvac gauges 1, 2, 3
    pub gauges: [SocketAddr; 3],
    /// cell control
    pub control: SocketAddr,
    /// laser tracker
    pub tracker: SocketAddr,
}

impl SimCellAddrs {
    /// `(name, address)` of every port, in the order `vatcal sim-cell` prints them (no
    /// `zaber` without a guide).
    pub fn named(&self) -> Vec<(&'static str, SocketAddr)> {
        let mut named =
            vec![("meca500-control", self.meca500_control), ("meca500-monitoring", self.meca500_monitoring)];
        named.extend(self.zaber.map(|z| ("zaber", z)));
        named.extend([
            ("gauge-1", self.gauges[0]),
            ("gauge-2", self.gauges[1]),
            ("gauge-3", self.gauges[2]),
            ("cell-control", self.control),
            ("tracker", self.tracker),
        ]);
        named
    }
}

/// A device of the cell, for fault injection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Device {
    /// the Meca500 (control and monitoring ports)
    Arm,
    /// the Zaber guide
    Guide,
    /// Sylvac gauge `.0` (0, 1, 2)
    Gauge(usize),
    /// the cell-control port
    Control,
    /// the laser tracker
    Tracker,
}

/// The running cell. Dropping it stops every server and closes every socket.
#[derive(Debug)]
pub struct SimCell {
    // fields drop in order: the tracker and the gauges (which read the arm and the guide) go
    // first
    tracker: TrackerSim,
    gauges: Vec<SylvacSim>,
    gauge_couplings: Vec<Arc<GaugeCoupling>>,
    control: SimServer,
    meca500: Arc<Meca500Sim>,
    zaber: Option<Arc<ZaberSim>>,
    cell: VirtualCell,
    addrs: SimCellAddrs,
}

impl SimCellOptions {
    /// The address of `port` on the bind address.
    fn at(&self, port: u16) -> SocketAddr {
        SocketAddr::new(self.bind, port)
    }

    /// The error of a server of `device` that cannot listen on `port`.
    fn bind_error(&self, device: &str, port: u16) -> impl FnOnce(std::io::Error) -> SimCellError {
        let address = self.at(port);
        let device = device.to_owned();
        move |source| SimCellError::Bind { device, address, source }
    }
}

/// The guide's server, if the cell has a guide: microsteps of the default lead, stroke and
/// speed of the nominal cell, its moves coupled to the world; with the link the gauges read it
/// through.
fn start_guide(
    options: &SimCellOptions,
    cell: &VirtualCell,
) -> Result<Option<(Arc<ZaberSim>, GuideLink)>, SimCellError> {
    let Some((_, stroke_mm)) = cell.guide_limits_mm() else { return Ok(None) };
    let mut zaber_config = ZaberConfig { time_scale: options.time_scale, ..ZaberConfig::default() };
    zaber_config.travel_mm = stroke_mm;
    let limits = options.nominal.to_cell().motion_limits();
    zaber_config.maxspeed = ZaberConfig::maxspeed_for(limits.guide_speed_mm_per_s, zaber_config.microstep_mm);
    let microstep_mm = zaber_config.microstep_mm;
    let full_maxspeed = zaber_config.maxspeed;
    zaber_config.bind = options.at(options.ports.zaber);
    let motion_maxspeed = Arc::new(std::sync::atomic::AtomicI64::new(0));
    zaber_config.backend = Some(Arc::new(GuideCoupling {
        cell: cell.clone(),
        microstep_mm,
        motion_maxspeed: Arc::clone(&motion_maxspeed),
    }));
    let sim =
        Arc::new(ZaberSim::start(zaber_config).map_err(options.bind_error("zaber", options.ports.zaber))?);
    let link = GuideLink { sim: Arc::downgrade(&sim), microstep_mm, full_maxspeed, motion_maxspeed };
    Ok(Some((sim, link)))
}

/// The arm's server: the nominal cell's joint limits, motions coupled to the world.
fn start_arm(options: &SimCellOptions, cell: &VirtualCell) -> Result<Arc<Meca500Sim>, SimCellError> {
    let mut meca_config = MecaConfig { time_scale: options.time_scale, ..MecaConfig::default() };
    for (slot, (lo, hi)) in meca_config.joint_limits_deg.iter_mut().zip(cell.arm_joint_limits()) {
        *slot = (lo.to_degrees(), hi.to_degrees());
    }
    meca_config.control_bind = options.at(options.ports.meca500_control);
    meca_config.monitoring_bind = options.at(options.ports.meca500_monitoring);
    meca_config.backend = Some(Arc::new(ArmCoupling { cell: cell.clone() }));
    Ok(Arc::new(
        Meca500Sim::start(meca_config)
            .map_err(options.bind_error("meca500", options.ports.meca500_control))?,
    ))
}

/// The gauges' servers: the S_Dial's 12.5 mm travel, reading zero (a centred calibration
/// ball) at 6 mm so that the display is the in-process reading and the master ball (+6.35 mm)
/// still fits; their plungers coupled to the arm and the guide.
fn start_gauges(
    options: &SimCellOptions,
    cell: &VirtualCell,
    meca500: &Arc<Meca500Sim>,
    guide_link: Option<GuideLink>,
) -> Result<(Vec<SylvacSim>, Vec<Arc<GaugeCoupling>>), SimCellError> {
    let range_mm = cell.config().gauge_range_mm;
    let mut gauges = Vec::new();
    let mut gauge_couplings = Vec::new();
    for (index, port) in options.ports.gauges.iter().enumerate() {
        let coupling = Arc::new(GaugeCoupling::new(
            cell.clone(),
            index,
            range_mm,
            Arc::downgrade(meca500),
            guide_link.clone(),
        ));
        let decimals = options.gauge_decimals;
        let config = SylvacConfig {
            id: format!("SY289-SIM{}", index + 1),
            resolution_mm: 10f64.powi(-(decimals as i32)),
            decimals_mm: decimals,
            seed: options.seed.wrapping_add(index as u64),
            bind: options.at(*port),
            plunger: Some(coupling.clone()),
            zeroed_at_mm: Some(range_mm),
            ..SylvacConfig::default()
        };
        let name = format!("gauge-{}", index + 1);
        gauges.push(SylvacSim::start(config).map_err(options.bind_error(&name, *port))?);
        gauge_couplings.push(coupling);
    }
    Ok((gauges, gauge_couplings))
}

/// The tracker's server: the SMR's world position in the tracker's frame (`options`'
/// tracker pose), after the gauges' `sync`.
fn start_tracker(
    options: &SimCellOptions,
    cell: &VirtualCell,
    sync: &Arc<GaugeCoupling>,
) -> Result<TrackerSim, SimCellError> {
    TrackerSim::start(TrackerConfig {
        identity: format!("vatcal sim-cell tracker (seed {})", options.seed),
        bind: options.at(options.ports.tracker),
        source: Some(Arc::new(TrackerCoupling {
            cell: cell.clone(),
            sync: Arc::clone(sync),
            tracker_from_world: options.tracker_pose.inverse(),
            read_time: std::time::Duration::from_secs_f64(
                cell.config().timing.tracker_read_s / options.time_scale,
            ),
        })),
        ..TrackerConfig::default()
    })
    .map_err(options.bind_error("tracker", options.ports.tracker))
}

impl SimCell {
    /// Builds the virtual world and starts every server.
    ///
    /// # Errors
    /// Invalid options, or a port that cannot be bound (in use, no permission) — the error
    /// names the device and the address.
    pub fn start(options: SimCellOptions) -> Result<Self, SimCellError> {
        options.check()?;
        let cell = VirtualCell::new(
            options.nominal.clone(),
            options.truth.clone(),
            options.sim_config(),
            options.seed,
        );
        let at = |port: u16| options.at(port);
        let (zaber, guide_link) = match start_guide(&options, &cell)? {
            Some((sim, link)) => (Some(sim), Some(link)),
            None => (None, None),
        };
        let meca500 = start_arm(&options, &cell)?;
        let (gauges, gauge_couplings) = start_gauges(&options, &cell, &meca500, guide_link)?;
        let control = SimServer::spawn(
            "sim-cell-control",
            &[at(options.ports.control)],
            control::ControlService::new(cell.clone(), options.time_scale).with_sync({
                let coupling = Arc::clone(&gauge_couplings[0]);
                Arc::new(move || coupling.sync())
            }),
        )
        .map_err(options.bind_error("cell-control", options.ports.control))?;
        let tracker = start_tracker(&options, &cell, &gauge_couplings[0])?;
        let addrs = SimCellAddrs {
            meca500_control: meca500.control_addr(),
            meca500_monitoring: meca500.monitoring_addr().unwrap_or_else(|| at(0)),
            zaber: zaber.as_ref().map(|z| z.addr()),
            gauges: [gauges[0].addr(), gauges[1].addr(), gauges[2].addr()],
            control: control.addrs()[0],
            tracker: tracker.addr(),
        };
        Ok(Self { tracker, gauges, gauge_couplings, control, meca500, zaber, cell, addrs })
    }

    /// The bound addresses.
    pub fn addrs(&self) -> SimCellAddrs {
        self.addrs
    }

    /// The virtual world (oracles for tests: the truth, the plate position, the true ball
    /// offset, the physical joints).
    pub fn cell(&self) -> &VirtualCell {
        &self.cell
    }

    /// The Meca500 simulator (its state, and its own fault hooks).
    pub fn meca500(&self) -> &Meca500Sim {
        &self.meca500
    }

    /// The Zaber simulator (`None`: the cell has no guide).
    pub fn zaber(&self) -> Option<&ZaberSim> {
        self.zaber.as_deref()
    }

    /// The tracker simulator (its own fault hooks: line of sight, garbled answers).
    pub fn tracker(&self) -> &TrackerSim {
        &self.tracker
    }

    /// Gauge simulator `index` (0, 1, 2).
    pub fn gauge(&self, index: usize) -> Option<&SylvacSim> {
        self.gauges.get(index)
    }

    // ---- fault injection -----------------------------------------------------------------

    /// Closes the connections of `device` (the client sees its socket closed).
    pub fn drop_connections(&self, device: Device) {
        match device {
            Device::Arm => self.meca500.drop_client(),
            Device::Guide => {
                if let Some(z) = &self.zaber {
                    z.drop_clients();
                }
            }
            Device::Gauge(i) => {
                if let Some(g) = self.gauges.get(i) {
                    g.drop_clients();
                }
            }
            Device::Control => self.control.drop_clients(),
            Device::Tracker => self.tracker.drop_clients(),
        }
    }

    /// Stalls (`true`) or revives `device`: connections stay open, nothing is answered.
    pub fn set_stalled(&self, device: Device, stalled: bool) {
        match device {
            Device::Arm => self.meca500.set_stalled(stalled),
            Device::Guide => {
                if let Some(z) = &self.zaber {
                    z.set_stalled(stalled);
                }
            }
            Device::Gauge(i) => {
                if let Some(g) = self.gauges.get(i) {
                    g.set_stalled(stalled);
                }
            }
            Device::Control => self.control.set_stalled(stalled),
            Device::Tracker => self.tracker.set_stalled(stalled),
        }
    }

    /// The robot raises error `code` (e.g. 3005 motion error): error mode, motion stopped.
    pub fn robot_error(&self, code: u16, text: &str) {
        self.meca500.inject_error(code, text);
    }

    /// Presses or releases the robot's E-Stop.
    pub fn set_estop(&self, pressed: bool) {
        self.meca500.set_estop(pressed);
    }

    /// Gauge `index` reads out of range (`ERR3`) until cleared, wherever the ball is.
    pub fn set_gauge_out_of_range(&self, index: usize, on: bool) {
        if let Some(c) = self.gauge_couplings.get(index) {
            c.out_of_range.store(on, Ordering::SeqCst);
        }
    }

    /// The guide's motor stalls (`FS`); a running guide move stops where it is (nothing
    /// without a guide).
    pub fn guide_stall(&self) {
        if let Some(z) = &self.zaber {
            z.inject_stall();
        }
    }
}
