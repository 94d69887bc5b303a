//! Simulated cells with hidden effects, shared by the integration tests.

#![allow(dead_code)]

pub mod benchmark;
pub mod campaign;

use vatcal_core::effects::EffectSpec;
use vatcal_core::{CellFile, Measurement, ParamId, ParamSet};
use vatcal_discovery::fit::{fit, residuals};
use vatcal_identification::{ErrorStats, IdentifyOptions};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
    synthetic_tracker_measurements,
};

/// Tracker noise of the validation data [mm] (a tracker with SMRs in nests, a few µm).
pub const TRACKER_SIGMA_MM: f64 = 0.005;

pub fn nominal() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("canonical cell");
    Model::from_cell(&cell).expect("model")
}

/// A hidden effect: the catalog instance and the true values of its parameters.
#[derive(Debug, Clone)]
pub struct Hidden {
    pub spec: EffectSpec,
    pub values: Vec<(ParamId, f64)>,
}

/// A simulated data set: the truth, probe measurements to fit, tracker measurements to validate.
pub struct Scenario {
    pub truth: Model,
    pub probe: Vec<Measurement>,
    pub validation: Vec<Measurement>,
}

/// Realistic true cell (seeded) with `hidden` effects switched on; `compliance`, when given,
/// replaces the drawn compliances c2..c7.
pub fn scenario(seed: u64, hidden: &[Hidden], compliance: Option<[f64; 6]>, n_probe: usize) -> Scenario {
    let nominal = nominal();
    let mut truth = perturbed_truth(&nominal, seed, &ErrorBudget::realistic());
    if let Some(c) = compliance {
        for (k, v) in c.iter().enumerate() {
            truth.set_param(ParamId::Compliance(k as u8 + 2), *v).expect("compliance");
        }
    }
    for h in hidden {
        truth.enable_effect(h.spec).expect("effect");
        for (id, v) in &h.values {
            truth.set_param(*id, *v).expect("effect value");
        }
    }
    let starts = probe_start_poses(&nominal, n_probe, seed.wrapping_add(101));
    let probe = synthetic_probe_measurements(&truth, &starts, ProbeNoise::default(), seed.wrapping_add(202));
    let validation = synthetic_tracker_measurements(&truth, 250, TRACKER_SIGMA_MM, seed.wrapping_add(303));
    Scenario { truth, probe, validation }
}

/// Validation error of the truth itself (the noise floor).
pub fn truth_validation(s: &Scenario) -> ErrorStats {
    ErrorStats::from_errors(&residuals(&s.truth, &s.validation).expect("residuals"))
}

/// Validation error of a fit with the *true* structure: `params` plus the parameters of the
/// hidden effects, starting from the nominal model with those effects switched on.
pub fn oracle_validation(s: &Scenario, params: &ParamSet, hidden: &[Hidden]) -> ErrorStats {
    let mut start = nominal();
    let mut set = params.clone();
    for h in hidden {
        start.enable_effect(h.spec).expect("effect");
        for id in h.spec.params() {
            if set.index_of(id).is_none() {
                set.0.push(id);
            }
        }
    }
    let f = fit(&start, &s.probe, &set, &IdentifyOptions::default()).expect("oracle fit");
    ErrorStats::from_errors(&residuals(&f.model, &s.validation).expect("residuals"))
}

/// A tool-changer offset and tilt (30 / −20 µm, 0.02° / −0.03°).
pub fn tool_frame() -> Hidden {
    use vatcal_core::params::ToolFrameDof as T;
    let id = |d| ParamId::Effect(vatcal_core::params::EffectParam::ToolFrame(d));
    Hidden {
        spec: EffectSpec::ToolFrame,
        values: vec![
            (id(T::Tx), 0.030),
            (id(T::Ty), -0.020),
            (id(T::Rx), 0.02f64.to_radians()),
            (id(T::Ry), -0.03f64.to_radians()),
        ],
    }
}

/// Gear harmonic `harmonic` of `joint` with amplitude [deg] and phase [deg].
pub fn cyclic_h(joint: u8, harmonic: u8, amplitude_deg: f64, phase_deg: f64) -> Hidden {
    let a = amplitude_deg.to_radians();
    let (s, c) = phase_deg.to_radians().sin_cos();
    Hidden {
        spec: EffectSpec::JointCyclic { joint, harmonic },
        values: vec![
            (ParamId::Effect(vatcal_core::params::EffectParam::CyclicSin { joint, harmonic }), a * c),
            (ParamId::Effect(vatcal_core::params::EffectParam::CyclicCos { joint, harmonic }), a * s),
        ],
    }
}
