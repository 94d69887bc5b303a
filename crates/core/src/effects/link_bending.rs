//! `link-bending`: a link tilts about the two axes perpendicular to its joint axis in
//! proportion to the gravity **bending moment** its joint carries — the tilt stiffness of the
//! joint's bearings and the bending of the link, which the torsion-only `joint-compliance`
//! (`theta_i += c_i tau_i`) leaves out. After frame i: `Rx(k_x M_x) Ry(k_y M_y)`, `M` the
//! moment of gravity on everything distal to joint i about the origin of frame i, along frame
//! i's x and y axes, on the undeflected geometry (`M_z` is the torque `tau_i`); parameters
//! `bend{i}_x`, `bend{i}_y` \[rad/(N·m)\].
//!
//! The bending moment comes from the part of the distal weight that is out of the plane of
//! the joint axis (lateral link offsets, the tool's centre of mass): an arm whose links all lie
//! in the plane of its pitch axes carries none about those axes, and the effect there only
//! acts through the wrist's and tool's lateral offsets. When the joints before i keep gravity
//! fixed in frame i − 1 (vertical axes, a vertical guide), equal compliances about x and y tilt
//! frame i by a constant angle in frame i − 1 — a constant joint-axis misalignment that the
//! geometric parameters absorb; only their difference and the pose-dependent part of the
//! lever are then observable (discovery's refit handles the near-equivalence).

use super::{
    EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook, PerJoint, joint_param,
};
use crate::params::{Axis, EffectParam, ParamId, ParamUnit};

/// This effect's id among the extensions.
pub const ID: u8 = 2;
const KIND: EffectKind = EffectKind::Extension(ID);

/// Largest plausible tilt of a link under its gravity bending moment \[rad\] (0.25°): the
/// chain-scaled bound of a compliance is this tilt at the joint's largest bending moment on
/// the data (`crate::canonical::bounds`).
pub const MAX_TILT_RAD: f64 = 0.25 * std::f64::consts::PI / 180.0;

/// The `link-bending` effect.
#[derive(Debug, Clone, Copy)]
pub struct LinkBending;

/// The instance on joint `joint`.
pub fn spec(joint: u8) -> EffectSpec {
    EffectSpec::Extension { kind: KIND, joint, index: 0 }
}

/// The compliance about frame `joint`'s x (`Axis::X`) or y axis.
pub fn param(joint: u8, axis: Axis) -> EffectParam {
    EffectParam::Extension { kind: KIND, joint, index: 0, slot: u8::from(axis == Axis::Y) }
}

fn axis_of(slot: u8) -> Axis {
    if slot == 0 { Axis::X } else { Axis::Y }
}

/// Its instances: one per revolute joint.
const INSTANCES: PerJoint = PerJoint {
    spec,
    joint_of: |s| match *s {
        EffectSpec::Extension { joint, .. } => joint,
        _ => 0,
    },
};

impl ErrorEffect for LinkBending {
    per_joint!(instances: INSTANCES);

    fn kind(&self) -> EffectKind {
        KIND
    }
    fn name(&self) -> &'static str {
        "link-bending"
    }
    fn meaning(&self) -> &'static str {
        "the link tilts about the axes perpendicular to its joint axis under the gravity bending moment the joint carries (bearing tilt stiffness, link bending)"
    }
    fn params(&self, s: &EffectSpec) -> Vec<ParamId> {
        let joint = INSTANCES.joint(s);
        [Axis::X, Axis::Y].map(|a| ParamId::Effect(param(joint, a))).to_vec()
    }
    fn owner(&self, p: &EffectParam) -> Option<EffectSpec> {
        match *p {
            EffectParam::Extension { kind: KIND, joint, index: 0, slot: 0 | 1 } => Some(spec(joint)),
            _ => None,
        }
    }
    fn param_name(&self, p: &EffectParam) -> String {
        match *p {
            EffectParam::Extension { kind: KIND, joint, slot, .. } => {
                format!("bend{joint}_{}", axis_of(slot).letter())
            }
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let (j, axis) = name.strip_prefix("bend")?.split_once('_')?;
        let joint = joint_param(j, "")?;
        let axis = [Axis::X, Axis::Y].into_iter().find(|a| a.letter() == axis)?;
        Some(param(joint, axis))
    }
    fn param_unit(&self, _p: &EffectParam) -> ParamUnit {
        ParamUnit::RadPerNm
    }
    fn bound(&self, _p: &ParamId) -> Option<(f64, &'static str)> {
        Some((1e-3, "1e-3 rad/(N*m)"))
    }
    fn driver(&self, s: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        // the gravity load of the joint (its bending moment has no column of its own)
        EffectDriver::Torque(INSTANCES.joint(s))
    }
    fn needs_link_moments(&self) -> bool {
        true
    }
    fn contributions(
        &self,
        s: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let joint = INSTANCES.joint(s);
        let m = x.link_moments.get(joint as usize - 1).copied().unwrap_or([0.0; 2]);
        for (axis, mk) in [(Axis::X, m[0]), (Axis::Y, m[1])] {
            add(param(joint, axis), Hook::LinkRotation { joint, axis }, mk);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::MAX_JOINTS;

    #[test]
    fn names_round_trip_and_the_hooks_carry_the_bending_moment() {
        let s = spec(3);
        assert_eq!(s.label(), "link-bending (joint 3)");
        let names: Vec<String> = s.params().iter().map(ParamId::name).collect();
        assert_eq!(names, ["bend3_x", "bend3_y"]);
        for p in s.params() {
            assert_eq!(ParamId::from_name(&p.name()), Some(p));
            assert_eq!(p.unit(), ParamUnit::RadPerNm);
        }
        assert!(ParamId::from_name("bend3_z").is_none() && ParamId::from_name("bend13_x").is_none());
        let q = [0.0; 7];
        let ctx = crate::measurement::MeasurementContext::default();
        let mut link_moments = [[0.0; 2]; MAX_JOINTS];
        link_moments[2] = [0.4, -1.5];
        let x = EffectInputs { guide: Some(1), link_moments, ..EffectInputs::at(&q, &ctx) };
        assert_eq!(
            super::super::hook_of(param(3, Axis::Y), &x),
            Some((Hook::LinkRotation { joint: 3, axis: Axis::Y }, -1.5))
        );
        assert_eq!(
            super::super::hook_of(param(3, Axis::X), &x),
            Some((Hook::LinkRotation { joint: 3, axis: Axis::X }, 0.4))
        );
    }
}
