//! Shared helpers of the planning tests.
#![allow(dead_code)]

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::BaseParam;
use vatcal_core::{CellFile, ParamId};
use vatcal_kinematics::Model;

/// The canonical cell file.
pub fn cell() -> CellFile {
    CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("canonical cell")
}

/// The nominal model of the canonical cell.
pub fn nominal() -> Model {
    Model::from_cell(&cell()).expect("nominal model")
}

/// A "calibrated" model: every MDH and base parameter perturbed by a small random error, beta_3,
/// non-zero compliance on every joint, and a cyclic error, a guide pitch/yaw and a tilted tool
/// frame switched on.
pub fn perturbed(seed: u64) -> Model {
    let mut m = nominal();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut nudge = |m: &mut Model, id: ParamId, amplitude: f64| {
        let v = m.param(id).expect("param") + rng.random_range(-amplitude..amplitude);
        m.set_param(id, v).expect("set");
    };
    let deg = 1f64.to_radians();
    for i in 2..=7u8 {
        nudge(&mut m, ParamId::Alpha(i), 0.3 * deg);
        nudge(&mut m, ParamId::A(i), 0.5);
        nudge(&mut m, ParamId::D(i), 0.5);
        nudge(&mut m, ParamId::ThetaOffset(i), 0.5 * deg);
        m.set_param(ParamId::Compliance(i), 2e-3).expect("compliance");
    }
    nudge(&mut m, ParamId::Beta(4), 0.2 * deg);
    for b in BaseParam::ALL {
        let amplitude = if matches!(b, BaseParam::X | BaseParam::Y | BaseParam::Z) { 2.0 } else { 0.3 * deg };
        nudge(&mut m, ParamId::Base(b), amplitude);
    }
    for spec in [
        EffectSpec::JointCyclic { joint: 3, harmonic: 1 },
        EffectSpec::GuideAngular { order: 2 },
        EffectSpec::ToolFrame,
    ] {
        m.enable_effect(spec).expect("effect");
        for id in spec.params() {
            let amplitude = if id.name().starts_with("tool_t") { 0.3 } else { 0.05 * deg };
            nudge(&mut m, id, amplitude);
        }
    }
    m
}
