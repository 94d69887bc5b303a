//! `joint-thermal-drift`: the zero of a revolute joint drifts with the temperature (or with time
//! during a warm-up): `theta_i += k_i (T − T_ref)` (parameter `thermal{i}_per_k` \[rad/K\]) or
//! `theta_i += k_i t` (`thermal{i}_per_s` \[rad/s\]).
//!
//! The warm-up of a robot moves its joints' zeros as much as it grows its links: the motor and
//! gearbox heat, the encoder's mounting and the gear's preload shift, and the error appears as
//! a joint offset that follows the temperature. `thermal-drift` scales the lengths (the arm
//! grows); this effect is the angular part, one joint at a time.

use super::{
    CandidateScope, ChainInfo, DataAvailability, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec,
    ErrorEffect, Hook, ThermalDriver, entry_joint, joint_param, revolute_joint,
};
use crate::cell::EffectEntry;
use crate::params::{EffectParam, ParamId, ParamUnit};

/// This effect's id among the extensions.
pub const ID: u8 = 4;
const KIND: EffectKind = EffectKind::Extension(ID);

/// The `joint-thermal-drift` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointThermalDrift;

fn index_of(driver: ThermalDriver) -> u8 {
    match driver {
        ThermalDriver::Temperature => 0,
        ThermalDriver::Time => 1,
    }
}

fn driver_of_index(index: u8) -> ThermalDriver {
    if index == 0 { ThermalDriver::Temperature } else { ThermalDriver::Time }
}

/// The instance on joint `joint` driven by `driver`.
pub fn spec(joint: u8, driver: ThermalDriver) -> EffectSpec {
    EffectSpec::Extension { kind: KIND, joint, index: index_of(driver) }
}

/// The parameter of the instance on `joint` driven by `driver`.
pub fn param(joint: u8, driver: ThermalDriver) -> EffectParam {
    EffectParam::Extension { kind: KIND, joint, index: index_of(driver), slot: 0 }
}

fn of(spec: &EffectSpec) -> (u8, ThermalDriver) {
    match *spec {
        EffectSpec::Extension { joint, index, .. } => (joint, driver_of_index(index)),
        _ => (0, ThermalDriver::Temperature),
    }
}

fn driver_name(driver: ThermalDriver) -> &'static str {
    match driver {
        ThermalDriver::Time => "time",
        ThermalDriver::Temperature => "temperature",
    }
}

impl ErrorEffect for JointThermalDrift {
    fn kind(&self) -> EffectKind {
        KIND
    }
    fn name(&self) -> &'static str {
        "joint-thermal-drift"
    }
    fn meaning(&self) -> &'static str {
        "the joint's zero drifts with the temperature or during the warm-up (motor and gearbox heating moves the encoder and gear)"
    }
    fn params(&self, s: &EffectSpec) -> Vec<ParamId> {
        let (joint, driver) = of(s);
        vec![ParamId::Effect(param(joint, driver))]
    }
    fn label(&self, s: &EffectSpec) -> String {
        let (joint, driver) = of(s);
        format!("joint-thermal-drift (joint {joint}, {})", driver_name(driver))
    }
    fn joint(&self, s: &EffectSpec) -> Option<u8> {
        Some(of(s).0)
    }
    fn owner(&self, p: &EffectParam) -> Option<EffectSpec> {
        match *p {
            EffectParam::Extension { kind: KIND, joint, index: index @ (0 | 1), slot: 0 } => {
                Some(spec(joint, driver_of_index(index)))
            }
            _ => None,
        }
    }
    fn param_name(&self, p: &EffectParam) -> String {
        match *p {
            EffectParam::Extension { kind: KIND, joint, index, .. } => match driver_of_index(index) {
                ThermalDriver::Temperature => format!("thermal{joint}_per_k"),
                ThermalDriver::Time => format!("thermal{joint}_per_s"),
            },
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let rest = name.strip_prefix("thermal")?;
        if let Some(j) = rest.strip_suffix("_per_k") {
            return Some(param(joint_param(j, "")?, ThermalDriver::Temperature));
        }
        Some(param(joint_param(rest.strip_suffix("_per_s")?, "")?, ThermalDriver::Time))
    }
    fn param_unit(&self, p: &EffectParam) -> ParamUnit {
        match *p {
            EffectParam::Extension { index: 1, .. } => ParamUnit::PerSecond,
            _ => ParamUnit::PerKelvin,
        }
    }
    fn bound(&self, p: &ParamId) -> Option<(f64, &'static str)> {
        match p {
            // 0.1 deg/K; 0.5 deg over an hour's warm-up
            ParamId::Effect(EffectParam::Extension { index: 1, .. }) => Some((2.4e-6, "2.4e-6 rad/s")),
            _ => Some((1.75e-3, "1.75e-3 rad/K")),
        }
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        let joint = entry_joint(entry)?;
        let driver = match entry.driver.as_deref() {
            Some("temperature") | None => ThermalDriver::Temperature,
            Some("time") => ThermalDriver::Time,
            Some(o) => return Err(format!("driver must be `temperature` or `time`, got `{o}`")),
        };
        Ok(spec(joint, driver))
    }
    fn write_entry(&self, s: &EffectSpec, entry: &mut EffectEntry, thermal_reference_c: f64) {
        let (joint, driver) = of(s);
        entry.joint = Some(joint);
        entry.driver = Some(driver_name(driver).to_string());
        if driver == ThermalDriver::Temperature {
            entry.reference_temperature_c = Some(thermal_reference_c);
        }
    }
    fn check(&self, s: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        revolute_joint(of(s).0, chain)
    }
    fn scope(&self) -> CandidateScope {
        CandidateScope::PerRevoluteJoint
    }
    fn candidates(&self, _chain: &ChainInfo<'_>, _data: &DataUse, joint: Option<u8>) -> Vec<EffectSpec> {
        joint
            .map(|j| vec![spec(j, ThermalDriver::Temperature), spec(j, ThermalDriver::Time)])
            .unwrap_or_default()
    }
    fn data_columns(&self, s: &EffectSpec) -> &'static [&'static str] {
        match of(s).1 {
            ThermalDriver::Time => &["time_s"],
            ThermalDriver::Temperature => &["temperature_c"],
        }
    }
    fn missing_data(&self, s: &EffectSpec, data: &DataAvailability) -> Option<&'static str> {
        match of(s).1 {
            ThermalDriver::Time if !data.time => Some("needs the time_s column"),
            ThermalDriver::Temperature if !data.temperature => Some("needs the temperature_c column"),
            _ => None,
        }
    }
    fn driver(&self, s: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        match of(s).1 {
            ThermalDriver::Time => EffectDriver::Time,
            ThermalDriver::Temperature => EffectDriver::Temperature,
        }
    }
    fn contributions(&self, s: &EffectSpec, x: &EffectInputs<'_>, add: &mut dyn FnMut(EffectParam, Hook, f64)) {
        let (joint, driver) = of(s);
        let v = match driver {
            ThermalDriver::Temperature => x.ctx.temperature_c.map_or(0.0, |t| t - x.thermal_reference_c),
            ThermalDriver::Time => x.ctx.time_s.unwrap_or(0.0),
        };
        add(param(joint, driver), Hook::Joint(joint), v);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::MeasurementContext;

    #[test]
    fn names_entries_and_hooks() {
        for driver in [ThermalDriver::Temperature, ThermalDriver::Time] {
            let s = spec(5, driver);
            for p in s.params() {
                assert_eq!(ParamId::from_name(&p.name()), Some(p), "{}", p.name());
            }
            let mut entry = EffectEntry { effect: "joint-thermal-drift".into(), ..EffectEntry::default() };
            JointThermalDrift.write_entry(&s, &mut entry, 21.0);
            assert_eq!(JointThermalDrift.read_entry(&entry), Ok(s));
        }
        assert_eq!(param(5, ThermalDriver::Temperature), ParamId::from_name("thermal5_per_k").and_then(|p| match p {
            ParamId::Effect(e) => Some(e),
            _ => None,
        }).expect("parses"));
        // thermal-drift's own names stay its own
        assert!(matches!(ParamId::from_name("thermal_per_k"), Some(ParamId::Effect(EffectParam::ThermalPerKelvin))));
        let q = [0.0; 7];
        let ctx = MeasurementContext { temperature_c: Some(23.5), time_s: Some(600.0), ..Default::default() };
        let x = EffectInputs { guide: Some(1), ..EffectInputs::at(&q, &ctx) };
        assert_eq!(super::super::hook_of(param(5, ThermalDriver::Temperature), &x), Some((Hook::Joint(5), 3.5)));
        assert_eq!(super::super::hook_of(param(5, ThermalDriver::Time), &x), Some((Hook::Joint(5), 600.0)));
        let no_temperature = DataAvailability { time: true, ..Default::default() };
        assert!(JointThermalDrift.missing_data(&spec(5, ThermalDriver::Temperature), &no_temperature).is_some());
        assert!(JointThermalDrift.missing_data(&spec(5, ThermalDriver::Time), &no_temperature).is_none());
    }
}
