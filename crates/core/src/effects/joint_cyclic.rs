//! `joint-cyclic`: periodic transmission error of a revolute joint i,
//! `theta_i += s sin(k q_i) + c cos(k q_i)` for harmonic k (parameters
//! `cyclic{i}_h{k}_sin`, `cyclic{i}_h{k}_cos` \[rad\]).

use super::{
    CandidateScope, ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect,
    Hook, entry_joint,
};
use crate::cell::EffectEntry;
use crate::params::{EffectParam, ParamId, ParamUnit};
use crate::units::MAX_JOINTS;

/// Highest gear harmonic discovery proposes (harmonics enter in order: the next one is
/// proposed once the model has harmonic h ≥ 2).
pub const MAX_PROPOSED_HARMONIC: u8 = 4;

/// The `joint-cyclic` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointCyclic;

fn of(spec: &EffectSpec) -> (u8, u8) {
    match *spec {
        EffectSpec::JointCyclic { joint, harmonic } => (joint, harmonic),
        _ => (0, 0),
    }
}

impl ErrorEffect for JointCyclic {
    fn kind(&self) -> EffectKind {
        EffectKind::JointCyclic
    }
    fn name(&self) -> &'static str {
        "joint-cyclic"
    }
    fn meaning(&self) -> &'static str {
        "periodic transmission error of the joint (strain-wave gear, encoder eccentricity)"
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        let (joint, harmonic) = of(spec);
        vec![
            ParamId::Effect(EffectParam::CyclicSin { joint, harmonic }),
            ParamId::Effect(EffectParam::CyclicCos { joint, harmonic }),
        ]
    }
    fn label(&self, spec: &EffectSpec) -> String {
        let (joint, harmonic) = of(spec);
        format!("joint-cyclic (joint {joint}, harmonic {harmonic})")
    }
    fn joint(&self, spec: &EffectSpec) -> Option<u8> {
        Some(of(spec).0)
    }
    fn owner(&self, param: &EffectParam) -> Option<EffectSpec> {
        match *param {
            EffectParam::CyclicSin { joint, harmonic } | EffectParam::CyclicCos { joint, harmonic } => {
                Some(EffectSpec::JointCyclic { joint, harmonic })
            }
            _ => None,
        }
    }
    fn param_name(&self, param: &EffectParam) -> String {
        match *param {
            EffectParam::CyclicSin { joint, harmonic } => format!("cyclic{joint}_h{harmonic}_sin"),
            EffectParam::CyclicCos { joint, harmonic } => format!("cyclic{joint}_h{harmonic}_cos"),
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let s = name.strip_prefix("cyclic")?;
        let mut it = s.split('_');
        let j: u8 = it.next()?.parse().ok().filter(|j| (1..=MAX_JOINTS as u8).contains(j))?;
        let h: u8 = it.next()?.strip_prefix('h')?.parse().ok().filter(|h| *h >= 1)?;
        let kind = it.next()?;
        if it.next().is_some() {
            return None;
        }
        match kind {
            "sin" => Some(EffectParam::CyclicSin { joint: j, harmonic: h }),
            "cos" => Some(EffectParam::CyclicCos { joint: j, harmonic: h }),
            _ => None,
        }
    }
    fn param_unit(&self, _param: &EffectParam) -> ParamUnit {
        ParamUnit::Rad
    }
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        Some((0.5f64.to_radians(), "0.5 deg"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::JointCyclic {
            joint: entry_joint(entry)?,
            harmonic: entry.harmonic.ok_or("needs `harmonic`")?,
        })
    }
    fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        let (joint, harmonic) = of(spec);
        entry.joint = Some(joint);
        entry.harmonic = Some(harmonic);
    }
    fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        let (joint, harmonic) = of(spec);
        if chain.is_revolute(joint) && harmonic >= 1 {
            Ok(())
        } else {
            Err(format!(
                "joint must be a revolute joint of this chain of {}, and harmonic >= 1",
                chain.describe()
            ))
        }
    }
    fn scope(&self) -> CandidateScope {
        CandidateScope::PerRevoluteJoint
    }
    fn candidates(&self, _chain: &ChainInfo<'_>, _data: &DataUse, joint: Option<u8>) -> Vec<EffectSpec> {
        let Some(joint) = joint else { return Vec::new() };
        (1..=2u8).map(|harmonic| EffectSpec::JointCyclic { joint, harmonic }).collect()
    }
    fn follow_ups(&self, enabled: &EffectSpec) -> Vec<EffectSpec> {
        let (joint, harmonic) = of(enabled);
        if (2..MAX_PROPOSED_HARMONIC).contains(&harmonic) {
            vec![EffectSpec::JointCyclic { joint, harmonic: harmonic + 1 }]
        } else {
            Vec::new()
        }
    }
    fn driver(&self, spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Joint(of(spec).0)
    }
    fn contributions(
        &self,
        spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let (joint, harmonic) = of(spec);
        let qj = x.q.get(joint as usize - 1).copied().unwrap_or(0.0);
        let (s, c) = (f64::from(harmonic) * qj).sin_cos();
        add(EffectParam::CyclicSin { joint, harmonic }, Hook::Joint(joint), s);
        add(EffectParam::CyclicCos { joint, harmonic }, Hook::Joint(joint), c);
    }
}
