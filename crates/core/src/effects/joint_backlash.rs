//! `joint-backlash`: lost motion of a revolute joint i, `theta_i += b_i dir_i` with `dir_i`
//! the sign of the joint's last motion (±1; 0 when unknown) from the `dir{i}` column
//! (parameter `backlash{i}` [rad]).

use super::{
    CandidateScope, ChainInfo, DataAvailability, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec,
    DIR_COLUMNS, ErrorEffect, Hook, entry_joint, joint_param, revolute_joint,
};
use crate::cell::EffectEntry;
use crate::params::{EffectParam, ParamId, ParamUnit};

/// The `joint-backlash` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointBacklash;

fn joint_of(spec: &EffectSpec) -> u8 {
    match *spec {
        EffectSpec::JointBacklash { joint } => joint,
        _ => 0,
    }
}

impl ErrorEffect for JointBacklash {
    fn kind(&self) -> EffectKind {
        EffectKind::JointBacklash
    }
    fn name(&self) -> &'static str {
        "joint-backlash"
    }
    fn meaning(&self) -> &'static str {
        "lost motion: the joint stops short by a fixed angle depending on the approach direction"
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        vec![ParamId::Effect(EffectParam::Backlash { joint: joint_of(spec) })]
    }
    fn label(&self, spec: &EffectSpec) -> String {
        format!("{} (joint {})", self.name(), joint_of(spec))
    }
    fn joint(&self, spec: &EffectSpec) -> Option<u8> {
        Some(joint_of(spec))
    }
    fn owner(&self, param: &EffectParam) -> Option<EffectSpec> {
        match *param {
            EffectParam::Backlash { joint } => Some(EffectSpec::JointBacklash { joint }),
            _ => None,
        }
    }
    fn param_name(&self, param: &EffectParam) -> String {
        match param {
            EffectParam::Backlash { joint } => format!("backlash{joint}"),
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        joint_param(name, "backlash").map(|j| EffectParam::Backlash { joint: j })
    }
    fn param_unit(&self, _param: &EffectParam) -> ParamUnit {
        ParamUnit::Rad
    }
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        Some((0.5f64.to_radians(), "0.5 deg"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::JointBacklash { joint: entry_joint(entry)? })
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
        joint.map(|joint| EffectSpec::JointBacklash { joint }).into_iter().collect()
    }
    fn data_columns(&self, spec: &EffectSpec) -> &'static [&'static str] {
        let k = usize::from(joint_of(spec)).wrapping_sub(1);
        DIR_COLUMNS.get(k).map_or(&[], std::slice::from_ref)
    }
    fn missing_data(&self, spec: &EffectSpec, data: &DataAvailability) -> Option<&'static str> {
        let k = usize::from(joint_of(spec)).wrapping_sub(1);
        (!data.dir_known.get(k).copied().unwrap_or(false))
            .then_some("needs the dir{i} column of the joint (sign of its last motion, not all 0)")
    }
    fn driver(&self, spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Direction(joint_of(spec))
    }
    fn contributions(
        &self,
        spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let joint = joint_of(spec);
        add(EffectParam::Backlash { joint }, Hook::Joint(joint), f64::from(x.ctx.dir_of(joint)));
    }
}
