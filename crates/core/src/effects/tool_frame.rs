//! `tool-frame`: the tool changer sits offset/tilted on the flange. Tool-changer frame =
//! frame N · `T(tx, ty, 0) Rx(rx) Ry(ry)` (parameters `tool_tx`, `tool_ty` \[mm\], `tool_rx`,
//! `tool_ry` \[rad\]).

use super::{ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook};
use crate::cell::EffectEntry;
use crate::params::{Axis, EffectParam, ParamId, ParamUnit, ToolFrameDof};

/// The `tool-frame` effect.
#[derive(Debug, Clone, Copy)]
pub struct ToolFrame;

impl ErrorEffect for ToolFrame {
    fn kind(&self) -> EffectKind {
        EffectKind::ToolFrame
    }
    fn name(&self) -> &'static str {
        "tool-frame"
    }
    fn meaning(&self) -> &'static str {
        "the tool changer sits offset/tilted on the flange"
    }
    fn params(&self, _spec: &EffectSpec) -> Vec<ParamId> {
        ToolFrameDof::ALL.iter().map(|d| ParamId::Effect(EffectParam::ToolFrame(*d))).collect()
    }
    fn owner(&self, param: &EffectParam) -> Option<EffectSpec> {
        matches!(param, EffectParam::ToolFrame(_)).then_some(EffectSpec::ToolFrame)
    }
    fn param_name(&self, param: &EffectParam) -> String {
        match param {
            EffectParam::ToolFrame(d) => format!("tool_{}", d.suffix()),
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let s = name.strip_prefix("tool_")?;
        ToolFrameDof::ALL.iter().find(|d| d.suffix() == s).map(|d| EffectParam::ToolFrame(*d))
    }
    fn param_unit(&self, param: &EffectParam) -> ParamUnit {
        match param {
            EffectParam::ToolFrame(ToolFrameDof::Rx | ToolFrameDof::Ry) => ParamUnit::Rad,
            _ => ParamUnit::Mm,
        }
    }
    fn bound(&self, param: &ParamId) -> Option<(f64, &'static str)> {
        match param {
            ParamId::Effect(EffectParam::ToolFrame(ToolFrameDof::Tx | ToolFrameDof::Ty)) => {
                Some((1.0, "1 mm"))
            }
            _ => Some((1.0f64.to_radians(), "1 deg")),
        }
    }
    fn read_entry(&self, _entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::ToolFrame)
    }
    fn check(&self, _spec: &EffectSpec, _chain: &ChainInfo<'_>) -> Result<(), String> {
        Ok(())
    }
    fn candidates(&self, _chain: &ChainInfo<'_>, _data: &DataUse, _joint: Option<u8>) -> Vec<EffectSpec> {
        vec![EffectSpec::ToolFrame]
    }
    fn driver(&self, _spec: &EffectSpec, _guide: u8, n: u8) -> EffectDriver {
        EffectDriver::Joint(n)
    }
    fn contributions(
        &self,
        _spec: &EffectSpec,
        _x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        add(EffectParam::ToolFrame(ToolFrameDof::Tx), Hook::ToolShift(Axis::X), 1.0);
        add(EffectParam::ToolFrame(ToolFrameDof::Ty), Hook::ToolShift(Axis::Y), 1.0);
        add(EffectParam::ToolFrame(ToolFrameDof::Rx), Hook::ToolRotation(Axis::X), 1.0);
        add(EffectParam::ToolFrame(ToolFrameDof::Ry), Hook::ToolRotation(Axis::Y), 1.0);
    }
}
