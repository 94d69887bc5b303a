//! `position-offset`: the CMM coordinates of one calibration position are wrong. Its
//! parameters are the built-in position coordinates `position{k}_{x,y,z}` \[mm\].

use super::{ChainInfo, DataUse, EffectDriver, EffectKind, EffectSpec, ErrorEffect};
use crate::cell::EffectEntry;
use crate::params::{Axis, ParamId};

/// The `position-offset` effect.
#[derive(Debug, Clone, Copy)]
pub struct PositionOffset;

fn position_of(spec: &EffectSpec) -> u32 {
    match *spec {
        EffectSpec::PositionOffset { position } => position,
        _ => 0,
    }
}

impl ErrorEffect for PositionOffset {
    fn kind(&self) -> EffectKind {
        EffectKind::PositionOffset
    }
    fn name(&self) -> &'static str {
        "position-offset"
    }
    fn meaning(&self) -> &'static str {
        "the CMM coordinates of one calibration position are wrong"
    }
    fn is_builtin(&self) -> bool {
        true
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        let id = position_of(spec);
        Axis::ALL.iter().map(|a| ParamId::Position { id, axis: *a }).collect()
    }
    fn label(&self, spec: &EffectSpec) -> String {
        format!("position-offset (position {})", position_of(spec))
    }
    fn bound(&self, param: &ParamId) -> Option<(f64, &'static str)> {
        matches!(param, ParamId::Position { .. }).then_some((1.0, "1 mm"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::PositionOffset { position: entry.position.ok_or("needs `position`")? })
    }
    fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        entry.position = Some(position_of(spec));
    }
    fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        if chain.positions.contains(&position_of(spec)) {
            Ok(())
        } else {
            Err("unknown calibration position id".to_string())
        }
    }
    fn candidates(&self, _chain: &ChainInfo<'_>, data: &DataUse, _joint: Option<u8>) -> Vec<EffectSpec> {
        data.positions.iter().map(|&position| EffectSpec::PositionOffset { position }).collect()
    }
    fn driver(&self, _spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Position
    }
}
