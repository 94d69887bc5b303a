//! What discovery needs to know about each catalog effect beyond its kinematics: the variable
//! that drives it (for the "where" analysis and the plots), a one-line physical meaning, and
//! the range of physically plausible values. Each effect says these things in its own module
//! of `vatcal_core::effects` (`ErrorEffect::driver`, `meaning`, `bound`); this module
//! translates them for discovery.

use vatcal_core::ParamId;
use vatcal_core::effects::{EffectDriver, EffectKind, EffectSpec};

use crate::location::Driver;

/// The variable whose residual plot shows the effect best, on the canonical cell.
pub fn driver_of(spec: &EffectSpec) -> Driver {
    driver_of_in(spec, 1, 7)
}

/// The variable whose residual plot shows the effect best on a chain of `n` joints whose guide
/// effects act on joint `guide` (its first prismatic joint).
pub fn driver_of_in(spec: &EffectSpec, guide: u8, n: u8) -> Driver {
    match spec.effect().map(|e| e.driver(spec, guide, n)) {
        Some(EffectDriver::Torque(j)) => Driver::Torque(j),
        Some(EffectDriver::Joint(j)) => Driver::Joint(j),
        Some(EffectDriver::Direction(j)) => Driver::Direction(j),
        Some(EffectDriver::Tcp) => Driver::Tcp,
        Some(EffectDriver::Position) => Driver::Position,
        Some(EffectDriver::Time) => Driver::Time,
        Some(EffectDriver::Temperature) => Driver::Temperature,
        None => Driver::Order,
    }
}

/// One sentence on what the effect is physically.
pub fn meaning(kind: EffectKind) -> &'static str {
    kind.effect().map_or("", |e| e.meaning())
}

/// Checks identified values of an effect's parameters: `changes` holds (parameter, identified
/// value − value before the effect was added) in internal units. Returns why it is implausible.
pub fn plausibility(spec: &EffectSpec, changes: &[(ParamId, f64)]) -> Result<(), String> {
    vatcal_core::effects::plausibility(spec, changes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::params::{EffectParam, ToolFrameDof};

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
