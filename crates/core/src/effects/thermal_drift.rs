//! `thermal-drift`: the arm grows or shrinks. The lengths `a_{i-1}`, `d_i` of the revolute
//! rows (2..7 on the canonical cell) scale by `1 + k v`, v = `time_s` (parameter
//! `thermal_per_s` \[1/s\]) or `temperature_c - T_ref` (parameter `thermal_per_k` \[1/K\]).

use super::{
    ChainInfo, DataAvailability, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect,
    Hook, ThermalDriver,
};
use crate::cell::EffectEntry;
use crate::params::{EffectParam, ParamId, ParamUnit};

/// The `thermal-drift` effect.
#[derive(Debug, Clone, Copy)]
pub struct ThermalDrift;

fn driver_of(spec: &EffectSpec) -> ThermalDriver {
    match *spec {
        EffectSpec::ThermalDrift { driver } => driver,
        _ => ThermalDriver::Time,
    }
}

fn param_of(driver: ThermalDriver) -> EffectParam {
    match driver {
        ThermalDriver::Time => EffectParam::ThermalPerSecond,
        ThermalDriver::Temperature => EffectParam::ThermalPerKelvin,
    }
}

impl ErrorEffect for ThermalDrift {
    fn kind(&self) -> EffectKind {
        EffectKind::ThermalDrift
    }
    fn name(&self) -> &'static str {
        "thermal-drift"
    }
    fn meaning(&self) -> &'static str {
        "the arm grows or shrinks with time or temperature"
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        vec![ParamId::Effect(param_of(driver_of(spec)))]
    }
    fn label(&self, spec: &EffectSpec) -> String {
        format!(
            "thermal-drift ({})",
            match driver_of(spec) {
                ThermalDriver::Time => "time",
                ThermalDriver::Temperature => "temperature",
            }
        )
    }
    fn owner(&self, param: &EffectParam) -> Option<EffectSpec> {
        match param {
            EffectParam::ThermalPerSecond => Some(EffectSpec::ThermalDrift { driver: ThermalDriver::Time }),
            EffectParam::ThermalPerKelvin => {
                Some(EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature })
            }
            _ => None,
        }
    }
    fn param_name(&self, param: &EffectParam) -> String {
        match param {
            EffectParam::ThermalPerKelvin => "thermal_per_k",
            _ => "thermal_per_s",
        }
        .to_string()
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        match name {
            "thermal_per_s" => Some(EffectParam::ThermalPerSecond),
            "thermal_per_k" => Some(EffectParam::ThermalPerKelvin),
            _ => None,
        }
    }
    fn param_unit(&self, param: &EffectParam) -> ParamUnit {
        match param {
            EffectParam::ThermalPerKelvin => ParamUnit::PerKelvin,
            _ => ParamUnit::PerSecond,
        }
    }
    fn bound(&self, param: &ParamId) -> Option<(f64, &'static str)> {
        match param {
            ParamId::Effect(EffectParam::ThermalPerKelvin) => Some((1e-4, "1e-4 /K")),
            _ => Some((1e-7, "1e-7 /s")),
        }
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::ThermalDrift {
            driver: match entry.driver.as_deref() {
                Some("time") | None => ThermalDriver::Time,
                Some("temperature") => ThermalDriver::Temperature,
                Some(o) => return Err(format!("driver must be `time` or `temperature`, got `{o}`")),
            },
        })
    }
    fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry, thermal_reference_c: f64) {
        let driver = driver_of(spec);
        entry.driver = Some(
            match driver {
                ThermalDriver::Time => "time",
                ThermalDriver::Temperature => "temperature",
            }
            .to_string(),
        );
        if driver == ThermalDriver::Temperature {
            entry.reference_temperature_c = Some(thermal_reference_c);
        }
    }
    fn check(&self, _spec: &EffectSpec, _chain: &ChainInfo<'_>) -> Result<(), String> {
        Ok(())
    }
    fn candidates(&self, _chain: &ChainInfo<'_>, _data: &DataUse, _joint: Option<u8>) -> Vec<EffectSpec> {
        vec![
            EffectSpec::ThermalDrift { driver: ThermalDriver::Time },
            EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature },
        ]
    }
    fn data_columns(&self, spec: &EffectSpec) -> &'static [&'static str] {
        match driver_of(spec) {
            ThermalDriver::Time => &["time_s"],
            ThermalDriver::Temperature => &["temperature_c"],
        }
    }
    fn missing_data(&self, spec: &EffectSpec, data: &DataAvailability) -> Option<&'static str> {
        match driver_of(spec) {
            ThermalDriver::Time if !data.time => Some("needs the time_s column"),
            ThermalDriver::Temperature if !data.temperature => Some("needs the temperature_c column"),
            _ => None,
        }
    }
    fn driver(&self, spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        match driver_of(spec) {
            ThermalDriver::Time => EffectDriver::Time,
            ThermalDriver::Temperature => EffectDriver::Temperature,
        }
    }
    fn contributions(
        &self,
        spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let driver = driver_of(spec);
        let v = match driver {
            ThermalDriver::Time => x.ctx.time_s.unwrap_or(0.0),
            ThermalDriver::Temperature => x.ctx.temperature_c.map_or(0.0, |t| t - x.thermal_reference_c),
        };
        add(param_of(driver), Hook::LengthScale, v);
    }
}
