//! `joint-compliance`: `theta_i += c_i tau_i` on a revolute joint i. The compliance `c_i` is a
//! built-in parameter of every model (the kinematics apply it with the gravity torques), so
//! this module only names it, bounds it and proposes it.

use super::{
    CandidateScope, ChainInfo, DataUse, EffectDriver, EffectKind, EffectSpec, ErrorEffect, entry_joint,
    revolute_joint,
};
use crate::cell::EffectEntry;
use crate::params::ParamId;

/// The `joint-compliance` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointCompliance;

fn joint_of(spec: &EffectSpec) -> u8 {
    match *spec {
        EffectSpec::JointCompliance { joint } => joint,
        _ => 0,
    }
}

impl ErrorEffect for JointCompliance {
    fn kind(&self) -> EffectKind {
        EffectKind::JointCompliance
    }
    fn name(&self) -> &'static str {
        "joint-compliance"
    }
    fn meaning(&self) -> &'static str {
        "the joint yields under the gravity load (angle error proportional to the torque)"
    }
    fn is_builtin(&self) -> bool {
        true
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        vec![ParamId::Compliance(joint_of(spec))]
    }
    fn label(&self, spec: &EffectSpec) -> String {
        format!("{} (joint {})", self.name(), joint_of(spec))
    }
    fn joint(&self, spec: &EffectSpec) -> Option<u8> {
        Some(joint_of(spec))
    }
    fn bound(&self, param: &ParamId) -> Option<(f64, &'static str)> {
        matches!(param, ParamId::Compliance(_)).then_some((1e-2, "1e-2 rad/(N*m)"))
    }
    fn plausibility(&self, _spec: &EffectSpec, changes: &[(ParamId, f64)]) -> Result<(), String> {
        for (id, change) in changes {
            if let ParamId::Compliance(j) = id {
                // the compliance starts at 0 when it is added: the identified value is `change`
                if *change <= 0.0 {
                    return Err(format!(
                        "c_{j} came out {change:.3e} rad/(N*m): a joint cannot stiffen under load"
                    ));
                }
            }
            super::check_bounds(std::slice::from_ref(&(*id, *change)))?;
        }
        Ok(())
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::JointCompliance { joint: entry_joint(entry)? })
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
        joint.map(|joint| EffectSpec::JointCompliance { joint }).into_iter().collect()
    }
    fn driver(&self, spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Torque(joint_of(spec))
    }
}
