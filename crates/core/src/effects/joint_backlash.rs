//! `joint-backlash`: lost motion of a revolute joint i, `theta_i += b_i dir_i` with `dir_i`
//! the sign of the joint's last motion (±1; 0 when unknown) from the `dir{i}` column
//! (parameter `backlash{i}` \[rad\]).

use super::{
    DIR_COLUMNS, DataAvailability, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook,
    JointParam, PerJoint,
};
use crate::params::{EffectParam, ParamId, ParamUnit};

/// The `joint-backlash` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointBacklash;

/// Its instances: one per revolute joint.
const INSTANCES: PerJoint = PerJoint {
    spec: |joint| EffectSpec::JointBacklash { joint },
    joint_of: |spec| match *spec {
        EffectSpec::JointBacklash { joint } => joint,
        _ => 0,
    },
};

/// The parameter of each instance: `backlash{i}` \[rad\].
const PARAM: JointParam = JointParam {
    prefix: "backlash",
    unit: ParamUnit::Rad,
    param: |joint| EffectParam::Backlash { joint },
    joint_of: |param| match *param {
        EffectParam::Backlash { joint } => Some(joint),
        _ => None,
    },
};

impl ErrorEffect for JointBacklash {
    per_joint!(instances: INSTANCES, param: PARAM);

    fn kind(&self) -> EffectKind {
        EffectKind::JointBacklash
    }
    fn name(&self) -> &'static str {
        "joint-backlash"
    }
    fn meaning(&self) -> &'static str {
        "lost motion: the joint stops short by a fixed angle depending on the approach direction"
    }
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        Some((0.5f64.to_radians(), "0.5 deg"))
    }
    fn data_columns(&self, spec: &EffectSpec) -> &'static [&'static str] {
        let k = usize::from(INSTANCES.joint(spec)).wrapping_sub(1);
        DIR_COLUMNS.get(k).map_or(&[], std::slice::from_ref)
    }
    fn missing_data(&self, spec: &EffectSpec, data: &DataAvailability) -> Option<&'static str> {
        let k = usize::from(INSTANCES.joint(spec)).wrapping_sub(1);
        (!data.dir_known.get(k).copied().unwrap_or(false))
            .then_some("needs the dir{i} column of the joint (sign of its last motion, not all 0)")
    }
    fn driver(&self, spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Direction(INSTANCES.joint(spec))
    }
    fn contributions(
        &self,
        spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let joint = INSTANCES.joint(spec);
        add(EffectParam::Backlash { joint }, Hook::Joint(joint), f64::from(x.ctx.dir_of(joint)));
    }
}
