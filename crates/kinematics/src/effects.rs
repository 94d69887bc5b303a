//! The effect catalog: what each effect does to the chain.
//!
//! Joint effects act on revolute joints i; guide effects act on the guide joint g, the first
//! prismatic joint of the chain (joint 1 on the canonical cell; a chain without a prismatic
//! joint cannot switch them on).
//!
//! | effect | change to forward kinematics | parameters |
//! |---|---|---|
//! | `joint-compliance` | `theta_i += c_i tau_i` | `c_i` |
//! | `joint-cyclic` | `theta_i += s sin(k q_i) + c cos(k q_i)` | `cyclic{i}_h{k}_sin`, `_cos` [rad] |
//! | `joint-scale` | `theta_i += g_i q_i` | `scale{i}` |
//! | `joint-backlash` | `theta_i += b_i dir_i` (dir = sign of the last motion, ±1; 0 when unknown) | `backlash{i}` [rad] |
//! | `guide-angular` | after frame g: `Rx(e_x(u)) Ry(e_y(u)) Rz(e_z(u))`, `e(u) = Σ_o e_o P_o(u)` | `guide_angular_{x,y,z}_p{o}` [rad] |
//! | `guide-straightness` | after frame g: `T(s_x(u), s_y(u), 0)`, orders ≥ 2 | `guide_straightness_{x,y}_p{o}` [mm] |
//! | `guide-scale` | `d_g = (1 + s) q_g + d_offset` | `guide_scale` |
//! | `guide-carriage-tilt` | after frame g: `Rx(k_x M_x) Ry(k_y M_y)`, `M` = gravity moment of links g+1..N + tool about the carriage origin (carriage axes, undeflected geometry) | `carriage_tilt_{x,y}` [rad/(N·m)] |
//! | `tool-frame` | tool-changer frame = frame N · `T(tx, ty, 0) Rx(rx) Ry(ry)` | `tool_tx`, `tool_ty` [mm], `tool_rx`, `tool_ry` [rad] |
//! | `tcp-offset` | TCP coordinates | `tcp{k}_{x,y,z}` [mm] |
//! | `position-offset` | calibration-position coordinates | `position{k}_{x,y,z}` [mm] |
//! | `thermal-drift` | `a_{i-1}, d_i` of the revolute rows (2..7 on the canonical cell) scale by `1 + k v`, v = `time_s` or `temperature_c - T_ref` | `thermal_per_s` / `thermal_per_k` |
//! | `hayati-beta` | `beta_{i-1}` on row i | `beta_{i-1}` [rad] |
//!
//! `u = (q_g - mid) / half_stroke` is the guide position normalised to [-1, 1] over its limits,
//! and `P_o` the Legendre polynomials. Gravity torques are evaluated on the MDH geometry
//! without any effect (second-order difference).

use vatcal_core::effects::{EffectSpec, ThermalDriver};
use vatcal_core::{Measurement, Target};

use crate::Model;

/// What a set of measurements provides for data-hungry effects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DataAvailability {
    /// every measurement has the `dir{i}` columns
    pub dir: bool,
    /// every measurement has `time_s`
    pub time: bool,
    /// every measurement has `temperature_c`
    pub temperature: bool,
}

impl DataAvailability {
    /// Inspects a measurement set.
    pub fn of(measurements: &[Measurement]) -> Self {
        let all = |f: &dyn Fn(&Measurement) -> bool| !measurements.is_empty() && measurements.iter().all(f);
        Self {
            dir: all(&|m| m.context.dir.is_some()),
            time: all(&|m| m.context.time_s.is_some()),
            temperature: all(&|m| m.context.temperature_c.is_some()),
        }
    }
}

/// The per-measurement context columns (file names) an effect's predictions depend on:
/// `dir2..dir7` for backlash (the canonical cell's columns; a backlash on joint i reads
/// `dir{i}`), `time_s` / `temperature_c` for thermal drift, none otherwise.
pub fn context_columns(spec: &EffectSpec) -> &'static [&'static str] {
    match spec {
        EffectSpec::JointBacklash { .. } => &["dir2", "dir3", "dir4", "dir5", "dir6", "dir7"],
        EffectSpec::ThermalDrift { driver: ThermalDriver::Time } => &["time_s"],
        EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature } => &["temperature_c"],
        _ => &[],
    }
}

/// Why a catalog effect cannot be a candidate with this data, if it cannot.
pub fn missing_data(spec: &EffectSpec, data: &DataAvailability) -> Option<&'static str> {
    match spec {
        EffectSpec::JointBacklash { .. } if !data.dir => {
            Some("needs the dir{i} columns (sign of the last motion of each revolute joint)")
        }
        EffectSpec::ThermalDrift { driver: ThermalDriver::Time } if !data.time => {
            Some("needs the time_s column")
        }
        EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature } if !data.temperature => {
            Some("needs the temperature_c column")
        }
        _ => None,
    }
}

/// Every catalog effect instance that could be added to `model`: per-joint effects on the
/// revolute joints (cyclic harmonics 1 and 2), guide effects (orders 2) when the chain has a
/// prismatic joint, tool frame, TCP and position offsets for the TCPs/positions used by
/// `measurements`, thermal drift, beta on rows 2..N (other than 4 on the canonical cell, where
/// beta_3 belongs to the paper's set). Instances whose parameters are all already in `fitted`
/// are left out by the caller.
pub fn candidate_effects(model: &Model, measurements: &[Measurement]) -> Vec<EffectSpec> {
    let mut v = Vec::new();
    for joint in (1..=model.joint_count() as u8).filter(|j| model.is_revolute(*j as usize)) {
        v.push(EffectSpec::JointCompliance { joint });
        for harmonic in 1..=2u8 {
            v.push(EffectSpec::JointCyclic { joint, harmonic });
        }
        v.push(EffectSpec::JointScale { joint });
        v.push(EffectSpec::JointBacklash { joint });
    }
    if model.guide_joint().is_some() {
        v.push(EffectSpec::GuideAngular { order: 2 });
        v.push(EffectSpec::GuideStraightness { order: 2 });
        v.push(EffectSpec::GuideScale);
        v.push(EffectSpec::GuideCarriageTilt);
    }
    v.push(EffectSpec::ToolFrame);
    let mut tcps: Vec<u32> = measurements.iter().map(|m| m.tcp).collect();
    tcps.sort_unstable();
    tcps.dedup();
    for tcp in tcps.into_iter().filter(|t| model.tcp(*t).is_some()) {
        v.push(EffectSpec::TcpOffset { tcp });
    }
    let mut positions: Vec<u32> = measurements
        .iter()
        .filter_map(|m| match m.target {
            Target::Probe { position } => Some(position),
            Target::Tracker { .. } => None,
        })
        .collect();
    positions.sort_unstable();
    positions.dedup();
    for position in positions.into_iter().filter(|p| model.position(*p).is_some()) {
        v.push(EffectSpec::PositionOffset { position });
    }
    v.push(EffectSpec::ThermalDrift { driver: ThermalDriver::Time });
    v.push(EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature });
    let canonical = model.is_meca500_on_guide();
    for row in (2..=model.joint_count() as u8).filter(|r| !(canonical && *r == 4)) {
        v.push(EffectSpec::HayatiBeta { row });
    }
    v
}
