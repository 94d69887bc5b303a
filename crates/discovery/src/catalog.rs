//! What discovery needs to know about each catalog effect beyond its kinematics: the variable
//! that drives it (for the "where" analysis and the plots), a one-line physical meaning, and
//! the range of physically plausible values.

use vatcal_core::ParamId;
use vatcal_core::effects::{EffectKind, EffectSpec, ThermalDriver};
use vatcal_core::params::{EffectParam, ToolFrameDof};

use crate::location::Driver;

/// The variable whose residual plot shows the effect best, on the canonical cell.
pub fn driver_of(spec: &EffectSpec) -> Driver {
    driver_of_in(spec, 1, 7)
}

/// The variable whose residual plot shows the effect best on a chain of `n` joints whose guide
/// effects act on joint `guide` (its first prismatic joint).
pub fn driver_of_in(spec: &EffectSpec, guide: u8, n: u8) -> Driver {
    match *spec {
        EffectSpec::JointCompliance { joint } => Driver::Torque(joint),
        EffectSpec::JointCyclic { joint, .. } | EffectSpec::JointScale { joint } => Driver::Joint(joint),
        EffectSpec::JointBacklash { joint } => Driver::Direction(joint),
        EffectSpec::GuideAngular { .. } | EffectSpec::GuideStraightness { .. } | EffectSpec::GuideScale => {
            Driver::Joint(guide)
        }
        // the moment about the carriage is dominated by the shoulder load (J2 of the Meca500
        // on the canonical cell: the second joint after the guide)
        EffectSpec::GuideCarriageTilt => Driver::Torque((guide + 2).min(n)),
        EffectSpec::ToolFrame => Driver::Joint(n),
        EffectSpec::TcpOffset { .. } => Driver::Tcp,
        EffectSpec::PositionOffset { .. } => Driver::Position,
        EffectSpec::ThermalDrift { driver: ThermalDriver::Time } => Driver::Time,
        EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature } => Driver::Temperature,
        EffectSpec::HayatiBeta { row } => Driver::Joint(row.clamp(2.min(n), n)),
    }
}

/// One sentence on what the effect is physically.
pub fn meaning(kind: EffectKind) -> &'static str {
    match kind {
        EffectKind::JointCompliance => {
            "the joint yields under the gravity load (angle error proportional to the torque)"
        }
        EffectKind::JointCyclic => {
            "periodic transmission error of the joint (strain-wave gear, encoder eccentricity)"
        }
        EffectKind::JointScale => {
            "the joint's gear ratio or encoder scale differs from nominal (error proportional to the angle)"
        }
        EffectKind::JointBacklash => {
            "lost motion: the joint stops short by a fixed angle depending on the approach direction"
        }
        EffectKind::GuideAngular => {
            "the carriage pitches/yaws/rolls along the guide (error grows with distance from the carriage)"
        }
        EffectKind::GuideStraightness => "the carriage path bows sideways along the guide",
        EffectKind::GuideScale => "the guide's lead-screw pitch (or its temperature) differs from nominal",
        EffectKind::GuideCarriageTilt => {
            "the guide carriage tilts under the moving weight of the arm (angle proportional to the gravity moment)"
        }
        EffectKind::ToolFrame => "the tool changer sits offset/tilted on the flange",
        EffectKind::TcpOffset => "the CMM coordinates of one calibration ball are wrong",
        EffectKind::PositionOffset => "the CMM coordinates of one calibration position are wrong",
        EffectKind::ThermalDrift => "the arm grows or shrinks with time or temperature",
        EffectKind::HayatiBeta => {
            "two consecutive joint axes are not exactly as the MDH row assumes (small rotation about y)"
        }
    }
}

/// Largest plausible magnitude of a parameter in internal units, if the catalog bounds it.
fn magnitude_bound(id: ParamId) -> Option<(f64, &'static str)> {
    Some(match id {
        ParamId::Effect(e) => match e {
            EffectParam::CyclicSin { .. } | EffectParam::CyclicCos { .. } => (0.5f64.to_radians(), "0.5 deg"),
            EffectParam::JointScale { .. } => (1e-2, "1 %"),
            EffectParam::Backlash { .. } => (0.5f64.to_radians(), "0.5 deg"),
            EffectParam::GuideAngular { .. } => (2e-3, "2 mrad"),
            EffectParam::GuideStraightness { .. } => (0.5, "0.5 mm"),
            EffectParam::GuideScale => (2e-3, "2000 ppm"),
            EffectParam::CarriageTilt { .. } => (1e-3, "1e-3 rad/(N*m)"),
            EffectParam::ToolFrame(ToolFrameDof::Tx | ToolFrameDof::Ty) => (1.0, "1 mm"),
            EffectParam::ToolFrame(_) => (1.0f64.to_radians(), "1 deg"),
            EffectParam::ThermalPerSecond => (1e-7, "1e-7 /s"),
            EffectParam::ThermalPerKelvin => (1e-4, "1e-4 /K"),
        },
        ParamId::Compliance(_) => (1e-2, "1e-2 rad/(N*m)"),
        ParamId::Beta(_) => (1.0f64.to_radians(), "1 deg"),
        // offsets relative to the nominal coordinates are checked by the caller
        ParamId::Tcp { .. } | ParamId::Position { .. } => (1.0, "1 mm"),
        _ => return None,
    })
}

/// Checks identified values of an effect's parameters: `changes` holds (parameter, identified
/// value − value before the effect was added) in internal units. Returns why it is implausible.
pub fn plausibility(spec: &EffectSpec, changes: &[(ParamId, f64)]) -> Result<(), String> {
    for (id, change) in changes {
        if let (ParamId::Compliance(j), EffectSpec::JointCompliance { .. }) = (id, spec) {
            // the compliance starts at 0 when it is added: the identified value is `change`
            if *change <= 0.0 {
                return Err(format!(
                    "c_{j} came out {change:.3e} rad/(N*m): a joint cannot stiffen under load"
                ));
            }
        }
        if let Some((bound, text)) = magnitude_bound(*id)
            && change.abs() > bound
        {
            return Err(format!("{} changed by {change:.3e}: more than the plausible {text}", id.name()));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plausibility_rejects_negative_compliance_and_large_tilts() {
        let c = EffectSpec::JointCompliance { joint: 3 };
        assert!(plausibility(&c, &[(ParamId::Compliance(3), 2e-4)]).is_ok());
        assert!(plausibility(&c, &[(ParamId::Compliance(3), -2e-4)]).is_err());
        let t = EffectSpec::ToolFrame;
        let rx = ParamId::Effect(EffectParam::ToolFrame(ToolFrameDof::Rx));
        assert!(plausibility(&t, &[(rx, 0.03f64.to_radians())]).is_ok());
        assert!(plausibility(&t, &[(rx, 3f64.to_radians())]).is_err());
    }

    #[test]
    fn every_effect_has_a_driver_and_meaning() {
        for k in EffectKind::ALL {
            assert!(!meaning(k).is_empty());
        }
        assert_eq!(driver_of(&EffectSpec::JointCyclic { joint: 4, harmonic: 1 }), Driver::Joint(4));
        assert_eq!(driver_of(&EffectSpec::JointCompliance { joint: 3 }), Driver::Torque(3));
    }
}
