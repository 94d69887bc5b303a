//! The physical state of the virtual cell, shared by all simulated devices.

use std::collections::BTreeMap;
use std::time::Duration;

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use rand::RngExt;
use vatcal_core::{JointVector, MAX_JOINTS, MeasurementContext};
use vatcal_hardware_traits::{ArmJoints, Clock, Error, ErrorKind, JointLayout, ProbePlacement, VirtualClock};
use vatcal_kinematics::Model;

use crate::config::SimConfig;
use crate::noise::{self, gauss, gauss3, key, uniform};

/// A straight-line motion in joint space between two instants (virtual time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Motion<const N: usize> {
    pub from: [f64; N],
    pub to: [f64; N],
    pub start: Duration,
    pub end: Duration,
}

impl<const N: usize> Motion<N> {
    pub fn at_rest(at: [f64; N]) -> Self {
        Self { from: at, to: at, start: Duration::ZERO, end: Duration::ZERO }
    }

    /// Position at `now` (the target once the motion is over; exact bits at rest).
    pub fn position(&self, now: Duration) -> [f64; N] {
        if now >= self.end || self.end <= self.start {
            return self.to;
        }
        let s = (now - self.start).as_secs_f64() / (self.end - self.start).as_secs_f64();
        let mut out = self.from;
        for (o, (a, b)) in out.iter_mut().zip(self.from.iter().zip(self.to.iter())) {
            *o = a + s * (b - a);
        }
        out
    }

    pub fn moving(&self, now: Duration) -> bool {
        now < self.end
    }
}

/// The arm as the controller and the physics see it. The arm has the joints of the cell's
/// [`JointLayout`] (J1.. = entries `0..n`, the rest of the fixed capacity stays 0).
#[derive(Debug, Clone)]
pub(crate) struct ArmState {
    pub activated: bool,
    pub homed: bool,
    pub error: Option<(i32, String)>,
    pub motion: Motion<MAX_JOINTS>,
    /// repeatability: world offset of the tool, re-drawn at every motion \[mm\]
    pub offset_mm: Vector3<f64>,
    /// sign of the last motion of each arm joint (J1.. = entries `0..n`)
    pub dir: [i8; MAX_JOINTS],
}

/// The arm's joints padded to the fixed capacity of [`ArmState`].
pub(crate) fn padded(arm: &ArmJoints) -> [f64; MAX_JOINTS] {
    let mut out = [0.0; MAX_JOINTS];
    for (o, v) in out.iter_mut().zip(arm.as_slice()) {
        *o = *v;
    }
    out
}

/// The guide.
#[derive(Debug, Clone)]
pub(crate) struct GuideState {
    pub homed: bool,
    pub motion: Motion<1>,
    /// repeatability: physical minus reported position \[mm\]
    pub offset_mm: f64,
}

/// What the campaign does not know about the probe.
#[derive(Debug, Clone)]
pub(crate) struct ProbeTruth {
    /// true world orientation of each placement
    pub placements: BTreeMap<u32, Matrix3<f64>>,
    /// true gauge directions in the (nominal) probe frame
    pub axes: [Vector3<f64>; 3],
    pub master_radius_mm: f64,
    pub ball_radius_mm: BTreeMap<u32, f64>,
    /// plunger position that reads zero, per gauge \[mm\]
    pub zero_plunger_mm: [f64; 3],
}

/// The whole virtual cell.
#[derive(Debug)]
pub(crate) struct World {
    pub seed: u64,
    pub config: SimConfig,
    pub nominal: Model,
    pub truth: Model,
    /// how the cell's joints split into the guide and the arm (from the nominal model)
    pub layout: JointLayout,
    pub clock: VirtualClock,
    pub arm: ArmState,
    pub guide: GuideState,
    pub plate: Option<u32>,
    pub master_ball: bool,
    /// tool-changer offset of this session, in the tool frame \[mm\]
    pub tool_offset_mm: Vector3<f64>,
    pub probe: ProbeTruth,
    /// nominal placements given to the campaign's TriCal
    pub nominal_placements: Vec<ProbePlacement>,
    /// key of the last event: readings draw their noise from it
    pub epoch: u64,
    pub reads_since_epoch: u64,
    /// world displacements requested by relative linear moves (oracle for tests)
    pub linear_moves: Vec<Vector3<f64>>,
    /// tracker registration error: reported = pivot + rotation (p − pivot) + translation
    pub tracker_registration: Option<TrackerRegistration>,
    /// offset of each SMR's optical centre from its nest centre, tool frame \[mm\]
    pub smr_offsets_mm: BTreeMap<u32, Vector3<f64>>,
    /// motions started by external simulators whose virtual time is not yet on the clock
    pub pending: Vec<PendingSegment>,
}

/// Motions of external simulators that run together (the guide and the arm commanded one
/// after the other and waited for together, as the campaign does): the virtual time of the
/// segment is the longer of the two.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct PendingSegment {
    /// arm motion from, to \[rad\] (J1.. = entries `0..n`)
    pub arm: Option<([f64; MAX_JOINTS], [f64; MAX_JOINTS])>,
    /// guide motion from, to \[mm\]
    pub guide: Option<(f64, f64)>,
}

/// The systematic error of the tracker's registration to the world frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TrackerRegistration {
    pub pivot: Vector3<f64>,
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
}

impl TrackerRegistration {
    fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.pivot + self.rotation * (p - self.pivot) + self.translation
    }
}

/// Rotation by an angle drawn uniformly in [0, max] about a random axis.
fn small_rotation(rng: &mut rand::rngs::ChaCha8Rng, max_rad: f64) -> Matrix3<f64> {
    let axis = gauss3(rng, 1.0);
    let angle = uniform(rng, 0.5 * max_rad) + 0.5 * max_rad;
    match Unit::try_new(axis, 1e-12) {
        Some(a) => *Rotation3::from_axis_angle(&a, angle).matrix(),
        None => Matrix3::identity(),
    }
}

/// `e` tilted by an angle drawn uniformly in [0, max] toward a random perpendicular.
fn tilted(rng: &mut rand::rngs::ChaCha8Rng, e: Vector3<f64>, max_rad: f64) -> Vector3<f64> {
    let angle = if max_rad > 0.0 { rng.random_range(0.0..=max_rad) } else { 0.0 };
    let perp = gauss3(rng, 1.0);
    let perp = perp - e * e.dot(&perp);
    match perp.try_normalize(1e-12) {
        Some(p) => e * angle.cos() + p * angle.sin(),
        None => e,
    }
}

impl World {
    pub fn new(nominal: Model, truth: Model, config: SimConfig, seed: u64, clock: VirtualClock) -> Self {
        let positions: Vec<(u32, Vector3<f64>)> = nominal
            .position_ids()
            .into_iter()
            .filter_map(|id| nominal.position(id).map(|p| (id, p)))
            .collect();
        let nominal_placements = ProbePlacement::radial_placements(&positions);

        let mut rng = noise::rng(key(seed, "probe", &[]));
        let imperfect = &config.probe;
        let placements = nominal_placements
            .iter()
            .map(|p| {
                (p.position, small_rotation(&mut rng, imperfect.placement_rotation_rad) * p.world_from_probe)
            })
            .collect();
        let axes = [Vector3::x(), Vector3::y(), Vector3::z()]
            .map(|e| tilted(&mut rng, e, imperfect.gauge_axis_tilt_rad));
        let master_radius_mm =
            config.master_ball_radius_mm + uniform(&mut rng, imperfect.ball_radius_tolerance_mm);
        let ball_radius_mm = truth
            .tcp_ids()
            .into_iter()
            .map(|t| (t, config.ball_radius_mm + uniform(&mut rng, imperfect.ball_radius_tolerance_mm)))
            .collect();
        // the probe comes zeroed with its master ball (6.350 mm preset)
        let zero = master_radius_mm - vatcal_hardware_traits::TRICAL_MASTER_PRESET_MM;

        let mut tool_rng = noise::rng(key(seed, "tool-changer", &[]));
        let tool_offset_mm = gauss3(&mut tool_rng, config.noise.tool_changer_repeatability_mm / 3.0);

        // tracker systematics (own streams: the other draws do not change when they are on)
        let physics = &config.physics;
        let mut reg_rng = noise::rng(key(seed, "tracker-registration", &[]));
        let pivot = if positions.is_empty() {
            Vector3::zeros()
        } else {
            positions.iter().map(|(_, p)| *p).sum::<Vector3<f64>>() / positions.len() as f64
        };
        let tracker_registration = (physics.tracker_registration_mm > 0.0
            || physics.tracker_registration_rad > 0.0)
            .then(|| TrackerRegistration {
                pivot,
                rotation: *Rotation3::new(gauss3(&mut reg_rng, physics.tracker_registration_rad)).matrix(),
                translation: gauss3(&mut reg_rng, physics.tracker_registration_mm),
            });
        let mut smr_rng = noise::rng(key(seed, "smr-nests", &[]));
        let smr_offsets_mm =
            truth.tcp_ids().into_iter().map(|t| (t, gauss3(&mut smr_rng, physics.smr_nest_mm))).collect();

        let layout = JointLayout::of(nominal.joint_kinds());
        Self {
            seed,
            config,
            nominal,
            truth,
            layout,
            clock,
            arm: ArmState {
                activated: false,
                homed: false,
                error: None,
                motion: Motion::at_rest([0.0; MAX_JOINTS]),
                offset_mm: Vector3::zeros(),
                dir: [0; MAX_JOINTS],
            },
            guide: GuideState { homed: false, motion: Motion::at_rest([0.0]), offset_mm: 0.0 },
            plate: None,
            master_ball: false,
            tool_offset_mm,
            probe: ProbeTruth {
                placements,
                axes,
                master_radius_mm,
                ball_radius_mm,
                zero_plunger_mm: [zero; 3],
            },
            nominal_placements,
            epoch: key(seed, "start", &[]),
            reads_since_epoch: 0,
            linear_moves: Vec::new(),
            tracker_registration,
            smr_offsets_mm,
            pending: Vec::new(),
        }
    }

    pub fn now(&self) -> Duration {
        self.clock.now()
    }

    /// A new event happened: readings now draw from `event_key`.
    pub fn new_epoch(&mut self, event_key: u64) {
        self.epoch = event_key;
        self.reads_since_epoch = 0;
    }

    /// The stream of the next reading of `device`.
    pub fn reading_rng(&mut self, device: &str, index: u64) -> rand::rngs::ChaCha8Rng {
        let k = key(self.epoch, device, &[index, self.reads_since_epoch]);
        self.reads_since_epoch += 1;
        noise::rng(k)
    }

    /// Number of arm joints.
    pub fn arm_count(&self) -> usize {
        self.layout.arm_joint_count()
    }

    /// Joints the arm reports now \[rad\].
    pub fn arm_joints(&self) -> ArmJoints {
        self.to_arm(&self.arm.motion.position(self.now()))
    }

    /// The arm's joints from the fixed-capacity storage.
    pub fn to_arm(&self, padded: &[f64; MAX_JOINTS]) -> ArmJoints {
        let mut a = ArmJoints::zeros(self.arm_count());
        let n = a.len();
        a.as_mut_slice().copy_from_slice(&padded[..n]);
        a
    }

    /// The arm's current motion directions (J1..).
    pub fn arm_dirs(&self) -> &[i8] {
        &self.arm.dir[..self.arm_count()]
    }

    /// The cell joint vector of the guide at `guide_mm` (ignored without a guide) and the arm
    /// at `arm`.
    pub fn cell_joints(&self, guide_mm: f64, arm: &ArmJoints) -> JointVector {
        let mut q = JointVector::zeros(self.layout.joint_count());
        if self.layout.has_guide() {
            q[0] = guide_mm;
        }
        for (k, v) in arm.as_slice().iter().enumerate() {
            q[self.layout.cell_joint(k) - 1] = *v;
        }
        q
    }

    /// Position the guide reports now \[mm\].
    pub fn guide_mm(&self) -> f64 {
        self.guide.motion.position(self.now())[0]
    }

    /// Duration of a joint-space move at `speed_fraction`.
    pub fn arm_duration(&self, from: &[f64], to: &[f64], speed_fraction: f64) -> Duration {
        let t = &self.config.timing;
        let s = (0..self.arm_count().min(from.len()).min(to.len()))
            .map(|j| (to[j] - from[j]).abs() / (t.joint_speed_rad_per_s[j] * speed_fraction).max(1e-9))
            .fold(0.0, f64::max);
        Duration::from_secs_f64(s + t.settle_s)
    }

    /// Starts an arm motion to `to`; `event_key` names the command (its noise).
    pub fn start_arm_motion(&mut self, to: &ArmJoints, speed_fraction: f64, event_key: u64) {
        let now = self.now();
        let from = self.arm.motion.position(now);
        let to = padded(to);
        for j in 0..self.arm_count() {
            if to[j] != from[j] {
                self.arm.dir[j] = if to[j] > from[j] { 1 } else { -1 };
            }
        }
        let end = now + self.arm_duration(&from, &to, speed_fraction);
        self.arm.motion = Motion { from, to, start: now, end };
        let mut rng = noise::rng(key(event_key, "arm-offset", &[]));
        self.arm.offset_mm = gauss3(&mut rng, self.config.noise.robot_repeatability_mm / 3.0);
        self.new_epoch(event_key);
    }

    /// Duration of a guide move over `distance_mm` at `speed_fraction`.
    pub fn guide_duration(&self, distance_mm: f64, speed_fraction: f64) -> Duration {
        let t = &self.config.timing;
        Duration::from_secs_f64(
            distance_mm.abs() / (t.guide_speed_mm_per_s * speed_fraction).max(1e-9) + t.settle_s,
        )
    }

    /// Starts a guide motion to `to_mm`.
    pub fn start_guide_motion(&mut self, to_mm: f64, speed_fraction: f64) {
        let now = self.now();
        let from = self.guide_mm();
        let previous_target = self.guide.motion.to[0];
        let end = now + self.guide_duration(to_mm - from, speed_fraction);
        self.guide.motion = Motion { from: [from], to: [to_mm], start: now, end };
        let event = key(self.seed, "guide", &[to_mm.to_bits(), previous_target.to_bits()]);
        let mut rng = noise::rng(key(event, "guide-offset", &[]));
        self.guide.offset_mm = gauss(&mut rng, self.config.noise.guide_repeatability_mm / 3.0);
        self.new_epoch(event);
    }

    /// Joints where the cell physically is (guide with its repeatability error).
    pub fn physical_joints(&self) -> JointVector {
        self.cell_joints(self.guide_mm() + self.guide.offset_mm, &self.arm_joints())
    }

    /// Per-sample context the true model sees (backlash direction, time, temperature when the
    /// cell has a temperature channel).
    pub fn context(&self) -> MeasurementContext {
        let t = self.now().as_secs_f64();
        MeasurementContext {
            dir: Some(self.layout.cell_dirs(self.arm_dirs())),
            time_s: Some(t),
            temperature_c: self.config.physics.thermal.map(|p| p.at(t)),
        }
    }

    /// What the cell's thermometer reads now [°C]: the temperature the truth sees
    /// ([`World::context`]) with the sensor's noise (keyed on the seed and the virtual time,
    /// drawing nothing from the other devices' streams) and resolution; `None` without a
    /// temperature channel.
    pub fn thermometer_c(&self) -> Option<f64> {
        let t = self.now().as_secs_f64();
        let true_c = self.config.physics.thermal?.at(t);
        let mut rng = noise::rng(key(self.seed, "thermometer", &[t.to_bits()]));
        Some(self.config.thermometer.reading_c(true_c, gauss(&mut rng, 1.0)))
    }

    /// True world position of the centre of ball (TCP) `tcp` \[mm\].
    pub fn ball_world(&self, tcp: u32) -> Option<Vector3<f64>> {
        self.tool_point_world(tcp, &Vector3::zeros())
    }

    /// True world position of the point `offset` (tool frame) away from ball `tcp`'s centre.
    fn tool_point_world(&self, tcp: u32, offset: &Vector3<f64>) -> Option<Vector3<f64>> {
        let t = self.truth.tcp(tcp)?;
        let chain = self.truth.chain_full(&self.physical_joints(), &self.context(), false, None);
        Some(chain.tool_point(&(t + self.tool_offset_mm + offset)) + self.arm.offset_mm)
    }

    /// Ball-centre offset from the true probe origin (world) and the ball's radius, for the
    /// ball nearest the origin; `None` without a plate.
    pub fn ball_in_probe(&self) -> Option<(Vector3<f64>, f64)> {
        let position = self.plate?;
        if self.master_ball {
            return Some((Vector3::zeros(), self.probe.master_radius_mm));
        }
        let origin = self.truth.position(position)?;
        self.truth
            .tcp_ids()
            .into_iter()
            .filter_map(|t| {
                let c = self.ball_world(t)? - origin;
                Some((c, self.probe.ball_radius_mm.get(&t).copied().unwrap_or(self.config.ball_radius_mm)))
            })
            .min_by(|a, b| a.0.norm().total_cmp(&b.0.norm()))
    }

    /// Plunger position of gauge `i` (tip plane distance from the origin along its axis) \[mm\];
    /// `None` when nothing touches it.
    pub fn plunger_mm(&self, i: usize) -> Option<f64> {
        let position = self.plate?;
        let (c_world, radius) = self.ball_in_probe()?;
        if c_world.norm() > self.config.gauge_range_mm + 2.0 {
            return None;
        }
        let r = self.probe.placements.get(&position)?;
        let c_probe = r.transpose() * c_world;
        Some(self.probe.axes[i].dot(&c_probe) + radius)
    }

    /// One noisy reading of gauge `i`.
    pub fn read_gauge(&mut self, i: usize) -> Result<f64, Error> {
        let device = format!("sim gauge {}", i + 1);
        let plunger = self.plunger_mm(i).ok_or_else(|| {
            Error::new(ErrorKind::OutOfRange, device.clone(), "nothing touches the plunger (at its stop)")
        })?;
        let mut rng = self.reading_rng("gauge", i as u64);
        let reading =
            plunger - self.probe.zero_plunger_mm[i] + uniform(&mut rng, self.config.noise.gauge_max_error_mm);
        if reading.abs() > self.config.gauge_range_mm {
            return Err(Error::new(
                ErrorKind::OutOfRange,
                device,
                format!("reading {reading:.4} mm is outside ±{} mm", self.config.gauge_range_mm),
            ));
        }
        Ok(reading)
    }

    /// Presets gauge `i` so that its current plunger position reads `value_mm`.
    pub fn preset_gauge(&mut self, i: usize, value_mm: f64) -> Result<(), Error> {
        let plunger = self.plunger_mm(i).ok_or_else(|| {
            Error::new(
                ErrorKind::OutOfRange,
                format!("sim gauge {}", i + 1),
                "nothing touches the plunger (at its stop)",
            )
        })?;
        self.probe.zero_plunger_mm[i] = plunger - value_mm;
        Ok(())
    }

    /// One noisy tracker measurement of ball/SMR `target`.
    /// With [`CellPhysics`](crate::CellPhysics) tracker errors, the SMR's optical centre sits
    /// off its nest centre and the reading carries the registration error.
    /// Target [`PROBE_NEST_TARGET`](vatcal_hardware_traits::PROBE_NEST_TARGET) is the SMR
    /// seated in the probe's trihedral nest: the true probe origin at the current placement
    /// (the registration measurements).
    pub fn track(&mut self, target: u32) -> Result<Vector3<f64>, Error> {
        let p = if target == vatcal_hardware_traits::PROBE_NEST_TARGET {
            let position = self.plate.ok_or_else(|| {
                Error::new(
                    ErrorKind::OutOfRange,
                    "sim tracker",
                    "the probe's nest SMR is not in view: the probe plate is not placed",
                )
            })?;
            self.truth.position(position)
        } else {
            let nest = self.smr_offsets_mm.get(&target).copied().unwrap_or_else(Vector3::zeros);
            if nest == Vector3::zeros() {
                self.ball_world(target)
            } else {
                self.tool_point_world(target, &nest)
            }
        };
        let p = p.ok_or_else(|| {
            Error::new(ErrorKind::OutOfRange, "sim tracker", format!("unknown target {target}"))
        })?;
        let loss = self.config.faults.tracker_line_of_sight_loss;
        if loss > 0.0 {
            let mut rng = self.reading_rng("tracker-line-of-sight", u64::from(target));
            if uniform(&mut rng, 0.5) + 0.5 < loss {
                return Err(Error::new(
                    ErrorKind::OutOfRange,
                    "sim tracker",
                    format!("line of sight lost: SMR {target} not visible"),
                ));
            }
        }
        let p = self.tracker_registration.map_or(p, |r| r.apply(&p));
        let mut rng = self.reading_rng("tracker", u64::from(target));
        Ok(p + gauss3(&mut rng, self.config.noise.tracker_error_mm / 3.0))
    }
}
