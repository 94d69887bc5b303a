//! Plausibility bounds of the effect parameters: the canonical cell's, and how they scale to
//! another chain.
//!
//! Each effect's file (`crate::effects`) states the largest plausible magnitude of its
//! parameters for the canonical cell (a Meca500 on a 300 mm guide: [`crate::effects::bound_of`]).
//! Sized for a small arm, some of them refuse what another robot plausibly has: a wrist joint
//! of a large arm carries a gravity torque of a few tenths of N·m, so a compliance that
//! deflects it by a fraction of a degree is far above `1e-2 rad/(N·m)`, and a lost motion
//! that moves the TCP by a millimetre at a short lever arm is more than 0.5°. The bounds
//! therefore also hold in the units that carry over between robots:
//!
//! * **compliance** `c_j`: the deflection at the joint's largest gravity torque on the data,
//!   `c_j · max|τ_j| ≤` [`COMPLIANCE_DEFLECTION_RAD`] (1°);
//! * **joint angle errors** (gear harmonics, the two-turn `joint-cyclic-half` terms,
//!   backlash): the TCP displacement at the joint's
//!   largest lever arm on the data, `|a| · max‖∂p/∂θ_j‖ ≤` [`JOINT_ERROR_DISPLACEMENT_MM`]
//!   (3 mm);
//! * **non-linear stiffness** `compliance_quadratic{j}`: the extra deflection at the joint's
//!   largest gravity torque, `|c2_j| · max|τ_j|² ≤` [`COMPLIANCE_DEFLECTION_RAD`] (1°);
//! * **link-bending compliances** `bend{j}_{x,y}`: the tilt at the joint's largest gravity
//!   bending moment on the data, `|k| · max‖M_⊥,j‖ ≤` [`link_bending::MAX_TILT_RAD`] (0.25°);
//!
//! and the bound used is the larger of the canonical one and the scaled one
//! ([`scaled_bound`]), so the canonical cell keeps its bounds where its own joints are
//! concerned. Every other parameter keeps the canonical bound. A user overrides any effect's
//! bound (`vatcal discover --bound NAME=VALUE`, or the cell file's `[plausibility_bounds]`
//! table).

use crate::effects::{EffectKind, joint_cyclic_half, joint_stiffness_nonlinear, link_bending};
use crate::params::{EffectParam, ParamId};
use crate::units::MAX_JOINTS;

/// Largest plausible gravity deflection of a joint \[rad\] (1°).
pub const COMPLIANCE_DEFLECTION_RAD: f64 = 1.0 * std::f64::consts::PI / 180.0;

/// Largest plausible TCP displacement caused by one joint's angle error (a gear harmonic, the
/// lost motion) \[mm\].
pub const JOINT_ERROR_DISPLACEMENT_MM: f64 = 3.0;

/// The size of a chain as the data see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainScale {
    /// largest |gravity torque| of each joint over the poses [N·m], `[j - 1]` for joint j
    pub max_torque_nm: [f64; MAX_JOINTS],
    /// largest lever arm `‖∂p/∂θ_j‖` of each revolute joint over the poses [mm/rad]
    pub max_lever_mm: [f64; MAX_JOINTS],
    /// largest gravity bending moment `‖(M_x, M_y)‖` of each joint over the poses [N·m]
    /// (`vatcal_kinematics::Model::link_bending_moments`)
    pub max_bending_nm: [f64; MAX_JOINTS],
}

/// A bound in internal units and how it came about, for people.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaledBound {
    /// the bound (internal units)
    pub value: f64,
    /// its text with unit and origin, e.g. `1.2e-1 rad/(N*m) (scaled to the chain: 1 deg at
    /// the joint's largest gravity torque 0.15 N*m)`
    pub text: String,
}

/// The bound of `id` on a chain of scale `scale`: the larger of the canonical bound
/// (`canonical`, `canonical_text`) and the scaled one (module docs). `None` when the
/// parameter has no canonical bound.
pub fn scaled_bound(id: &ParamId, canonical: Option<(f64, &str)>, scale: &ChainScale) -> Option<ScaledBound> {
    let (value, text) = canonical?;
    let joint = |j: u8| (j as usize).checked_sub(1).filter(|k| *k < MAX_JOINTS);
    let scaled = match id {
        ParamId::Compliance(j) => joint(*j).and_then(|k| {
            let tau = scale.max_torque_nm[k];
            (tau > 0.0).then(|| {
                (
                    COMPLIANCE_DEFLECTION_RAD / tau,
                    format!(
                        "rad/(N*m) (scaled to the chain: {:.1} deg deflection at the joint's largest gravity torque {tau:.3} N*m)",
                        COMPLIANCE_DEFLECTION_RAD.to_degrees()
                    ),
                )
            })
        }),
        ParamId::Effect(
            EffectParam::CyclicSin { joint: j, .. }
            | EffectParam::CyclicCos { joint: j, .. }
            | EffectParam::Backlash { joint: j }
            | EffectParam::Extension { kind: EffectKind::Extension(joint_cyclic_half::ID), joint: j, .. },
        ) => joint(*j).and_then(|k| {
            let lever = scale.max_lever_mm[k];
            (lever > 0.0).then(|| {
                let b = JOINT_ERROR_DISPLACEMENT_MM / lever;
                (
                    b,
                    format!(
                        "deg (scaled to the chain: {JOINT_ERROR_DISPLACEMENT_MM} mm at the joint's largest lever arm {lever:.0} mm)"
                    ),
                )
            })
        }),
        ParamId::Effect(EffectParam::Extension {
            kind: EffectKind::Extension(joint_stiffness_nonlinear::ID), joint: j, ..
        }) => joint(*j).and_then(|k| {
            let tau = scale.max_torque_nm[k];
            (tau > 0.0).then(|| {
                (
                    COMPLIANCE_DEFLECTION_RAD / (tau * tau),
                    format!(
                        "rad/(N*m)^2 (scaled to the chain: {:.1} deg deflection at the joint's largest gravity torque {tau:.3} N*m)",
                        COMPLIANCE_DEFLECTION_RAD.to_degrees()
                    ),
                )
            })
        }),
        ParamId::Effect(EffectParam::Extension {
            kind: EffectKind::Extension(link_bending::ID), joint: j, ..
        }) => joint(*j).and_then(|k| {
            let m = scale.max_bending_nm[k];
            (m > 0.0).then(|| {
                (
                    link_bending::MAX_TILT_RAD / m,
                    format!(
                        "rad/(N*m) (scaled to the chain: {:.2} deg tilt at the joint's largest bending moment {m:.3} N*m)",
                        link_bending::MAX_TILT_RAD.to_degrees()
                    ),
                )
            })
        }),
        _ => None,
    };
    Some(match scaled {
        Some((b, unit_text)) if b > value => {
            let shown = if unit_text.starts_with("deg") { b.to_degrees() } else { b };
            ScaledBound { value: b, text: format!("{shown:.3e} {unit_text}") }
        }
        _ => ScaledBound { value, text: text.to_string() },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_grow_for_light_wrists_and_short_levers_and_never_shrink() {
        let mut scale = ChainScale {
            max_torque_nm: [0.0; MAX_JOINTS],
            max_lever_mm: [0.0; MAX_JOINTS],
            max_bending_nm: [0.0; MAX_JOINTS],
        };
        scale.max_torque_nm[6] = 0.3; // a wrist: 1 deg / 0.3 N·m = 5.8e-2
        scale.max_torque_nm[2] = 20.0; // a shoulder: 8.7e-4 < the canonical 1e-2
        scale.max_lever_mm[6] = 150.0; // 3 mm / 150 mm = 1.15 deg
        scale.max_lever_mm[2] = 600.0; // 0.29 deg < 0.5 deg
        let c7 =
            scaled_bound(&ParamId::Compliance(7), Some((1e-2, "1e-2 rad/(N*m)")), &scale).expect("bound");
        assert!(
            (c7.value - COMPLIANCE_DEFLECTION_RAD / 0.3).abs() < 1e-12 && c7.text.contains("scaled"),
            "{c7:?}"
        );
        let c3 =
            scaled_bound(&ParamId::Compliance(3), Some((1e-2, "1e-2 rad/(N*m)")), &scale).expect("bound");
        assert_eq!(c3, ScaledBound { value: 1e-2, text: "1e-2 rad/(N*m)".into() });
        let half = 0.5f64.to_radians();
        let b7 = scaled_bound(
            &ParamId::Effect(EffectParam::Backlash { joint: 7 }),
            Some((half, "0.5 deg")),
            &scale,
        )
        .expect("bound");
        assert!((b7.value.to_degrees() - 3.0 / 150.0 * 180.0 / std::f64::consts::PI).abs() < 1e-9, "{b7:?}");
        assert!(b7.text.starts_with("1.146e0 deg"), "{}", b7.text);
        let b3 = scaled_bound(
            &ParamId::Effect(EffectParam::Backlash { joint: 3 }),
            Some((half, "0.5 deg")),
            &scale,
        )
        .expect("bound");
        assert_eq!(b3.value, half);
        assert!(scaled_bound(&ParamId::Compliance(7), None, &scale).is_none());
        // the two-turn cyclic terms scale like the gear harmonics
        let h7 = scaled_bound(
            &ParamId::Effect(joint_cyclic_half::param(7, 3, 0)),
            Some((half, "0.5 deg")),
            &scale,
        )
        .expect("bound");
        assert_eq!(h7.value, b7.value);
        let h3 = scaled_bound(
            &ParamId::Effect(joint_cyclic_half::param(3, 3, 1)),
            Some((half, "0.5 deg")),
            &scale,
        )
        .expect("bound");
        assert_eq!(h3.value, half);
        // a link-bending compliance: 0.25 deg at the joint's largest bending moment
        scale.max_bending_nm[2] = 0.05; // a light, nearly planar arm: 8.7e-2 rad/(N*m)
        scale.max_bending_nm[3] = 40.0; // a heavy arm: 1.1e-4 < the canonical 1e-3
        let bend = |j| ParamId::Effect(link_bending::param(j, crate::params::Axis::X));
        let k3 = scaled_bound(&bend(3), Some((1e-3, "1e-3 rad/(N*m)")), &scale).expect("bound");
        assert!((k3.value - link_bending::MAX_TILT_RAD / 0.05).abs() < 1e-12, "{k3:?}");
        assert!(k3.text.contains("bending moment 0.050 N*m"), "{}", k3.text);
        let k4 = scaled_bound(&bend(4), Some((1e-3, "1e-3 rad/(N*m)")), &scale).expect("bound");
        assert_eq!(k4.value, 1e-3);
    }
}
