//! `joint-compliance`: `theta_i += c_i tau_i` on a revolute joint i. The compliance `c_i` is a
//! built-in parameter of every model (the kinematics apply it with the gravity torques), so
//! this module only names it, bounds it and proposes it.

use super::{EffectDriver, EffectKind, EffectSpec, ErrorEffect, PerJoint};
use crate::params::ParamId;

/// The `joint-compliance` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointCompliance;

/// Its instances: one per revolute joint.
const INSTANCES: PerJoint = PerJoint {
    spec: |joint| EffectSpec::JointCompliance { joint },
    joint_of: |spec| match *spec {
        EffectSpec::JointCompliance { joint } => joint,
        _ => 0,
    },
};

impl ErrorEffect for JointCompliance {
    per_joint!(instances: INSTANCES);

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
        vec![ParamId::Compliance(INSTANCES.joint(spec))]
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
    fn driver(&self, spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Torque(INSTANCES.joint(spec))
    }
}
