//! `joint-scale`: the gear ratio or encoder scale of a revolute joint i differs from nominal,
//! `theta_i += g_i q_i` (parameter `scale{i}`).

use super::{
    CandidateScope, ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect,
    Hook, entry_joint, joint_param, revolute_joint,
};
use crate::cell::EffectEntry;
use crate::params::{EffectParam, ParamId, ParamUnit};

/// The `joint-scale` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointScale;

fn joint_of(spec: &EffectSpec) -> u8 {
    match *spec {
        EffectSpec::JointScale { joint } => joint,
        _ => 0,
    }
}

impl ErrorEffect for JointScale {
    fn kind(&self) -> EffectKind {
        EffectKind::JointScale
    }
    fn name(&self) -> &'static str {
        "joint-scale"
    }
    fn meaning(&self) -> &'static str {
        "the joint's gear ratio or encoder scale differs from nominal (error proportional to the angle)"
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        vec![ParamId::Effect(EffectParam::JointScale { joint: joint_of(spec) })]
    }
    fn label(&self, spec: &EffectSpec) -> String {
        format!("{} (joint {})", self.name(), joint_of(spec))
    }
    fn joint(&self, spec: &EffectSpec) -> Option<u8> {
        Some(joint_of(spec))
    }
    fn owner(&self, param: &EffectParam) -> Option<EffectSpec> {
        match *param {
            EffectParam::JointScale { joint } => Some(EffectSpec::JointScale { joint }),
            _ => None,
        }
    }
    fn param_name(&self, param: &EffectParam) -> String {
        match param {
            EffectParam::JointScale { joint } => format!("scale{joint}"),
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        joint_param(name, "scale").map(|j| EffectParam::JointScale { joint: j })
    }
    fn param_unit(&self, _param: &EffectParam) -> ParamUnit {
        ParamUnit::Ratio
    }
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        Some((1e-2, "1 %"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::JointScale { joint: entry_joint(entry)? })
    }
    fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        entry.joint = Some(joint_of(spec));
    }
    fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        revolute_joint(joint_of(spec), chain)
    }
    fn scope(&self) -> CandidateScope {
        CandidateScope::PerRevoluteJoint
    }
    fn candidates(&self, _chain: &ChainInfo<'_>, _data: &DataUse, joint: Option<u8>) -> Vec<EffectSpec> {
        joint.map(|joint| EffectSpec::JointScale { joint }).into_iter().collect()
    }
    fn driver(&self, spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Joint(joint_of(spec))
    }
    fn contributions(
        &self,
        spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let joint = joint_of(spec);
        let qj = x.q.get(joint as usize - 1).copied().unwrap_or(0.0);
        add(EffectParam::JointScale { joint }, Hook::Joint(joint), qj);
    }
}
