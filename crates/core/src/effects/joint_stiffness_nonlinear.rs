//! `joint-stiffness-nonlinear`: the joint's spring is not linear, `theta_i += c2_i τ_i |τ_i|`
//! (parameter `compliance_quadratic{i}` \[rad/(N·m)²\]) on top of the linear compliance
//! `c_i τ_i`.
//!
//! A strain-wave or cycloidal gear is soft near zero torque and stiffens as the load grows
//! (the manufacturers' three-segment torsional stiffness curves): its deflection is a concave,
//! odd function of the torque. The linear compliance is its secant; the first term the secant
//! leaves out is odd and quadratic in size, `τ |τ|` (negative `c2` for a stiffening spring,
//! positive for a softening one). Driven by the same gravity torque as the compliance.

use super::{EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook, JointParam, PerJoint};
use crate::params::{EffectParam, ParamId, ParamUnit};

/// This effect's id among the extensions.
pub const ID: u8 = 6;
const KIND: EffectKind = EffectKind::Extension(ID);

/// The `joint-stiffness-nonlinear` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointStiffnessNonlinear;

/// The instance on joint `joint`.
pub fn spec(joint: u8) -> EffectSpec {
    EffectSpec::Extension { kind: KIND, joint, index: 0 }
}

/// Its parameter on joint `joint`.
pub fn param(joint: u8) -> EffectParam {
    EffectParam::Extension { kind: KIND, joint, index: 0, slot: 0 }
}

/// Its instances: one per revolute joint.
const INSTANCES: PerJoint = PerJoint {
    spec,
    joint_of: |s| match *s {
        EffectSpec::Extension { joint, .. } => joint,
        _ => 0,
    },
};

/// The parameter of each instance: `compliance_quadratic{i}` [rad/(N·m)²].
const PARAM: JointParam = JointParam {
    prefix: "compliance_quadratic",
    unit: ParamUnit::RadPerNm2,
    param,
    joint_of: |p| match *p {
        EffectParam::Extension { kind: KIND, joint, index: 0, slot: 0 } => Some(joint),
        _ => None,
    },
};

/// Largest plausible canonical magnitude \[rad/(N·m)²\]: 0.5° of extra deflection at 10 N·m
/// (the chain-scaled bound, 1° at the joint's largest gravity torque, is usually larger:
/// `crate::canonical::bounds`).
pub const CANONICAL_BOUND: f64 = 8.7e-5;

impl ErrorEffect for JointStiffnessNonlinear {
    per_joint!(instances: INSTANCES, param: PARAM);

    fn kind(&self) -> EffectKind {
        KIND
    }
    fn name(&self) -> &'static str {
        "joint-stiffness-nonlinear"
    }
    fn meaning(&self) -> &'static str {
        "the joint's spring is soft near zero torque and stiffens under load (strain-wave and cycloidal gears): the deflection's term in tau |tau| beyond the linear compliance"
    }
    fn bound(&self, _p: &ParamId) -> Option<(f64, &'static str)> {
        Some((CANONICAL_BOUND, "8.7e-5 rad/(N*m)^2"))
    }
    fn driver(&self, s: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Torque(INSTANCES.joint(s))
    }
    fn needs_torques(&self) -> bool {
        true
    }
    /// The term beyond the linear compliance `c_i` of the same joint.
    fn prerequisites(&self, s: &EffectSpec) -> Vec<EffectSpec> {
        vec![EffectSpec::JointCompliance { joint: INSTANCES.joint(s) }]
    }
    fn contributions(
        &self,
        s: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let joint = INSTANCES.joint(s);
        let tau = x.torques.get(joint as usize - 1).copied().unwrap_or(0.0);
        add(param(joint), Hook::Joint(joint), tau * tau.abs());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::MeasurementContext;
    use crate::units::MAX_JOINTS;

    #[test]
    fn names_and_the_hook_is_odd_in_the_torque() {
        let p = spec(3).params()[0];
        assert_eq!(p.name(), "compliance_quadratic3");
        assert_eq!(ParamId::from_name("compliance_quadratic3"), Some(p));
        assert_eq!(p.unit(), ParamUnit::RadPerNm2);
        let q = [0.0; 7];
        let ctx = MeasurementContext::default();
        let mut torques = [0.0; MAX_JOINTS];
        for tau in [-3.0, 0.5, 2.0] {
            torques[2] = tau;
            let x = EffectInputs { torques, ..EffectInputs::at(&q, &ctx) };
            assert_eq!(super::super::hook_of(param(3), &x), Some((Hook::Joint(3), tau * f64::abs(tau))));
        }
        assert!(JointStiffnessNonlinear.needs_torques());
        assert_eq!(
            JointStiffnessNonlinear.prerequisites(&spec(3)),
            vec![EffectSpec::JointCompliance { joint: 3 }]
        );
    }
}
