//! `joint-coupling`: the angle of revolute joint i is off in proportion to the angle of a
//! neighbouring joint k, `theta_i += g_{i,k} q_k` (parameter `coupling{i}_q{k}` \[rad/rad\]).
//!
//! Wrist joints are often driven through coupled transmissions (concentric shafts, bevel or
//! belt stages that pass through the preceding joint): turning joint k turns joint i's drive by
//! a ratio the controller compensates. A wrong compensation ratio leaves an error of joint i
//! proportional to q_k — the cross term of the transmission matrix, where `joint-scale` is its
//! diagonal. Discovery proposes it on each revolute joint for its revolute neighbours.

use super::{
    CandidateScope, ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook,
    entry_joint, revolute_joint,
};
use crate::cell::EffectEntry;
use crate::params::{EffectParam, ParamId, ParamUnit};
use crate::units::MAX_JOINTS;

/// This effect's id among the extensions.
pub const ID: u8 = 5;
const KIND: EffectKind = EffectKind::Extension(ID);

/// The `joint-coupling` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointCoupling;

/// The instance: joint `joint`'s error driven by joint `by`'s angle.
pub fn spec(joint: u8, by: u8) -> EffectSpec {
    EffectSpec::Extension { kind: KIND, joint, index: by }
}

/// The parameter of the instance on `joint` driven by `by`.
pub fn param(joint: u8, by: u8) -> EffectParam {
    EffectParam::Extension { kind: KIND, joint, index: by, slot: 0 }
}

fn of(spec: &EffectSpec) -> (u8, u8) {
    match *spec {
        EffectSpec::Extension { joint, index, .. } => (joint, index),
        _ => (0, 0),
    }
}

impl ErrorEffect for JointCoupling {
    fn kind(&self) -> EffectKind {
        KIND
    }
    fn name(&self) -> &'static str {
        "joint-coupling"
    }
    fn meaning(&self) -> &'static str {
        "the joint's angle is off in proportion to a neighbouring joint's angle (a coupled transmission whose compensation ratio is wrong)"
    }
    fn params(&self, s: &EffectSpec) -> Vec<ParamId> {
        let (joint, by) = of(s);
        vec![ParamId::Effect(param(joint, by))]
    }
    fn label(&self, s: &EffectSpec) -> String {
        let (joint, by) = of(s);
        format!("joint-coupling (joint {joint} by q{by})")
    }
    fn joint(&self, s: &EffectSpec) -> Option<u8> {
        Some(of(s).0)
    }
    fn owner(&self, p: &EffectParam) -> Option<EffectSpec> {
        match *p {
            EffectParam::Extension { kind: KIND, joint, index, slot: 0 } => Some(spec(joint, index)),
            _ => None,
        }
    }
    fn param_name(&self, p: &EffectParam) -> String {
        match *p {
            EffectParam::Extension { kind: KIND, joint, index, .. } => format!("coupling{joint}_q{index}"),
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let (j, k) = name.strip_prefix("coupling")?.split_once("_q")?;
        let ok = |v: u8| (1..=MAX_JOINTS as u8).contains(&v);
        let (j, k): (u8, u8) = (j.parse().ok().filter(|v| ok(*v))?, k.parse().ok().filter(|v| ok(*v))?);
        (j != k).then(|| param(j, k))
    }
    fn param_unit(&self, _p: &EffectParam) -> ParamUnit {
        ParamUnit::Ratio
    }
    fn bound(&self, _p: &ParamId) -> Option<(f64, &'static str)> {
        Some((1e-2, "1 %"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        let joint = entry_joint(entry)?;
        let by = entry.driving_joint.ok_or("needs `driving_joint` (the joint whose angle drives the error)")?;
        Ok(spec(joint, by))
    }
    fn write_entry(&self, s: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        let (joint, by) = of(s);
        entry.joint = Some(joint);
        entry.driving_joint = Some(by);
    }
    fn check(&self, s: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        let (joint, by) = of(s);
        revolute_joint(joint, chain)?;
        if by == joint || !(1..=chain.n() as u8).contains(&by) {
            return Err(format!("driving_joint must be another joint of this chain of {}, got {by}", chain.describe()));
        }
        Ok(())
    }
    fn scope(&self) -> CandidateScope {
        CandidateScope::PerRevoluteJoint
    }
    fn candidates(&self, chain: &ChainInfo<'_>, _data: &DataUse, joint: Option<u8>) -> Vec<EffectSpec> {
        let Some(j) = joint else { return Vec::new() };
        [j.wrapping_sub(1), j + 1].into_iter().filter(|k| chain.is_revolute(*k)).map(|k| spec(j, k)).collect()
    }
    fn driver(&self, s: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Joint(of(s).1)
    }
    fn contributions(&self, s: &EffectSpec, x: &EffectInputs<'_>, add: &mut dyn FnMut(EffectParam, Hook, f64)) {
        let (joint, by) = of(s);
        let qk = x.q.get((by as usize).wrapping_sub(1)).copied().unwrap_or(0.0);
        add(param(joint, by), Hook::Joint(joint), qk);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::MeasurementContext;
    use crate::units::JointKind;

    #[test]
    fn names_entries_candidates_and_hooks() {
        let s = spec(6, 5);
        assert_eq!(s.label(), "joint-coupling (joint 6 by q5)");
        let p = s.params()[0];
        assert_eq!(p.name(), "coupling6_q5");
        assert_eq!(ParamId::from_name("coupling6_q5"), Some(p));
        assert!(ParamId::from_name("coupling6_q6").is_none());
        let mut entry = EffectEntry { effect: "joint-coupling".into(), joint: Some(6), ..EffectEntry::default() };
        assert!(JointCoupling.read_entry(&entry).is_err_and(|m| m.contains("driving_joint")));
        JointCoupling.write_entry(&s, &mut entry, 20.0);
        assert_eq!(JointCoupling.read_entry(&entry), Ok(s));
        let kinds = [JointKind::Prismatic, JointKind::Revolute, JointKind::Revolute, JointKind::Revolute];
        let chain = ChainInfo { kinds: &kinds, guide: Some(1), tcps: &[], positions: &[], canonical: false, ranges: &[] };
        // neighbours that are revolute joints only (not the guide)
        assert_eq!(JointCoupling.candidates(&chain, &DataUse::default(), Some(2)), vec![spec(2, 3)]);
        assert_eq!(JointCoupling.candidates(&chain, &DataUse::default(), Some(3)), vec![spec(3, 2), spec(3, 4)]);
        assert!(JointCoupling.check(&spec(3, 3), &chain).is_err());
        assert!(JointCoupling.check(&spec(3, 9), &chain).is_err());
        let q = [10.0, 0.2, -0.7, 0.4];
        let ctx = MeasurementContext::default();
        let x = EffectInputs { guide: Some(1), ..EffectInputs::at(&q, &ctx) };
        assert_eq!(super::super::hook_of(param(3, 4), &x), Some((Hook::Joint(3), 0.4)));
    }
}
