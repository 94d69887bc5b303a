//! The vocabulary models are described in: the catalog's effect kinds ([`EffectKind`]) and the
//! parameter identifiers ([`ParamId`] and its parts). Plain types, below both the effect
//! catalog (`crate::effects`, which gives the kinds their names and the effect parameters their
//! names and units) and the parameter names and sets (`crate::params`); both re-export them.

use serde::{Deserialize, Serialize};

/// The effect catalog. `name()` gives the exact catalog name used in files and reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum EffectKind {
    /// `joint-compliance`: theta_i += c_i tau_i
    JointCompliance,
    /// `joint-cyclic`: theta_i += s sin(k q_i) + c cos(k q_i)
    JointCyclic,
    /// `joint-scale`: theta_i += g_i q_i
    JointScale,
    /// `joint-backlash`: theta_i += b_i dir_i
    JointBacklash,
    /// `guide-angular`: carriage pitch/yaw/roll as Legendre polynomials of q1
    GuideAngular,
    /// `guide-straightness`: lateral carriage deviation as Legendre polynomials of q1
    GuideStraightness,
    /// `guide-scale`: d_1 += s q1
    GuideScale,
    /// `guide-carriage-tilt`: carriage rotation proportional to the arm's gravity moment
    GuideCarriageTilt,
    /// `tool-frame`: lateral offset and tilt of the tool-changer frame
    ToolFrame,
    /// `tcp-offset`: error of a TCP's CMM coordinates
    TcpOffset,
    /// `position-offset`: error of a calibration position
    PositionOffset,
    /// `thermal-drift`: arm length scaling with time or temperature
    ThermalDrift,
    /// `hayati-beta`: beta on an MDH row other than 4
    HayatiBeta,
    /// an effect added after the original catalog, identified by its own id (the `ID` constant
    /// of its module; unique, checked by a test)
    Extension(u8),
}

impl EffectKind {
    /// The 13 entries of the original catalog (every registered effect:
    /// [`catalog()`](crate::effects::catalog)).
    pub const ALL: [EffectKind; 13] = [
        EffectKind::JointCompliance,
        EffectKind::JointCyclic,
        EffectKind::JointScale,
        EffectKind::JointBacklash,
        EffectKind::GuideAngular,
        EffectKind::GuideStraightness,
        EffectKind::GuideScale,
        EffectKind::GuideCarriageTilt,
        EffectKind::ToolFrame,
        EffectKind::TcpOffset,
        EffectKind::PositionOffset,
        EffectKind::ThermalDrift,
        EffectKind::HayatiBeta,
    ];
}

/// A Cartesian axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Axis {
    /// x
    X,
    /// y
    Y,
    /// z
    Z,
}

impl Axis {
    /// All three axes in order.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// Index 0..3.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }

    /// Lower-case letter.
    pub fn letter(self) -> &'static str {
        match self {
            Axis::X => "x",
            Axis::Y => "y",
            Axis::Z => "z",
        }
    }

    pub(crate) fn from_letter(s: &str) -> Option<Self> {
        match s {
            "x" => Some(Axis::X),
            "y" => Some(Axis::Y),
            "z" => Some(Axis::Z),
            _ => None,
        }
    }
}

/// One of the six base-pose parameters `H_0^W = T(x,y,z) Rx(alpha) Ry(beta) Rz(gamma)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum BaseParam {
    /// x translation \[mm\]
    X,
    /// y translation \[mm\]
    Y,
    /// z translation \[mm\]
    Z,
    /// rotation about x \[rad\]
    Alpha,
    /// rotation about the new y \[rad\]
    Beta,
    /// rotation about the new z \[rad\]
    Gamma,
}

impl BaseParam {
    /// All six in the order x, y, z, alpha, beta, gamma.
    pub const ALL: [BaseParam; 6] =
        [BaseParam::X, BaseParam::Y, BaseParam::Z, BaseParam::Alpha, BaseParam::Beta, BaseParam::Gamma];

    pub(crate) fn suffix(self) -> &'static str {
        match self {
            BaseParam::X => "x",
            BaseParam::Y => "y",
            BaseParam::Z => "z",
            BaseParam::Alpha => "alpha",
            BaseParam::Beta => "beta",
            BaseParam::Gamma => "gamma",
        }
    }
}

/// The four degrees of freedom of the `tool-frame` effect:
/// `H_7 -> H_7 · T(tx, ty, 0) · Rx(rx) · Ry(ry)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ToolFrameDof {
    /// lateral offset along x7 \[mm\]
    Tx,
    /// lateral offset along y7 \[mm\]
    Ty,
    /// tilt about x \[rad\]
    Rx,
    /// tilt about y \[rad\]
    Ry,
}

impl ToolFrameDof {
    /// All four in order.
    pub const ALL: [ToolFrameDof; 4] =
        [ToolFrameDof::Tx, ToolFrameDof::Ty, ToolFrameDof::Rx, ToolFrameDof::Ry];

    pub(crate) fn suffix(self) -> &'static str {
        match self {
            ToolFrameDof::Tx => "tx",
            ToolFrameDof::Ty => "ty",
            ToolFrameDof::Rx => "rx",
            ToolFrameDof::Ry => "ry",
        }
    }
}

/// Parameters of the optional effect blocks (see the `effects` catalog in vatcal-kinematics).
///
/// `joint` is always the **joint index 1..=N** of the chain (a revolute joint; 2..=7 for the
/// Meca500 joints of the canonical cell).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum EffectParam {
    /// `joint-cyclic`: sine amplitude \[rad\] of harmonic `harmonic` of joint `joint`
    /// (`theta_i += s sin(k q_i) + c cos(k q_i)`). Name `cyclic{joint}_h{k}_sin`.
    CyclicSin {
        /// revolute joint 1..=N (2..=7 on the canonical cell)
        joint: u8,
        /// harmonic k >= 1
        harmonic: u8,
    },
    /// `joint-cyclic`: cosine amplitude \[rad\]. Name `cyclic{joint}_h{k}_cos`.
    CyclicCos {
        /// revolute joint 1..=N (2..=7 on the canonical cell)
        joint: u8,
        /// harmonic k >= 1
        harmonic: u8,
    },
    /// `joint-scale`: `theta_i += g_i q_i` [rad/rad]. Name `scale{joint}`.
    JointScale {
        /// revolute joint 1..=N (2..=7 on the canonical cell)
        joint: u8,
    },
    /// `joint-backlash`: `theta_i += b_i dir_i` \[rad\]. Name `backlash{joint}`.
    Backlash {
        /// revolute joint 1..=N (2..=7 on the canonical cell)
        joint: u8,
    },
    /// `guide-angular`: rotation of the carriage about its `axis` \[rad\], coefficient of the
    /// Legendre polynomial `P_order(u)`, `u = (q1 - mid) / half_stroke`. Name
    /// `guide_angular_{x,y,z}_p{order}`.
    GuideAngular {
        /// carriage axis
        axis: Axis,
        /// polynomial order (1 = linear, 2 = quadratic, ...)
        order: u8,
    },
    /// `guide-straightness`: lateral carriage deviation along `axis` (x or y) \[mm\], coefficient
    /// of `P_order(u)`. Name `guide_straightness_{x,y}_p{order}`.
    GuideStraightness {
        /// carriage axis (x or y)
        axis: Axis,
        /// polynomial order (>= 2 is separable; 1 is absorbed by the base pose)
        order: u8,
    },
    /// `guide-scale`: `d_1 += s q1` [mm/mm]. Name `guide_scale`.
    GuideScale,
    /// `guide-carriage-tilt`: compliance \[rad/(N·m)\] of the guide carriage about its `axis`
    /// (x or y, the carriage axes across the guide): the carriage rotates by
    /// `k_axis · M_axis`, `M` the gravity moment of the arm and its load about the carriage
    /// origin. Name `carriage_tilt_{x,y}`.
    CarriageTilt {
        /// carriage axis (x or y)
        axis: Axis,
    },
    /// `tool-frame`: offset/tilt of the tool-changer frame. Names `tool_tx`, `tool_ty`,
    /// `tool_rx`, `tool_ry`.
    ToolFrame(ToolFrameDof),
    /// `thermal-drift` driven by time: arm lengths scale by `1 + k t` \[1/s\]. Name
    /// `thermal_per_s`.
    ThermalPerSecond,
    /// `thermal-drift` driven by temperature: arm lengths scale by `1 + k (T - T_ref)` \[1/K\].
    /// Name `thermal_per_k`.
    ThermalPerKelvin,
    /// a parameter of an effect added after the original catalog (name and unit come from
    /// the effect's module)
    Extension {
        /// the effect ([`EffectKind::Extension`])
        kind: EffectKind,
        /// joint (or row) of the instance, 0 when none
        joint: u8,
        /// second instance index (harmonic, order, ...), 0 when none
        index: u8,
        /// which of the instance's parameters
        slot: u8,
    },
}

impl EffectParam {
    /// The catalog effect the parameter belongs to.
    pub fn kind(&self) -> EffectKind {
        match self {
            EffectParam::CyclicSin { .. } | EffectParam::CyclicCos { .. } => EffectKind::JointCyclic,
            EffectParam::JointScale { .. } => EffectKind::JointScale,
            EffectParam::Backlash { .. } => EffectKind::JointBacklash,
            EffectParam::GuideAngular { .. } => EffectKind::GuideAngular,
            EffectParam::GuideStraightness { .. } => EffectKind::GuideStraightness,
            EffectParam::GuideScale => EffectKind::GuideScale,
            EffectParam::CarriageTilt { .. } => EffectKind::GuideCarriageTilt,
            EffectParam::ToolFrame(_) => EffectKind::ToolFrame,
            EffectParam::ThermalPerSecond | EffectParam::ThermalPerKelvin => EffectKind::ThermalDrift,
            EffectParam::Extension { kind, .. } => *kind,
        }
    }
}

/// A stable identifier of one model parameter. See the module docs for names and units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ParamId {
    /// `alpha_{i-1}` of MDH row i (1..=N) \[rad\]
    Alpha(u8),
    /// `a_{i-1}` of MDH row i \[mm\]
    A(u8),
    /// Hayati `beta_{i-1}` of MDH row i \[rad\]
    Beta(u8),
    /// `theta_offset_i` of row i \[rad\]
    ThetaOffset(u8),
    /// `d_i` of row i \[mm\] (row 1: the guide offset)
    D(u8),
    /// joint compliance `c_i` of revolute joint i \[rad/(N·m)\]
    Compliance(u8),
    /// base pose in the world
    Base(BaseParam),
    /// TCP coordinate in the flange frame N (7 on the canonical cell) \[mm\]
    Tcp {
        /// TCP id
        id: u32,
        /// axis
        axis: Axis,
    },
    /// calibration-position coordinate in the world \[mm\]
    Position {
        /// calibration position id
        id: u32,
        /// axis
        axis: Axis,
    },
    /// a contact plane's normal tilt or offset in the world (plane rows, [`PlaneDof`])
    Plane {
        /// plane id
        id: u32,
        /// which degree of freedom
        dof: PlaneDof,
    },
    /// a parameter of an optional effect block
    Effect(EffectParam),
}

/// The three degrees of freedom of a contact plane `n·x = offset` in the world frame. The
/// normal is `n = normalize(n₀ + tilt_u·u + tilt_v·v)`, with `n₀` the plane's reference
/// normal (the cell file's, or the first estimate from the data) and `u`, `v` a fixed
/// orthonormal basis of the plane `n₀` spans; the offset is the plane's signed distance from
/// the world origin along `n` \[mm\].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum PlaneDof {
    /// tilt of the normal towards `u` \[rad\]
    TiltU,
    /// tilt of the normal towards `v` \[rad\]
    TiltV,
    /// signed distance of the plane from the world origin along its normal \[mm\]
    Offset,
}

impl PlaneDof {
    /// All three, in the order tilt_u, tilt_v, offset.
    pub const ALL: [PlaneDof; 3] = [PlaneDof::TiltU, PlaneDof::TiltV, PlaneDof::Offset];

    /// The name suffix (`tilt_u`, `tilt_v`, `offset`).
    pub fn suffix(self) -> &'static str {
        match self {
            PlaneDof::TiltU => "tilt_u",
            PlaneDof::TiltV => "tilt_v",
            PlaneDof::Offset => "offset",
        }
    }
}

/// Physical kind of a parameter, which fixes its unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ParamUnit {
    /// millimetres
    Mm,
    /// radians (shown in degrees at the boundary)
    Rad,
    /// rad/(N·m)
    RadPerNm,
    /// rad/(N·m)²
    RadPerNm2,
    /// dimensionless ratio (mm/mm or rad/rad)
    Ratio,
    /// 1/s
    PerSecond,
    /// 1/K
    PerKelvin,
}

impl ParamUnit {
    /// Unit label used in reports.
    pub fn label(self) -> &'static str {
        match self {
            ParamUnit::Mm => "mm",
            ParamUnit::Rad => "rad",
            ParamUnit::RadPerNm => "rad/(N*m)",
            ParamUnit::RadPerNm2 => "rad/(N*m)^2",
            ParamUnit::Ratio => "1",
            ParamUnit::PerSecond => "1/s",
            ParamUnit::PerKelvin => "1/K",
        }
    }
}
