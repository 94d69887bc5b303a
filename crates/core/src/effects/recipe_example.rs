//! The "add an effect" recipe followed for a tiny effect (compiled for the unit tests of
//! this crate only, so the catalog itself is unchanged): `joint-quadratic`, a quadratic
//! transmission error of a revolute joint j, `theta_j += g q_j²` (parameter `quadratic{j}`).
//! It is a copy of `joint_scale.rs` using the generic `Extension` identifiers, registered by
//! one line in the `catalog!` list.

use super::{EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook, JointParam, PerJoint};
use crate::params::{EffectParam, ParamId, ParamUnit};

/// This effect's id (unique among the extensions).
pub const ID: u8 = 0;
const KIND: EffectKind = EffectKind::Extension(ID);

/// The `joint-quadratic` example effect.
#[derive(Debug, Clone, Copy)]
pub struct JointQuadratic;

/// Its instances: one per revolute joint.
const INSTANCES: PerJoint = PerJoint {
    spec: |joint| EffectSpec::Extension { kind: KIND, joint, index: 0 },
    joint_of: |spec| match *spec {
        EffectSpec::Extension { joint, .. } => joint,
        _ => 0,
    },
};

/// The parameter of each instance: `quadratic{j}` [1/rad].
const PARAM: JointParam = JointParam {
    prefix: "quadratic",
    unit: ParamUnit::Ratio,
    param: |joint| EffectParam::Extension { kind: KIND, joint, index: 0, slot: 0 },
    joint_of: |param| match *param {
        EffectParam::Extension { kind: KIND, joint, .. } => Some(joint),
        _ => None,
    },
};

impl ErrorEffect for JointQuadratic {
    per_joint!(instances: INSTANCES, param: PARAM);

    fn kind(&self) -> EffectKind {
        KIND
    }
    fn name(&self) -> &'static str {
        "joint-quadratic"
    }
    fn meaning(&self) -> &'static str {
        "the joint's transmission error grows with the square of the angle"
    }
    fn bound(&self, _p: &ParamId) -> Option<(f64, &'static str)> {
        Some((1e-3, "1e-3 /rad"))
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
        add((PARAM.param)(joint), Hook::Joint(joint), qj * qj);
    }
}
