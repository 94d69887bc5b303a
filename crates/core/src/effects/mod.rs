//! Names of the error-effect catalog and the parameters each effect instance brings.
//!
//! The *meaning* of each effect (how it changes forward kinematics and which Jacobian columns
//! it contributes) lives in `vatcal-kinematics::effects`; this module only fixes the stable
//! names, so that files, reports and the CLI agree.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::params::{Axis, EffectParam, ParamId, ToolFrameDof};

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
}

impl EffectKind {
    /// Every catalog entry.
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

    /// Exact catalog name (e.g. `joint-cyclic`).
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::JointCompliance => "joint-compliance",
            EffectKind::JointCyclic => "joint-cyclic",
            EffectKind::JointScale => "joint-scale",
            EffectKind::JointBacklash => "joint-backlash",
            EffectKind::GuideAngular => "guide-angular",
            EffectKind::GuideStraightness => "guide-straightness",
            EffectKind::GuideScale => "guide-scale",
            EffectKind::GuideCarriageTilt => "guide-carriage-tilt",
            EffectKind::ToolFrame => "tool-frame",
            EffectKind::TcpOffset => "tcp-offset",
            EffectKind::PositionOffset => "position-offset",
            EffectKind::ThermalDrift => "thermal-drift",
            EffectKind::HayatiBeta => "hayati-beta",
        }
    }

    /// Parses a catalog name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|k| k.name() == name)
    }

    /// True for effects whose parameters exist in every model (compliance, beta, TCP and
    /// position coordinates): "adding" them means adding their parameters to the fitted set.
    pub fn is_builtin(self) -> bool {
        matches!(
            self,
            EffectKind::JointCompliance
                | EffectKind::TcpOffset
                | EffectKind::PositionOffset
                | EffectKind::HayatiBeta
        )
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
        }
    }

    /// Joint index (1..=N) for per-joint effects, `None` otherwise.
    pub fn joint(&self) -> Option<u8> {
        match *self {
            EffectSpec::JointCompliance { joint }
            | EffectSpec::JointCyclic { joint, .. }
            | EffectSpec::JointScale { joint }
            | EffectSpec::JointBacklash { joint } => Some(joint),
            EffectSpec::GuideAngular { .. }
            | EffectSpec::GuideStraightness { .. }
            | EffectSpec::GuideScale
            | EffectSpec::GuideCarriageTilt => Some(1),
            _ => None,
        }
    }

    /// The parameters this effect instance brings, in a fixed order.
    pub fn params(&self) -> Vec<ParamId> {
        use EffectParam as E;
        match *self {
            EffectSpec::JointCompliance { joint } => vec![ParamId::Compliance(joint)],
            EffectSpec::JointCyclic { joint, harmonic } => vec![
                ParamId::Effect(E::CyclicSin { joint, harmonic }),
                ParamId::Effect(E::CyclicCos { joint, harmonic }),
            ],
            EffectSpec::JointScale { joint } => vec![ParamId::Effect(E::JointScale { joint })],
            EffectSpec::JointBacklash { joint } => vec![ParamId::Effect(E::Backlash { joint })],
            EffectSpec::GuideAngular { order } => (1..=order)
                .flat_map(|o| Axis::ALL.map(|axis| ParamId::Effect(E::GuideAngular { axis, order: o })))
                .collect(),
            EffectSpec::GuideStraightness { order } => (2..=order.max(2))
                .flat_map(|o| {
                    [Axis::X, Axis::Y].map(|axis| ParamId::Effect(E::GuideStraightness { axis, order: o }))
                })
                .collect(),
            EffectSpec::GuideScale => vec![ParamId::Effect(E::GuideScale)],
            EffectSpec::GuideCarriageTilt => {
                [Axis::X, Axis::Y].map(|axis| ParamId::Effect(E::CarriageTilt { axis })).to_vec()
            }
            EffectSpec::ToolFrame => {
                ToolFrameDof::ALL.iter().map(|d| ParamId::Effect(E::ToolFrame(*d))).collect()
            }
            EffectSpec::TcpOffset { tcp } => {
                Axis::ALL.iter().map(|a| ParamId::Tcp { id: tcp, axis: *a }).collect()
            }
            EffectSpec::PositionOffset { position } => {
                Axis::ALL.iter().map(|a| ParamId::Position { id: position, axis: *a }).collect()
            }
            EffectSpec::ThermalDrift { driver } => vec![ParamId::Effect(match driver {
                ThermalDriver::Time => E::ThermalPerSecond,
                ThermalDriver::Temperature => E::ThermalPerKelvin,
            })],
            EffectSpec::HayatiBeta { row } => vec![ParamId::Beta(row)],
        }
    }

    /// Short human label, e.g. `joint-cyclic (joint 4, harmonic 1)`.
    pub fn label(&self) -> String {
        match *self {
            EffectSpec::JointCyclic { joint, harmonic } => {
                format!("joint-cyclic (joint {joint}, harmonic {harmonic})")
            }
            EffectSpec::JointCompliance { joint }
            | EffectSpec::JointScale { joint }
            | EffectSpec::JointBacklash { joint } => format!("{} (joint {joint})", self.kind()),
            EffectSpec::GuideAngular { order } | EffectSpec::GuideStraightness { order } => {
                format!("{} (orders up to {order})", self.kind())
            }
            EffectSpec::TcpOffset { tcp } => format!("tcp-offset (TCP {tcp})"),
            EffectSpec::PositionOffset { position } => {
                format!("position-offset (position {position})")
            }
            EffectSpec::ThermalDrift { driver } => format!(
                "thermal-drift ({})",
                match driver {
                    ThermalDriver::Time => "time",
                    ThermalDriver::Temperature => "temperature",
                }
            ),
            EffectSpec::HayatiBeta { row } => format!("hayati-beta (row {row}, beta_{})", row - 1),
            EffectSpec::GuideScale | EffectSpec::GuideCarriageTilt | EffectSpec::ToolFrame => {
                self.kind().name().to_string()
            }
        }
    }
}
