//! The effect catalog: what each effect does to the chain.
//!
//! Each effect is defined in one module of [`vatcal_core::effects`] (one file per effect,
//! registered by one line in its `catalog.rs`): its names, parameters, bounds, candidates and
//! its linear contributions to the kinematic [`Hook`]s. This crate applies the hooks in one
//! place: `chain.rs` (forward kinematics: joint offsets before FK, guide-carriage and tool
//! frame corrections, length scale, link rotations and shifts) and `jacobian.rs` (the hook's column times the
//! parameter's coefficient). A model without effects skips the effect layer entirely.
//!
//! Joint effects act on revolute joints i; guide effects act on the guide joint g, the first
//! prismatic joint of the chain (joint 1 on the canonical cell; a chain without a prismatic
//! joint cannot switch them on).
//!
//! | effect | change to forward kinematics | parameters |
//! |---|---|---|
//! | `joint-compliance` | `theta_i += c_i tau_i` | `c_i` |
//! | `joint-cyclic` | `theta_i += s sin(k q_i) + c cos(k q_i)` | `cyclic{i}_h{k}_sin`, `_cos` \[rad\] |
//! | `joint-scale` | `theta_i += g_i q_i` | `scale{i}` |
//! | `joint-backlash` | `theta_i += b_i dir_i` (dir = sign of the last motion, ±1; 0 when unknown) | `backlash{i}` \[rad\] |
//! | `guide-angular` | after frame g: `Rx(e_x(u)) Ry(e_y(u)) Rz(e_z(u))`, `e(u) = Σ_o e_o P_o(u)` | `guide_angular_{x,y,z}_p{o}` \[rad\] |
//! | `guide-straightness` | after frame g: `T(s_x(u), s_y(u), 0)`, orders ≥ 2 | `guide_straightness_{x,y}_p{o}` \[mm\] |
//! | `guide-scale` | `d_g = (1 + s) q_g + d_offset` | `guide_scale` |
//! | `guide-carriage-tilt` | after frame g: `Rx(k_x M_x) Ry(k_y M_y)`, `M` = gravity moment of links g+1..N + tool about the carriage origin (carriage axes, undeflected geometry) | `carriage_tilt_{x,y}` \[rad/(N·m)\] |
//! | `tool-frame` | tool-changer frame = frame N · `T(tx, ty, 0) Rx(rx) Ry(ry)` | `tool_tx`, `tool_ty` \[mm\], `tool_rx`, `tool_ry` \[rad\] |
//! | `tcp-offset` | TCP coordinates | `tcp{k}_{x,y,z}` \[mm\] |
//! | `position-offset` | calibration-position coordinates | `position{k}_{x,y,z}` \[mm\] |
//! | `thermal-drift` | `a_{i-1}, d_i` of the revolute rows (2..7 on the canonical cell) scale by `1 + k v`, v = `time_s` or `temperature_c - T_ref` | `thermal_per_s` / `thermal_per_k` |
//! | `hayati-beta` | `beta_{i-1}` on row i | `beta_{i-1}` \[rad\] |
//! | `joint-cyclic-half` | `theta_i += s sin(m q_i / 2) + c cos(m q_i / 2)`, m odd | `halfcyclic{i}_m{m}_sin`, `_cos` \[rad\] |
//! | `link-bending` | after frame i: `Rx(k_x M_x) Ry(k_y M_y)`, `M` = gravity moment of everything distal to joint i about the origin of frame i (frame i's axes, undeflected geometry: [`Model::link_bending_moments`]) | `bend{i}_{x,y}` \[rad/(N·m)\] |
//! | `link-out-of-plane` | after frame i: `T(0, 0, s(q)) Rx(e_x(q)) Ry(e_y(q))`, one component per instance, each `Σ_k c_k φ_k(q_{i-1}, q_i)` over the first Fourier terms of both angles and their products | `oop{i}_{axial,rx,ry}_{term}` \[mm, rad\] |
//! | `joint-thermal-drift` | `theta_i += k_i (T - T_ref)` or `k_i t` | `thermal{i}_per_k` \[rad/K\], `thermal{i}_per_s` \[rad/s\] |
//! | `joint-coupling` | `theta_i += g q_k`, k a neighbouring revolute joint | `coupling{i}_q{k}` |
//! | `joint-stiffness-nonlinear` | `theta_i += c2_i tau_i \|tau_i\|` | `compliance_quadratic{i}` \[rad/(N·m)²\] |
//!
//! `u = (q_g - mid) / half_stroke` is the guide position normalised to [-1, 1] over its limits,
//! and `P_o` the Legendre polynomials. Gravity torques are evaluated on the MDH geometry
//! without any effect (second-order difference).

use vatcal_core::effects::{DataUse, EffectSpec};
use vatcal_core::{Measurement, Target};

use crate::Model;

pub use vatcal_core::effects::{
    DataAvailability, EffectInputs, ErrorEffect, Hook, catalog, hook_of, kind_of_param, legendre,
    plausibility,
};

/// The per-measurement context columns (file names) an effect's predictions depend on:
/// `dir{i}` for a backlash on joint i, `time_s` / `temperature_c` for thermal drift, none
/// otherwise.
pub fn context_columns(spec: &EffectSpec) -> &'static [&'static str] {
    spec.effect().map_or(&[], |e| e.data_columns(spec))
}

/// Why a catalog effect cannot be a candidate with this data, if it cannot.
pub fn missing_data(spec: &EffectSpec, data: &DataAvailability) -> Option<&'static str> {
    spec.effect().and_then(|e| e.missing_data(spec, data))
}

/// Every catalog effect instance that could be added to `model`: per-joint effects on the
/// revolute joints (cyclic harmonics 1 and 2), guide effects (orders 2) when the chain has a
/// prismatic joint, tool frame, TCP and position offsets for the TCPs/positions used by
/// `measurements`, thermal drift, beta on rows 2..N (other than 4 on the canonical cell, where
/// beta_3 belongs to the paper's set): what each effect's module proposes
/// ([`ErrorEffect::candidates`]). Instances whose parameters are all already in `fitted`
/// are left out by the caller.
pub fn candidate_effects(model: &Model, measurements: &[Measurement]) -> Vec<EffectSpec> {
    let mut tcps: Vec<u32> = measurements.iter().map(|m| m.tcp).collect();
    tcps.sort_unstable();
    tcps.dedup();
    tcps.retain(|t| model.tcp(*t).is_some());
    let mut positions: Vec<u32> = measurements
        .iter()
        .filter_map(|m| match m.target {
            Target::Probe { position } => Some(position),
            Target::Tracker { .. } | Target::Orientation { .. } | Target::Plane { .. } => None,
        })
        .collect();
    positions.sort_unstable();
    positions.dedup();
    positions.retain(|p| model.position(*p).is_some());
    let (model_tcps, model_positions) = (model.tcp_ids(), model.position_ids());
    vatcal_core::effects::candidates(
        &model.chain_info(&model_tcps, &model_positions),
        &DataUse { tcps, positions },
    )
}
