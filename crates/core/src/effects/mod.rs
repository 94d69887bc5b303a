//! The error-effect catalog: one file per effect behind the [`ErrorEffect`] trait.
//!
//! Each catalog effect (e.g. `joint-cyclic`) lives in its own module of this folder and says
//! everything about itself in one place: its name, the parameters an instance brings (names,
//! units, plausibility bounds), how it is written to and read from the cell file's
//! `[[effects]]`, which chains it applies to, its candidate instances for discovery, the data
//! columns it needs, and **how it changes the kinematics**, as linear contributions of its
//! parameters to a small fixed set of [`Hook`]s (a joint-space offset before FK, a correction
//! of the guide-carriage or tool frame, a length scale). `vatcal-kinematics` turns hooks into
//! forward kinematics and analytic Jacobian columns once, for every effect: the Jacobian column
//! of an effect parameter is its coefficient times the hook's column.
//!
//! The registry ([`catalog()`], the `catalog!` list in this file) lists every effect once, one
//! line each. Adding an effect is one new file plus one registration line there (recipe in `docs/ARCHITECTURE.md`, "Add an
//! effect"); a new effect uses the generic [`EffectKind::Extension`], [`EffectSpec::Extension`]
//! and [`EffectParam::Extension`] identifiers, so no enum changes. The 13 effects of the
//! original catalog keep their named variants (files, reports and the public API name them).

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::cell::EffectEntry;
use crate::measurement::{Measurement, MeasurementContext};
use crate::units::JointKind;
use crate::units::MAX_JOINTS;
pub use crate::vocabulary::EffectKind;
use crate::vocabulary::{Axis, EffectParam, ParamId, ParamUnit};

/// Writes the `ErrorEffect` methods of a per-joint effect that follow from its [`PerJoint`]
/// (`per_joint!(instances: X)`), and from its [`JointParam`] too
/// (`per_joint!(instances: X, param: P)`); the effect's file writes the rest.
macro_rules! per_joint {
    (instances: $instances:expr) => {
        fn label(&self, spec: &$crate::effects::EffectSpec) -> String {
            $instances.label(self.name(), spec)
        }
        fn joint(&self, spec: &$crate::effects::EffectSpec) -> Option<u8> {
            Some($instances.joint(spec))
        }
        fn read_entry(
            &self,
            entry: &$crate::cell::EffectEntry,
        ) -> Result<$crate::effects::EffectSpec, String> {
            $instances.read_entry(entry)
        }
        fn write_entry(&self, spec: &$crate::effects::EffectSpec, entry: &mut $crate::cell::EffectEntry, _t: f64) {
            $instances.write_entry(spec, entry)
        }
        fn check(
            &self,
            spec: &$crate::effects::EffectSpec,
            chain: &$crate::effects::ChainInfo<'_>,
        ) -> Result<(), String> {
            $instances.check(spec, chain)
        }
        fn scope(&self) -> $crate::effects::CandidateScope {
            $crate::effects::CandidateScope::PerRevoluteJoint
        }
        fn candidates(
            &self,
            _chain: &$crate::effects::ChainInfo<'_>,
            _data: &$crate::effects::DataUse,
            joint: Option<u8>,
        ) -> Vec<$crate::effects::EffectSpec> {
            joint.map($instances.spec).into_iter().collect()
        }
    };
    (instances: $instances:expr, param: $param:expr) => {
        per_joint!(instances: $instances);
        fn params(&self, spec: &$crate::effects::EffectSpec) -> Vec<$crate::params::ParamId> {
            vec![$crate::params::ParamId::Effect(($param.param)($instances.joint(spec)))]
        }
        fn owner(&self, param: &$crate::params::EffectParam) -> Option<$crate::effects::EffectSpec> {
            ($param.joint_of)(param).map($instances.spec)
        }
        fn param_name(&self, param: &$crate::params::EffectParam) -> String {
            $param.name(param)
        }
        fn parse_param(&self, name: &str) -> Option<$crate::params::EffectParam> {
            $param.parse(name)
        }
        fn param_unit(&self, _param: &$crate::params::EffectParam) -> $crate::params::ParamUnit {
            $param.unit
        }
    };
}

/// Declares each effect's module and lists it in the registry: one line per effect,
/// `module::Struct`, in catalog order (the order of the catalog table and of discovery's
/// candidates).
macro_rules! catalog {
    ($($module:ident :: $effect:ident),* $(,)?) => {
        $(pub mod $module;)*

        /// The registered effects, in catalog order.
        const REGISTERED: &[&dyn ErrorEffect] = &[$(&$module::$effect),*];
    };
}

// The registry: add a new effect's line here.
catalog! {
    joint_compliance::JointCompliance,
    joint_cyclic::JointCyclic,
    joint_scale::JointScale,
    joint_backlash::JointBacklash,
    guide_angular::GuideAngular,
    guide_straightness::GuideStraightness,
    guide_scale::GuideScale,
    guide_carriage_tilt::GuideCarriageTilt,
    tool_frame::ToolFrame,
    tcp_offset::TcpOffset,
    position_offset::PositionOffset,
    thermal_drift::ThermalDrift,
    hayati_beta::HayatiBeta,
    joint_cyclic_half::JointCyclicHalf,
    link_bending::LinkBending,
    link_out_of_plane::LinkOutOfPlane,
    joint_thermal_drift::JointThermalDrift,
    joint_coupling::JointCoupling,
    joint_stiffness_nonlinear::JointStiffnessNonlinear,
}

#[cfg(test)]
mod recipe_example;

#[cfg(not(test))]
static CATALOG: &[&dyn ErrorEffect] = REGISTERED;

/// In this crate's unit tests the registry also holds the recipe's example effect
/// (`recipe_example.rs`): what its one line in the `catalog!` list would register.
#[cfg(test)]
static CATALOG: [&dyn ErrorEffect; REGISTERED.len() + 1] = {
    let mut all: [&dyn ErrorEffect; REGISTERED.len() + 1] =
        [&recipe_example::JointQuadratic; REGISTERED.len() + 1];
    let mut i = 0;
    while i < REGISTERED.len() {
        all[i] = REGISTERED[i];
        i += 1;
    }
    all
};

/// Every registered effect, in catalog order.
#[allow(clippy::redundant_slicing)] // a slice in the library, an array in its unit tests
pub fn catalog() -> &'static [&'static dyn ErrorEffect] {
    &CATALOG[..]
}

impl EffectKind {
    /// The registered implementation (`None` only for an unregistered extension id).
    pub fn effect(self) -> Option<&'static dyn ErrorEffect> {
        catalog().iter().copied().find(|e| e.kind() == self)
    }

    /// Exact catalog name (e.g. `joint-cyclic`).
    pub fn name(self) -> &'static str {
        self.effect().map_or("unregistered-effect", |e| e.name())
    }

    /// Parses a catalog name (any registered effect).
    pub fn from_name(name: &str) -> Option<Self> {
        catalog().iter().find(|e| e.name() == name).map(|e| e.kind())
    }

    /// True for effects whose parameters exist in every model (compliance, beta, TCP and
    /// position coordinates): "adding" them means adding their parameters to the fitted set.
    pub fn is_builtin(self) -> bool {
        self.effect().is_some_and(|e| e.is_builtin())
    }
}

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What drives the `thermal-drift` length scaling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ThermalDriver {
    /// the `time_s` column (seconds since the campaign start)
    Time,
    /// the `temperature_c` column, relative to the model's reference temperature
    Temperature,
}

/// One instance of a catalog effect (e.g. "joint-cyclic on joint 4, harmonic 1").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum EffectSpec {
    /// `joint-compliance` on a revolute joint
    JointCompliance {
        /// revolute joint 1..=N (2..=7 on the canonical cell)
        joint: u8,
    },
    /// `joint-cyclic` harmonic `harmonic` on a revolute joint (two parameters: sin, cos)
    JointCyclic {
        /// revolute joint 1..=N (2..=7 on the canonical cell)
        joint: u8,
        /// harmonic k >= 1
        harmonic: u8,
    },
    /// `joint-scale` on a revolute joint
    JointScale {
        /// revolute joint 1..=N (2..=7 on the canonical cell)
        joint: u8,
    },
    /// `joint-backlash` on a revolute joint (needs `dir` data)
    JointBacklash {
        /// revolute joint 1..=N (2..=7 on the canonical cell)
        joint: u8,
    },
    /// `guide-angular`: rotations about the three carriage axes, Legendre orders 1..=`order`
    GuideAngular {
        /// highest polynomial order
        order: u8,
    },
    /// `guide-straightness`: lateral x/y deviation, Legendre orders 2..=`order` (order 1 is
    /// indistinguishable from a tilted guide and is absorbed by the base pose)
    GuideStraightness {
        /// highest polynomial order (>= 2)
        order: u8,
    },
    /// `guide-scale`
    GuideScale,
    /// `guide-carriage-tilt` (2 parameters: compliances about the carriage x and y axes)
    GuideCarriageTilt,
    /// `tool-frame` (4 parameters)
    ToolFrame,
    /// `tcp-offset` of TCP `tcp` (3 parameters)
    TcpOffset {
        /// TCP id
        tcp: u32,
    },
    /// `position-offset` of calibration position `position` (3 parameters)
    PositionOffset {
        /// calibration position id
        position: u32,
    },
    /// `thermal-drift` (1 parameter)
    ThermalDrift {
        /// driving variable
        driver: ThermalDriver,
    },
    /// `hayati-beta` on MDH row `row` (1..=N)
    HayatiBeta {
        /// MDH row
        row: u8,
    },
    /// an instance of an effect added after the original catalog; what `joint` and `index`
    /// mean is up to the effect's module (e.g. a joint and a harmonic)
    Extension {
        /// the effect ([`EffectKind::Extension`])
        kind: EffectKind,
        /// joint (or row) the instance acts on, 0 when none
        joint: u8,
        /// a second instance index (harmonic, order, ...), 0 when none
        index: u8,
    },
}

impl EffectSpec {
    /// The catalog entry.
    pub fn kind(&self) -> EffectKind {
        match self {
            EffectSpec::JointCompliance { .. } => EffectKind::JointCompliance,
            EffectSpec::JointCyclic { .. } => EffectKind::JointCyclic,
            EffectSpec::JointScale { .. } => EffectKind::JointScale,
            EffectSpec::JointBacklash { .. } => EffectKind::JointBacklash,
            EffectSpec::GuideAngular { .. } => EffectKind::GuideAngular,
            EffectSpec::GuideStraightness { .. } => EffectKind::GuideStraightness,
            EffectSpec::GuideScale => EffectKind::GuideScale,
            EffectSpec::GuideCarriageTilt => EffectKind::GuideCarriageTilt,
            EffectSpec::ToolFrame => EffectKind::ToolFrame,
            EffectSpec::TcpOffset { .. } => EffectKind::TcpOffset,
            EffectSpec::PositionOffset { .. } => EffectKind::PositionOffset,
            EffectSpec::ThermalDrift { .. } => EffectKind::ThermalDrift,
            EffectSpec::HayatiBeta { .. } => EffectKind::HayatiBeta,
            EffectSpec::Extension { kind, .. } => *kind,
        }
    }

    /// The registered implementation of this instance's effect.
    pub fn effect(&self) -> Option<&'static dyn ErrorEffect> {
        self.kind().effect()
    }

    /// Joint index (1..=N) for per-joint effects (the canonical cell's guide, 1, for guide
    /// effects), `None` otherwise.
    pub fn joint(&self) -> Option<u8> {
        self.effect().and_then(|e| e.joint(self))
    }

    /// The parameters this effect instance brings, in a fixed order.
    pub fn params(&self) -> Vec<ParamId> {
        self.effect().map_or_else(Vec::new, |e| e.params(self))
    }

    /// The lower-order effects this instance corrects ([`ErrorEffect::prerequisites`]).
    pub fn prerequisites(&self) -> Vec<EffectSpec> {
        self.effect().map_or_else(Vec::new, |e| e.prerequisites(self))
    }

    /// Short human label, e.g. `joint-cyclic (joint 4, harmonic 1)`.
    pub fn label(&self) -> String {
        self.effect().map_or_else(|| format!("{self:?}"), |e| e.label(self))
    }
}

/// Where an effect parameter acts on the chain. `vatcal-kinematics` applies every hook in one
/// place (forward kinematics and the analytic Jacobian column of the hook).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Hook {
    /// joint-space offset of joint `j` (1..=N) before forward kinematics: added to `theta_j`
    /// of a revolute joint \[rad\], to `d_j` of a prismatic joint \[mm\]
    Joint(u8),
    /// translation of the guide carriage frame (after the guide joint's row) along its x or
    /// y axis \[mm\]; the carriage correction is `T(sx, sy, 0) Rx(ex) Ry(ey) Rz(ez)`
    GuideShift(Axis),
    /// rotation of the guide carriage frame about its x, y or z axis (in that order) \[rad\]
    GuideRotation(Axis),
    /// translation of the tool-changer frame along its x or y axis \[mm\]; the tool correction
    /// is `T(tx, ty, 0) Rx(rx) Ry(ry)` after frame N
    ToolShift(Axis),
    /// rotation of the tool-changer frame about its x or y axis \[rad\]
    ToolRotation(Axis),
    /// relative change of the lengths `a_{i-1}`, `d_i` of every revolute row
    LengthScale,
    /// rotation of link frame `joint` (1..=N, the frame after row `joint`) about its own x or
    /// y axis \[rad\]: the link tilts about the two axes perpendicular to its joint axis. The
    /// correction is `Rx(ex) Ry(ey)` inserted after frame `joint` (after a guide correction
    /// when `joint` is the guide); everything distal moves with it
    LinkRotation {
        /// the link frame (1..=N)
        joint: u8,
        /// `Axis::X` or `Axis::Y` (a rotation about z is a joint offset: [`Hook::Joint`])
        axis: Axis,
    },
    /// translation of link frame `joint` (1..=N) along its own x, y or z axis \[mm\]: the link
    /// correction after frame `joint` is `T(sx, sy, sz) Rx(ex) Ry(ey)` (the translation first,
    /// then the [`Hook::LinkRotation`] about the moved origin); everything distal moves with it
    LinkShift {
        /// the link frame (1..=N)
        joint: u8,
        /// the axis of frame `joint` the link moves along
        axis: Axis,
    },
}

/// What an effect's hook coefficients may depend on, for one sample.
#[derive(Debug, Clone, Copy)]
pub struct EffectInputs<'a> {
    /// joint values q_1..q_N (internal units: mm, rad)
    pub q: &'a [f64],
    /// per-sample context (motion directions, time, temperature)
    pub ctx: &'a MeasurementContext,
    /// the joint guide effects act on (1-based, the first prismatic joint), if any
    pub guide: Option<u8>,
    /// guide position normalised to [-1, 1] over its limits (0 without a guide)
    pub guide_u: f64,
    /// gravity moment about the carriage origin along the carriage x and y axes \[N·m\]
    /// (zeros unless an effect that [`ErrorEffect::needs_carriage_moment`] is evaluated)
    pub carriage_moment: [f64; 2],
    /// reference temperature \[°C\] of a temperature-driven drift
    pub thermal_reference_c: f64,
    /// gravity torque \[N·m\] of each joint, `[i - 1]` for joint i (the torques the
    /// compliances deflect under; zeros unless an effect that [`ErrorEffect::needs_torques`] is
    /// evaluated or a compliance is on)
    pub torques: [f64; MAX_JOINTS],
    /// gravity bending moment \[N·m\] each joint carries: the moment of everything distal to
    /// joint i about the origin of frame i, along frame i's x and y axes (`[i - 1]` for joint
    /// i; undeflected geometry; zeros unless an effect that
    /// [`ErrorEffect::needs_link_moments`] is evaluated)
    pub link_moments: [[f64; 2]; MAX_JOINTS],
}

impl<'a> EffectInputs<'a> {
    /// The inputs at joint values `q` with context `ctx` and nothing else: no guide, no loads
    /// (zero torques and moments), thermal reference 20 °C. Set the rest with struct update
    /// syntax (`EffectInputs { torques, ..EffectInputs::at(&q, &ctx) }`).
    pub fn at(q: &'a [f64], ctx: &'a MeasurementContext) -> Self {
        Self {
            q,
            ctx,
            guide: None,
            guide_u: 0.0,
            carriage_moment: [0.0; 2],
            thermal_reference_c: 20.0,
            torques: [0.0; MAX_JOINTS],
            link_moments: [[0.0; 2]; MAX_JOINTS],
        }
    }
}

/// What an effect may ask about the chain it is switched on for or proposed on.
#[derive(Debug, Clone, Copy)]
pub struct ChainInfo<'a> {
    /// joint kinds 1..=N
    pub kinds: &'a [JointKind],
    /// the joint guide effects act on (1-based), if any
    pub guide: Option<u8>,
    /// TCP ids of the model
    pub tcps: &'a [u32],
    /// calibration position ids of the model
    pub positions: &'a [u32],
    /// the canonical 7-joint Meca500-on-guide chain (prismatic guide + 6 revolute joints)
    pub canonical: bool,
    /// the joints' ranges (lower, upper) in internal units (rad, mm), 1..=N; empty when
    /// unknown (a continuous joint's range is one turn)
    pub ranges: &'a [(f64, f64)],
}

impl ChainInfo<'_> {
    /// Number of joints N.
    pub fn n(&self) -> usize {
        self.kinds.len()
    }

    /// True when joint `j` (1-based) exists and is revolute.
    pub fn is_revolute(&self, j: u8) -> bool {
        (1..=self.kinds.len()).contains(&(j as usize)) && self.kinds[j as usize - 1].is_revolute()
    }

    /// e.g. `7 joints (PRRRRRR)`.
    pub fn describe(&self) -> String {
        let letters: String = self.kinds.iter().map(|k| if k.is_revolute() { 'R' } else { 'P' }).collect();
        format!("{} joints ({letters})", self.kinds.len())
    }
}

/// Which measurements' TCPs and positions discovery may propose offsets for.
#[derive(Debug, Clone, Default)]
pub struct DataUse {
    /// TCP ids used by the measurements (sorted, unique, present in the model)
    pub tcps: Vec<u32>,
    /// calibration positions probed by the measurements (sorted, unique, present in the model)
    pub positions: Vec<u32>,
}

/// The direction column of each joint: `DIR_COLUMNS[i - 1]` is `dir{i}`, the sign of the last
/// motion of joint i (read for the revolute joints of a chain).
pub const DIR_COLUMNS: [&str; MAX_JOINTS] =
    ["dir1", "dir2", "dir3", "dir4", "dir5", "dir6", "dir7", "dir8", "dir9", "dir10", "dir11", "dir12"];

/// What a set of measurements provides for data-hungry effects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DataAvailability {
    /// every measurement has direction data (some `dir{i}` column)
    pub dir: bool,
    /// per joint (index `i - 1` is joint i): every measurement has direction data and some
    /// measurement knows the direction of joint i (a `dir{i}` column that is not all 0)
    pub dir_known: [bool; MAX_JOINTS],
    /// every measurement has `time_s`
    pub time: bool,
    /// every measurement has `temperature_c`
    pub temperature: bool,
}

impl DataAvailability {
    /// Inspects a measurement set.
    pub fn of(measurements: &[Measurement]) -> Self {
        let all = |f: &dyn Fn(&Measurement) -> bool| !measurements.is_empty() && measurements.iter().all(f);
        let dir = all(&|m| m.context.dir.is_some());
        let mut dir_known = [false; MAX_JOINTS];
        for (k, known) in dir_known.iter_mut().enumerate() {
            *known = dir && measurements.iter().any(|m| m.context.dir_of(k as u8 + 1) != 0);
        }
        Self {
            dir,
            dir_known,
            time: all(&|m| m.context.time_s.is_some()),
            temperature: all(&|m| m.context.temperature_c.is_some()),
        }
    }
}

/// The variable whose residual plot shows an effect best (discovery's "where" analysis).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EffectDriver {
    /// the gravity torque of joint j
    Torque(u8),
    /// the value of joint j
    Joint(u8),
    /// the motion direction of joint j
    Direction(u8),
    /// the TCP id
    Tcp,
    /// the calibration position id
    Position,
    /// `time_s`
    Time,
    /// `temperature_c`
    Temperature,
}

/// When discovery proposes an effect's instances.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CandidateScope {
    /// once per revolute joint, in the joint loop (instances of the per-joint effects are
    /// proposed joint by joint: compliance, cyclic, scale, backlash of joint 2, then joint 3, ...)
    PerRevoluteJoint,
    /// once for the chain, after the per-joint effects, in catalog order
    Chain,
}

/// One catalog effect. Implementations are stateless unit structs registered in `catalog.rs`.
///
/// Methods take the instance ([`EffectSpec`]) they describe; they are called only with
/// instances of their own kind. Nothing here is on the FK hot path of a model without effects:
/// the kinematics skip the effect layer entirely when no effect is switched on.
pub trait ErrorEffect: Sync + fmt::Debug {
    /// The effect's identifier.
    fn kind(&self) -> EffectKind;
    /// Exact catalog name (e.g. `joint-cyclic`), used in files and reports.
    fn name(&self) -> &'static str;
    /// One sentence on what the effect is physically.
    fn meaning(&self) -> &'static str;
    /// True for effects whose parameters are built into every model (compliance, beta, TCP
    /// and position coordinates): they have no hooks and no `values` in the cell file.
    fn is_builtin(&self) -> bool {
        false
    }
    /// True for a **generic** description (a basis of smooth functions, e.g.
    /// `link-out-of-plane`) rather than a named physical mechanism: discovery tests the physical
    /// effects first: a smaller share of each round's screening level goes to the generic ones
    /// (`vatcal_discovery::workflow::GENERIC_SCREENING_SHARE`).
    fn generic(&self) -> bool {
        false
    }
    /// True when a model holds at most one instance (a polynomial of some order): switching
    /// on another instance replaces it.
    fn single_instance(&self) -> bool {
        false
    }

    /// The parameters the instance brings, in a fixed order.
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId>;
    /// Short human label (default: the name).
    fn label(&self, _spec: &EffectSpec) -> String {
        self.name().to_string()
    }
    /// The joint the instance acts on, if any.
    fn joint(&self, _spec: &EffectSpec) -> Option<u8> {
        None
    }
    /// The instance (of the highest order) a parameter of this effect belongs to, for
    /// effect parameters ([`ParamId::Effect`]) only.
    fn owner(&self, _param: &EffectParam) -> Option<EffectSpec> {
        None
    }
    /// Stable name of one of this effect's [`EffectParam`]s.
    fn param_name(&self, param: &EffectParam) -> String {
        format!("{param:?}")
    }
    /// Parses a name produced by [`ErrorEffect::param_name`].
    fn parse_param(&self, _name: &str) -> Option<EffectParam> {
        None
    }
    /// Unit of one of this effect's [`EffectParam`]s.
    fn param_unit(&self, _param: &EffectParam) -> ParamUnit {
        ParamUnit::Ratio
    }
    /// Largest plausible magnitude (internal units) of one of the effect's parameters, with
    /// a human text (e.g. `0.5 deg`).
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        None
    }
    /// Checks the identified changes of the instance's parameters (default: the bounds of
    /// every parameter, see [`plausibility`]).
    fn plausibility(&self, spec: &EffectSpec, changes: &[(ParamId, f64)]) -> Result<(), String> {
        match self.bounded_magnitudes(spec, changes) {
            Some(peaks) => check_bounds(&peaks.iter().map(|(id, v, _)| (*id, *v)).collect::<Vec<_>>()),
            None => check_bounds(changes),
        }
    }
    /// For an effect whose parameters are the coefficients of a profile (the guide
    /// polynomials), what its plausibility bound applies to: per profile, the parameter whose
    /// bound is used, the profile's largest magnitude over the travel, and a name for people
    /// (e.g. "the x profile of guide-straightness (orders up to 8), peak over the travel").
    /// `None` (the default): the bound applies to every parameter on its own. A high-order
    /// polynomial has large coefficients that cancel, so its coefficients are no measure of
    /// how far it moves the carriage.
    fn bounded_magnitudes(
        &self,
        _spec: &EffectSpec,
        _changes: &[(ParamId, f64)],
    ) -> Option<Vec<(ParamId, f64, String)>> {
        None
    }

    /// Reads an instance from a cell file's `[[effects]]` entry (its `values` are read by the
    /// model). Errors say which field is missing or wrong.
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String>;
    /// Writes the instance's fields into an `[[effects]]` entry (name and values are written
    /// by the caller).
    fn write_entry(&self, _spec: &EffectSpec, _entry: &mut EffectEntry, _thermal_reference_c: f64) {}

    /// `Ok` when the instance exists on the chain; otherwise why not.
    fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String>;
    /// When discovery proposes instances.
    fn scope(&self) -> CandidateScope {
        CandidateScope::Chain
    }
    /// Candidate instances for discovery: for [`CandidateScope::PerRevoluteJoint`] those on
    /// `joint`; for [`CandidateScope::Chain`] (`joint` = `None`) those on the chain.
    fn candidates(&self, chain: &ChainInfo<'_>, data: &DataUse, joint: Option<u8>) -> Vec<EffectSpec>;
    /// Further candidates once `enabled` is in the model (e.g. the next gear harmonic).
    fn follow_ups(&self, _enabled: &EffectSpec) -> Vec<EffectSpec> {
        Vec::new()
    }
    /// Further candidates tested beside `candidate` (e.g. the lower polynomial orders).
    fn also_try(&self, _candidate: &EffectSpec) -> Vec<EffectSpec> {
        Vec::new()
    }
    /// The lower-order effects the instance `spec` is a correction of (the hierarchy
    /// principle: a higher-order term of a physical law is fitted with its first-order term;
    /// e.g. the `τ|τ|` term of a joint's spring with its linear compliance). When one of them is
    /// not in the model, discovery proposes the instance **together with it** and records both,
    /// so the higher-order term never stands in alone for the missing first-order one.
    /// Default: none.
    fn prerequisites(&self, _spec: &EffectSpec) -> Vec<EffectSpec> {
        Vec::new()
    }
    /// The per-measurement context columns (file names) the instance's predictions depend
    /// on (e.g. `dir3` for a backlash of joint 3, `time_s`).
    fn data_columns(&self, _spec: &EffectSpec) -> &'static [&'static str] {
        &[]
    }
    /// Why the instance cannot be a candidate with this data, if it cannot.
    fn missing_data(&self, _spec: &EffectSpec, _data: &DataAvailability) -> Option<&'static str> {
        None
    }
    /// The variable whose residual plot shows the instance best on a chain of `n` joints
    /// whose guide effects act on joint `guide`.
    fn driver(&self, spec: &EffectSpec, guide: u8, n: u8) -> EffectDriver;

    /// True when the hook coefficients need [`EffectInputs::carriage_moment`].
    fn needs_carriage_moment(&self) -> bool {
        false
    }
    /// True when the hook coefficients need [`EffectInputs::link_moments`].
    fn needs_link_moments(&self) -> bool {
        false
    }
    /// True when the hook coefficients need [`EffectInputs::torques`].
    fn needs_torques(&self) -> bool {
        false
    }
    /// How the instance changes the kinematics: calls `add(param, hook, coefficient)` once
    /// per parameter; the hook moves by `value(param) * coefficient` (every catalog effect
    /// is linear in its parameters), and `coefficient` is also the derivative of the hook
    /// with respect to the parameter. Built-in effects add nothing.
    fn contributions(
        &self,
        _spec: &EffectSpec,
        _x: &EffectInputs<'_>,
        _add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
    }
}

/// The effect a parameter belongs to: effect parameters by their variant, the built-in
/// parameters of the built-in effects (`c_i`, `beta_{i-1}`, TCP and position coordinates);
/// `None` for the other geometric parameters.
pub fn kind_of_param(id: &ParamId) -> Option<EffectKind> {
    match id {
        ParamId::Effect(e) => Some(e.kind()),
        ParamId::Compliance(_) => Some(EffectKind::JointCompliance),
        ParamId::Beta(_) => Some(EffectKind::HayatiBeta),
        ParamId::Tcp { .. } => Some(EffectKind::TcpOffset),
        ParamId::Position { .. } => Some(EffectKind::PositionOffset),
        _ => None,
    }
}

/// Largest plausible magnitude of a parameter in internal units, if the catalog bounds it.
pub fn bound_of(id: &ParamId) -> Option<(f64, &'static str)> {
    kind_of_param(id).and_then(EffectKind::effect).and_then(|e| e.bound(id))
}

fn check_bounds(changes: &[(ParamId, f64)]) -> Result<(), String> {
    for (id, change) in changes {
        if let Some((bound, text)) = bound_of(id)
            && change.abs() > bound
        {
            return Err(format!("{} changed by {change:.3e}: more than the plausible {text}", id.name()));
        }
    }
    Ok(())
}

/// Checks identified values of an effect's parameters: `changes` holds (parameter, identified
/// value − value before the effect was added) in internal units. Returns why it is implausible.
pub fn plausibility(spec: &EffectSpec, changes: &[(ParamId, f64)]) -> Result<(), String> {
    match spec.effect() {
        Some(e) => e.plausibility(spec, changes),
        None => check_bounds(changes),
    }
}

/// The hook and coefficient of one effect parameter at a sample (the derivative of the hook
/// with respect to the parameter): `None` when the parameter belongs to no registered effect.
pub fn hook_of(param: EffectParam, x: &EffectInputs<'_>) -> Option<(Hook, f64)> {
    let effect = param.kind().effect()?;
    let spec = effect.owner(&param)?;
    let mut found = None;
    effect.contributions(&spec, x, &mut |p, hook, c| {
        if p == param {
            found = Some((hook, c));
        }
    });
    found
}

/// Legendre polynomial P_n(u) (the guide polynomials).
pub fn legendre(n: u8, u: f64) -> f64 {
    match n {
        0 => 1.0,
        1 => u,
        2 => 0.5 * (3.0 * u * u - 1.0),
        3 => 0.5 * (5.0 * u * u * u - 3.0 * u),
        4 => (35.0 * u.powi(4) - 30.0 * u * u + 3.0) / 8.0,
        _ => {
            let (mut p0, mut p1) = (1.0, u);
            for k in 1..n {
                let kf = f64::from(k);
                let p2 = ((2.0 * kf + 1.0) * u * p1 - kf * p0) / (kf + 1.0);
                p0 = p1;
                p1 = p2;
            }
            p1
        }
    }
}

/// Every candidate instance of the catalog on a chain, in the order discovery scores them:
/// the per-revolute-joint effects joint by joint, then the chain effects in catalog order.
pub fn candidates(chain: &ChainInfo<'_>, data: &DataUse) -> Vec<EffectSpec> {
    let mut v = Vec::new();
    for joint in (1..=chain.n() as u8).filter(|j| chain.is_revolute(*j)) {
        for e in catalog().iter().filter(|e| e.scope() == CandidateScope::PerRevoluteJoint) {
            v.extend(e.candidates(chain, data, Some(joint)));
        }
    }
    for e in catalog().iter().filter(|e| e.scope() == CandidateScope::Chain) {
        v.extend(e.candidates(chain, data, None));
    }
    v
}

/// A joint number from an `[[effects]]` entry.
pub(crate) fn entry_joint(e: &EffectEntry) -> Result<u8, String> {
    e.joint.ok_or_else(|| "needs `joint`".to_string())
}

/// The check of a per-joint effect that acts on a revolute joint: `Ok` when `joint` is one of
/// `chain`'s revolute joints, the cell-file error otherwise.
pub(crate) fn revolute_joint(joint: u8, chain: &ChainInfo<'_>) -> Result<(), String> {
    if chain.is_revolute(joint) {
        Ok(())
    } else {
        Err(format!("joint must be a revolute joint of this chain of {}", chain.describe()))
    }
}

/// The joint of a per-joint parameter name `<prefix><joint>` (e.g. `scale3`), 1..=[`MAX_JOINTS`].
pub(crate) fn joint_param(name: &str, prefix: &str) -> Option<u8> {
    let j: u8 = name.strip_prefix(prefix)?.parse().ok()?;
    (1..=MAX_JOINTS as u8).contains(&j).then_some(j)
}

/// The instances of a per-joint effect: one on each revolute joint, written to the cell file
/// as `joint = j` (`joint-compliance`, `joint-scale`, `joint-backlash`). `per_joint!` turns
/// it into the effect's `label` (`<name> (joint j)`), `joint`, `read_entry`, `write_entry`,
/// `check` (a revolute joint of the chain), `scope` (per revolute joint) and `candidates`.
#[derive(Clone, Copy)]
pub(crate) struct PerJoint {
    /// the instance on joint j
    pub spec: fn(u8) -> EffectSpec,
    /// the joint of an instance (only asked for the effect's own instances)
    pub joint_of: fn(&EffectSpec) -> u8,
}

impl PerJoint {
    /// The joint of one of the effect's instances.
    pub(crate) fn joint(&self, spec: &EffectSpec) -> u8 {
        (self.joint_of)(spec)
    }
    pub(crate) fn label(&self, name: &str, spec: &EffectSpec) -> String {
        format!("{name} (joint {})", self.joint(spec))
    }
    pub(crate) fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        entry_joint(entry).map(self.spec)
    }
    pub(crate) fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry) {
        entry.joint = Some(self.joint(spec));
    }
    pub(crate) fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        revolute_joint(self.joint(spec), chain)
    }
}

/// The one effect parameter of each instance of a per-joint effect, named `<prefix><joint>`
/// (e.g. `scale3`). `per_joint!` turns it into the effect's `params`, `owner`, `param_name`,
/// `parse_param` and `param_unit`.
#[derive(Clone, Copy)]
pub(crate) struct JointParam {
    /// the name prefix (`scale` for `scale3`)
    pub prefix: &'static str,
    /// the unit of every instance's parameter
    pub unit: ParamUnit,
    /// the parameter of the instance on joint j
    pub param: fn(u8) -> EffectParam,
    /// the joint of a parameter, `None` for another effect's parameter
    pub joint_of: fn(&EffectParam) -> Option<u8>,
}

impl JointParam {
    pub(crate) fn name(&self, param: &EffectParam) -> String {
        (self.joint_of)(param).map_or_else(String::new, |j| format!("{}{j}", self.prefix))
    }
    pub(crate) fn parse(&self, name: &str) -> Option<EffectParam> {
        joint_param(name, self.prefix).map(self.param)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registry_holds_every_effect_once_with_round_tripping_names() {
        let kinds: Vec<EffectKind> = catalog().iter().map(|e| e.kind()).collect();
        let mut unique = kinds.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), kinds.len(), "an effect id is registered twice");
        for k in EffectKind::ALL {
            assert!(kinds.contains(&k), "{k:?} is not registered");
            assert_eq!(EffectKind::from_name(k.name()), Some(k));
        }
        let mut names: Vec<&str> = catalog().iter().map(|e| e.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), kinds.len(), "two effects share a name");
    }

    /// The recipe followed for `joint-quadratic` (`recipe_example.rs` + its registry line):
    /// the effect is known by name, its instances and parameters get names, units, bounds,
    /// cell-file entries and candidates from its file alone, and its hook coefficient is
    /// the derivative of its joint offset (what the kinematics turn into FK and Jacobian).
    #[test]
    fn an_effect_added_by_the_recipe_works_everywhere() {
        use crate::cell::CellFile;
        use crate::params::ParamSet;
        use JointKind::{Prismatic as P, Revolute as R};
        let kind = EffectKind::from_name("joint-quadratic").expect("registered by name");
        assert_eq!(kind, EffectKind::Extension(recipe_example::ID));
        let spec = EffectSpec::Extension { kind, joint: 3, index: 0 };
        assert_eq!(spec.label(), "joint-quadratic (joint 3)");
        let params = spec.params();
        assert_eq!(params.len(), 1);
        assert_eq!(params[0].name(), "quadratic3");
        assert_eq!(ParamSet::parse("quadratic3, d_4").map(|s| s.0[0]), Ok(params[0]));
        assert_eq!(params[0].unit(), ParamUnit::Ratio);
        assert!(plausibility(&spec, &[(params[0], 2e-3)]).is_err(), "beyond its bound");
        assert!(plausibility(&spec, &[(params[0], 2e-4)]).is_ok());
        // the chain check and the candidates
        let kinds = [P, R, R, R, R, R, R];
        let chain = ChainInfo {
            kinds: &kinds,
            guide: Some(1),
            tcps: &[1],
            positions: &[1],
            canonical: true,
            ranges: &[],
        };
        let effect = spec.effect().expect("registered");
        assert!(effect.check(&spec, &chain).is_ok());
        let on_guide = EffectSpec::Extension { kind, joint: 1, index: 0 };
        assert!(effect.check(&on_guide, &chain).is_err_and(|m| m.contains("revolute")));
        assert!(candidates(&chain, &DataUse::default()).contains(&spec));
        // the cell file's [[effects]] entry: the name validates, the fields round-trip
        let mut cell = CellFile::from_toml_str(
            include_str!("../../../../fixtures/meca500-zaber.toml"),
            "meca500-zaber.toml",
        )
        .expect("canonical cell");
        let mut entry = EffectEntry { effect: kind.name().to_string(), ..EffectEntry::default() };
        effect.write_entry(&spec, &mut entry, 20.0);
        assert_eq!(effect.read_entry(&entry), Ok(spec));
        cell.effects.push(entry);
        assert!(cell.validate("cell").is_ok(), "{:?}", cell.validate("cell"));
        // the hook: theta_3 += g q_3², coefficient q_3²
        let q = [100.0, 0.1, 0.7, 0.0, 0.0, 0.0, 0.0];
        let ctx = MeasurementContext::default();
        let x = EffectInputs { guide: Some(1), ..EffectInputs::at(&q, &ctx) };
        let ParamId::Effect(p) = params[0] else { panic!("an effect parameter") };
        assert_eq!(hook_of(p, &x), Some((Hook::Joint(3), 0.7 * 0.7)));
    }

    /// A backlash needs its own joint's `dir{i}` column, on any chain, and is a candidate only
    /// when that joint's directions are known in the data.
    #[test]
    fn a_backlash_needs_the_dir_column_of_its_joint() {
        use crate::measurement::Target;
        use crate::units::JointVector;
        let effect = EffectKind::JointBacklash.effect().expect("registered");
        for joint in [1, 3, 11, 12] {
            let spec = EffectSpec::JointBacklash { joint };
            assert_eq!(effect.data_columns(&spec), [format!("dir{joint}").as_str()]);
        }
        let measurement = |dir: Option<[i8; MAX_JOINTS]>| Measurement {
            tcp: 1,
            q: JointVector::new([0.0; 12]),
            target: Target::Probe { position: 1 },
            context: MeasurementContext { dir, ..Default::default() },
            probe_offset_mm: None,
        };
        let mut d = [0; MAX_JOINTS];
        d[10] = -1;
        let data = DataAvailability::of(&[measurement(Some(d)), measurement(Some([0; MAX_JOINTS]))]);
        let on = |joint| effect.missing_data(&EffectSpec::JointBacklash { joint }, &data);
        assert_eq!((on(11), on(10).is_some()), (None, true));
        let none = DataAvailability::of(&[measurement(Some(d)), measurement(None)]);
        assert!(effect.missing_data(&EffectSpec::JointBacklash { joint: 11 }, &none).is_some());
    }

    #[test]
    fn every_candidate_parameter_has_an_owner_and_a_round_tripping_name() {
        use JointKind::{Prismatic as P, Revolute as R};
        let kinds = [P, R, R, R, R, R, R];
        let chain = ChainInfo {
            kinds: &kinds,
            guide: Some(1),
            tcps: &[1, 2],
            positions: &[1],
            canonical: true,
            ranges: &[],
        };
        let data = DataUse { tcps: vec![1, 2], positions: vec![1] };
        let mut specs = candidates(&chain, &data);
        specs.push(EffectSpec::GuideAngular { order: 4 });
        specs.push(EffectSpec::GuideStraightness { order: 4 });
        for spec in specs {
            assert!(spec.effect().is_some_and(|e| e.check(&spec, &chain).is_ok()), "{spec:?}");
            for p in spec.params() {
                assert_eq!(ParamId::from_name(&p.name()), Some(p), "{}", p.name());
                if let ParamId::Effect(e) = p {
                    let owner = e.kind().effect().and_then(|k| k.owner(&e));
                    assert!(owner.is_some_and(|o| o.params().contains(&p)), "{} has no owner", p.name());
                }
            }
        }
    }
}
