//! The "add an effect" recipe followed for a tiny effect (compiled for the unit tests of
//! this crate only, so the catalog itself is unchanged): `joint-quadratic`, a quadratic
//! transmission error of a revolute joint j, `theta_j += g q_j²` (parameter `quadratic{j}`).
//! It is a copy of `joint_scale.rs` using the generic `Extension` identifiers, registered by
//! one line in the `catalog!` list.

use super::{
    CandidateScope, ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect,
    Hook, entry_joint, joint_param, revolute_joint,
};
use crate::cell::EffectEntry;
use crate::params::{EffectParam, ParamId, ParamUnit};

/// This effect's id (unique among the extensions).
pub const ID: u8 = 0;
const KIND: EffectKind = EffectKind::Extension(ID);

/// The `joint-quadratic` example effect.
#[derive(Debug, Clone, Copy)]
pub struct JointQuadratic;

fn joint_of(spec: &EffectSpec) -> u8 {
    match *spec {
        EffectSpec::Extension { joint, .. } => joint,
        _ => 0,
    }
}

fn param(joint: u8) -> EffectParam {
    EffectParam::Extension { kind: KIND, joint, index: 0, slot: 0 }
}

impl ErrorEffect for JointQuadratic {
    fn kind(&self) -> EffectKind {
        KIND
    }
    fn name(&self) -> &'static str {
        "joint-quadratic"
    }
    fn meaning(&self) -> &'static str {
        "the joint's transmission error grows with the square of the angle"
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        vec![ParamId::Effect(param(joint_of(spec)))]
    }
    fn label(&self, spec: &EffectSpec) -> String {
        format!("{} (joint {})", self.name(), joint_of(spec))
    }
    fn joint(&self, spec: &EffectSpec) -> Option<u8> {
        Some(joint_of(spec))
    }
    fn owner(&self, p: &EffectParam) -> Option<EffectSpec> {
        match *p {
            EffectParam::Extension { kind: KIND, joint, .. } => {
                Some(EffectSpec::Extension { kind: KIND, joint, index: 0 })
            }
            _ => None,
        }
    }
    fn param_name(&self, p: &EffectParam) -> String {
        match p {
            EffectParam::Extension { joint, .. } => format!("quadratic{joint}"),
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        joint_param(name, "quadratic").map(param)
    }
    fn param_unit(&self, _p: &EffectParam) -> ParamUnit {
        ParamUnit::Ratio
    }
    fn bound(&self, _p: &ParamId) -> Option<(f64, &'static str)> {
        Some((1e-3, "1e-3 /rad"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::Extension { kind: KIND, joint: entry_joint(entry)?, index: 0 })
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
        joint.map(|joint| EffectSpec::Extension { kind: KIND, joint, index: 0 }).into_iter().collect()
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
        add(param(joint), Hook::Joint(joint), qj * qj);
    }
}
