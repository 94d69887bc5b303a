//! `joint-scale`: the gear ratio or encoder scale of a revolute joint i differs from nominal,
//! `theta_i += g_i q_i` (parameter `scale{i}`).

use super::{EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook, JointParam, PerJoint};
use crate::params::{EffectParam, ParamId, ParamUnit};

/// The `joint-scale` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointScale;

/// Its instances: one per revolute joint.
const INSTANCES: PerJoint = PerJoint {
    spec: |joint| EffectSpec::JointScale { joint },
    joint_of: |spec| match *spec {
        EffectSpec::JointScale { joint } => joint,
        _ => 0,
    },
};

/// The parameter of each instance: `scale{i}` [rad/rad].
const PARAM: JointParam = JointParam {
    prefix: "scale",
    unit: ParamUnit::Ratio,
    param: |joint| EffectParam::JointScale { joint },
    joint_of: |param| match *param {
        EffectParam::JointScale { joint } => Some(joint),
        _ => None,
    },
};

impl ErrorEffect for JointScale {
    per_joint!(instances: INSTANCES, param: PARAM);

    fn kind(&self) -> EffectKind {
        EffectKind::JointScale
    }
    fn name(&self) -> &'static str {
        "joint-scale"
    }
    fn meaning(&self) -> &'static str {
        "the joint's gear ratio or encoder scale differs from nominal (error proportional to the angle)"
    }
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        Some((1e-2, "1 %"))
    }
    fn driver(&self, spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Joint(INSTANCES.joint(spec))
    }
    fn contributions(
        &self,
        spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let joint = INSTANCES.joint(spec);
        let qj = x.q.get(joint as usize - 1).copied().unwrap_or(0.0);
        add(EffectParam::JointScale { joint }, Hook::Joint(joint), qj);
    }
}
