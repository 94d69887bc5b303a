//! `tcp-offset`: the CMM coordinates of one TCP are wrong. Its parameters are the built-in
//! TCP coordinates `tcp{k}_{x,y,z}` \[mm\].

use super::{ChainInfo, DataUse, EffectDriver, EffectKind, EffectSpec, ErrorEffect};
use crate::cell::EffectEntry;
use crate::params::{Axis, ParamId};

/// The `tcp-offset` effect.
#[derive(Debug, Clone, Copy)]
pub struct TcpOffset;

fn tcp_of(spec: &EffectSpec) -> u32 {
    match *spec {
        EffectSpec::TcpOffset { tcp } => tcp,
        _ => 0,
    }
}

impl ErrorEffect for TcpOffset {
    fn kind(&self) -> EffectKind {
        EffectKind::TcpOffset
    }
    fn name(&self) -> &'static str {
        "tcp-offset"
    }
    fn meaning(&self) -> &'static str {
        "the CMM coordinates of one calibration ball are wrong"
    }
    fn is_builtin(&self) -> bool {
        true
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        let id = tcp_of(spec);
        Axis::ALL.iter().map(|a| ParamId::Tcp { id, axis: *a }).collect()
    }
    fn label(&self, spec: &EffectSpec) -> String {
        format!("tcp-offset (TCP {})", tcp_of(spec))
    }
    fn bound(&self, param: &ParamId) -> Option<(f64, &'static str)> {
        // offsets relative to the nominal coordinates are checked by the caller
        matches!(param, ParamId::Tcp { .. }).then_some((1.0, "1 mm"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::TcpOffset { tcp: entry.tcp.ok_or("needs `tcp`")? })
    }
    fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        entry.tcp = Some(tcp_of(spec));
    }
    fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        if chain.tcps.contains(&tcp_of(spec)) { Ok(()) } else { Err("unknown TCP id".to_string()) }
    }
    fn candidates(&self, _chain: &ChainInfo<'_>, data: &DataUse, _joint: Option<u8>) -> Vec<EffectSpec> {
        data.tcps.iter().map(|&tcp| EffectSpec::TcpOffset { tcp }).collect()
    }
    fn driver(&self, _spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Tcp
    }
}
