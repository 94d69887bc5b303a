//! Configuration of the virtual cell: the paper's error budget (§2.5), probe imperfections,
//! motion timing and fault injection.

use vatcal_core::cell::MotionLimits;
use vatcal_core::{JointKind, MAX_JOINTS};

/// Random errors of the devices. Each figure is the paper's number, interpreted as a **3σ**
/// bound: Gaussian draws use σ = figure / 3 per axis; the gauge error is a uniform draw within
/// ± its maximum error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseBudget {
    /// robot position repeatability: a fresh random TCP offset after every arm motion \[mm\]
    pub robot_repeatability_mm: f64,
    /// guide repeatability: a fresh random position error after every guide motion \[mm\]
    pub guide_repeatability_mm: f64,
    /// tool-changer repeatability: a random tool offset drawn once per session \[mm\]
    pub tool_changer_repeatability_mm: f64,
    /// gauge maximum error (uniform) \[mm\]
    pub gauge_max_error_mm: f64,
    /// laser-tracker error per axis (3σ) \[mm\]
    pub tracker_error_mm: f64,
}

impl NoiseBudget {
    /// The paper's budget: robot 5 µm, guide 2.5 µm, tool changer 5 µm, gauge 1.2 µm,
    /// tracker ≈ 20 µm.
    pub fn paper() -> Self {
        Self {
            robot_repeatability_mm: 0.005,
            guide_repeatability_mm: 0.0025,
            tool_changer_repeatability_mm: 0.005,
            gauge_max_error_mm: 0.0012,
            tracker_error_mm: 0.020,
        }
    }

    /// No noise at all.
    pub fn none() -> Self {
        Self {
            robot_repeatability_mm: 0.0,
            guide_repeatability_mm: 0.0,
            tool_changer_repeatability_mm: 0.0,
            gauge_max_error_mm: 0.0,
            tracker_error_mm: 0.0,
        }
    }
}

impl Default for NoiseBudget {
    fn default() -> Self {
        Self::paper()
    }
}

/// Imperfections of the TriCal probe that the campaign does not know about.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeImperfections {
    /// each true gauge axis is tilted from its nominal direction by up to this angle \[rad\]
    /// (uniform in a cone): the nominal axes are "slightly non-orthogonal" to the truth
    pub gauge_axis_tilt_rad: f64,
    /// the true orientation of each placement differs from the configured one by up to this
    /// angle about a random axis \[rad\]
    pub placement_rotation_rad: f64,
    /// radius error of each ball (master and calibration balls), uniform within ± \[mm\]
    /// (half the paper's 2.5 µm diameter tolerance)
    pub ball_radius_tolerance_mm: f64,
}

impl Default for ProbeImperfections {
    /// 0.3° gauge-axis tilt, 0.1° placement rotation, ±1.25 µm ball radii.
    fn default() -> Self {
        Self {
            gauge_axis_tilt_rad: 0.3f64.to_radians(),
            placement_rotation_rad: 0.1f64.to_radians(),
            ball_radius_tolerance_mm: 0.00125,
        }
    }
}

/// How long things take in virtual time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimTiming {
    /// maximum speed of each arm joint J1.. \[rad/s\] (mm/s for a prismatic arm joint); index
    /// k is arm joint J(k+1), entries beyond the arm's joints are unused
    pub joint_speed_rad_per_s: [f64; MAX_JOINTS],
    /// maximum guide speed \[mm/s\]
    pub guide_speed_mm_per_s: f64,
    /// added to every motion (acceleration, settling) \[s\]
    pub settle_s: f64,
    /// one gauge reading \[s\]
    pub gauge_read_s: f64,
    /// one tracker measurement \[s\]
    pub tracker_read_s: f64,
    /// activation + homing of the arm \[s\]
    pub homing_s: f64,
    /// the operator re-placing the probe plate \[s\]
    pub operator_s: f64,
}

impl SimTiming {
    /// Speeds from the cell file's motion limits for a six-axis arm of revolute joints
    /// (degrees → radians), 0.3 s settling, 0.15 s per gauge reading, 1 s per tracker
    /// measurement, 8 s homing, the file's probe re-placement time.
    pub fn from_motion_limits(m: &MotionLimits) -> Self {
        Self::for_arm(m, &[JointKind::Revolute; 6])
    }

    /// [`SimTiming::from_motion_limits`] for an arm with joints `arm_kinds` (the arm's joints
    /// only, without the guide), with the rule of the planner's motion timer: the k-th
    /// revolute joint moves at the k-th of the `[motion]` table's six joint speeds, any further
    /// revolute joint at the slowest of them, a prismatic arm joint at the guide speed.
    pub fn for_arm(m: &MotionLimits, arm_kinds: &[JointKind]) -> Self {
        let slowest = m.joint_speed_deg_per_s.iter().copied().fold(f64::INFINITY, f64::min);
        let mut speed = [slowest.to_radians(); MAX_JOINTS];
        let mut revolute = 0;
        for (s, kind) in speed.iter_mut().zip(arm_kinds) {
            *s = if kind.is_revolute() {
                revolute += 1;
                m.joint_speed_deg_per_s.get(revolute - 1).copied().unwrap_or(slowest).to_radians()
            } else {
                m.guide_speed_mm_per_s
            };
        }
        Self {
            joint_speed_rad_per_s: speed,
            guide_speed_mm_per_s: m.guide_speed_mm_per_s,
            settle_s: 0.3,
            gauge_read_s: 0.15,
            tracker_read_s: 1.0,
            homing_s: 8.0,
            operator_s: m.probe_replacement_s,
        }
    }
}

impl Default for SimTiming {
    /// [`SimTiming::from_motion_limits`] of the default limits (Meca500 R3 rated speeds,
    /// 50 mm/s guide).
    fn default() -> Self {
        Self::from_motion_limits(&MotionLimits::default())
    }
}

/// Faults injected on purpose (tests of the safety checks).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimFaults {
    /// the physical result of a relative linear move is scaled by this factor (1 = healthy;
    /// 2.5 makes auto-centering overshoot and diverge; −1 moves the wrong way)
    pub linear_move_gain: f64,
    /// every gauge reading times out
    pub gauge_timeouts: bool,
    /// probability that a tracker measurement finds no line of sight to its SMR (an
    /// [`ErrorKind::OutOfRange`](vatcal_hardware_traits::ErrorKind::OutOfRange) error, like
    /// the paper's "not measurable due to SMR visibility issues"); drawn from the reading's
    /// own noise key, so a resumed campaign meets the same losses (0: never, the default)
    pub tracker_line_of_sight_loss: f64,
}

impl Default for SimFaults {
    fn default() -> Self {
        Self { linear_move_gain: 1.0, gauge_timeouts: false, tracker_line_of_sight_loss: 0.0 }
    }
}

/// Slow temperature of the cell, driven by the virtual clock:
/// `T(t) = start + rise (1 − e^(−t/τ)) + cycle_amplitude sin(2π t / cycle_period)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalProfile {
    /// temperature at t = 0 \[°C\]
    pub start_c: f64,
    /// warm-up rise reached for t ≫ τ \[K\]
    pub rise_k: f64,
    /// warm-up time constant τ \[s\]
    pub time_constant_s: f64,
    /// amplitude of the room's air-conditioning cycle \[K\]
    pub cycle_amplitude_k: f64,
    /// period of that cycle \[s\]
    pub cycle_period_s: f64,
}

impl ThermalProfile {
    /// Temperature at virtual time `t_s` \[°C\].
    pub fn at(&self, t_s: f64) -> f64 {
        let warm = if self.time_constant_s > 0.0 { 1.0 - (-t_s / self.time_constant_s).exp() } else { 1.0 };
        let cycle = if self.cycle_period_s > 0.0 {
            (std::f64::consts::TAU * t_s / self.cycle_period_s).sin()
        } else {
            0.0
        };
        self.start_c + self.rise_k * warm + self.cycle_amplitude_k * cycle
    }
}

/// The simulated thermometer of a cell with a temperature channel: it reads the cell's
/// temperature ([`ThermalProfile::at`] of the virtual time, the same temperature the truth's
/// thermal drift sees) plus Gaussian noise, rounded to its resolution (a PT100 with a 0.01 K
/// display: σ 0.02 K). The noise is keyed on the seed and the reading's virtual time, so a
/// resumed campaign reads the same values and the other devices' noise is unaffected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermometerSpec {
    /// σ of the reading noise \[K\]
    pub sigma_k: f64,
    /// display resolution \[K\] (0: none)
    pub resolution_k: f64,
}

impl Default for ThermometerSpec {
    /// σ 0.02 K, resolution 0.01 K.
    fn default() -> Self {
        Self { sigma_k: 0.02, resolution_k: 0.01 }
    }
}

impl ThermometerSpec {
    /// What the sensor shows for the true temperature `true_c` with the standard normal draw
    /// `z`: `true_c + σ z`, rounded to the resolution.
    pub fn reading_c(&self, true_c: f64, z: f64) -> f64 {
        let v = true_c + self.sigma_k * z;
        if self.resolution_k > 0.0 { (v / self.resolution_k).round() * self.resolution_k } else { v }
    }
}

/// Physics of the cell that is not a parameter of the true model: the temperature the clock
/// drives (seen by a temperature-driven `thermal-drift` of the truth and recorded as
/// `temperature_c`), and the systematic errors of the laser tracker. All zero / `None` =
/// today's idealised cell.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CellPhysics {
    /// cell temperature; `None`: no temperature channel (context `temperature_c` is empty)
    pub thermal: Option<ThermalProfile>,
    /// σ per axis of the translation error of the tracker's registration to the world \[mm\]
    /// (drawn once per cell)
    pub tracker_registration_mm: f64,
    /// σ per axis of the rotation error of that registration \[rad\], about the centroid of the
    /// calibration positions (the points the registration was measured on)
    pub tracker_registration_rad: f64,
    /// σ per axis of the offset of each SMR's optical centre from its nest centre, constant per
    /// SMR (they are not re-oriented in their nests) \[mm\]
    pub smr_nest_mm: f64,
}

impl CellPhysics {
    /// Nothing: no temperature channel, a perfectly registered tracker, perfect SMRs.
    pub fn none() -> Self {
        Self::default()
    }
}

/// Everything the virtual cell needs besides the models and the seed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// random device errors
    pub noise: NoiseBudget,
    /// probe imperfections
    pub probe: ProbeImperfections,
    /// virtual timing
    pub timing: SimTiming,
    /// injected faults
    pub faults: SimFaults,
    /// gauge measuring range: readings beyond ± this are errors \[mm\]
    pub gauge_range_mm: f64,
    /// master ball radius (1.5 in) \[mm\]
    pub master_ball_radius_mm: f64,
    /// calibration ball radius (1 in) \[mm\]
    pub ball_radius_mm: f64,
    /// temperature and tracker systematics ([`CellPhysics::none`] by default)
    pub physics: CellPhysics,
    /// the thermometer of a cell with a temperature channel (`physics.thermal`)
    pub thermometer: ThermometerSpec,
}

impl Default for SimConfig {
    /// The paper's cell: [`NoiseBudget::paper`], default imperfections and timing, no faults,
    /// ±6 mm gauges, 1.5 in master ball, 1 in calibration balls.
    fn default() -> Self {
        Self {
            noise: NoiseBudget::paper(),
            probe: ProbeImperfections::default(),
            timing: SimTiming::default(),
            faults: SimFaults::default(),
            gauge_range_mm: 6.0,
            master_ball_radius_mm: 19.05,
            ball_radius_mm: 12.7,
            physics: CellPhysics::none(),
            thermometer: ThermometerSpec::default(),
        }
    }
}

impl SimConfig {
    /// A perfect cell: no noise, no probe imperfections (timing kept).
    pub fn ideal() -> Self {
        Self {
            noise: NoiseBudget::none(),
            probe: ProbeImperfections {
                gauge_axis_tilt_rad: 0.0,
                placement_rotation_rad: 0.0,
                ball_radius_tolerance_mm: 0.0,
            },
            ..Self::default()
        }
    }
}
