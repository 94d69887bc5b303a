//! `hayati-beta`: two consecutive joint axes are not exactly as the MDH row assumes: the
//! built-in parameter `beta_{i-1}` \[rad\] of MDH row i (row 4, `beta_3`, is in the paper's set
//! on the canonical cell).

use super::{ChainInfo, DataUse, EffectDriver, EffectKind, EffectSpec, ErrorEffect};
use crate::cell::EffectEntry;
use crate::params::ParamId;

/// The `hayati-beta` effect.
#[derive(Debug, Clone, Copy)]
pub struct HayatiBeta;

fn row_of(spec: &EffectSpec) -> u8 {
    match *spec {
        EffectSpec::HayatiBeta { row } => row,
        _ => 0,
    }
}

impl ErrorEffect for HayatiBeta {
    fn kind(&self) -> EffectKind {
        EffectKind::HayatiBeta
    }
    fn name(&self) -> &'static str {
        "hayati-beta"
    }
    fn meaning(&self) -> &'static str {
        "two consecutive joint axes are not exactly as the MDH row assumes (small rotation about y)"
    }
    fn is_builtin(&self) -> bool {
        true
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        vec![ParamId::Beta(row_of(spec))]
    }
    fn label(&self, spec: &EffectSpec) -> String {
        let row = row_of(spec);
        format!("hayati-beta (row {row}, beta_{})", row.saturating_sub(1))
    }
    fn bound(&self, param: &ParamId) -> Option<(f64, &'static str)> {
        matches!(param, ParamId::Beta(_)).then_some((1.0f64.to_radians(), "1 deg"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::HayatiBeta { row: entry.row.ok_or("needs `row`")? })
    }
    fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        entry.row = Some(row_of(spec));
    }
    fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        if (1..=chain.n()).contains(&(row_of(spec) as usize)) {
            Ok(())
        } else {
            Err(format!("row must be 1..={}", chain.n()))
        }
    }
    fn candidates(&self, chain: &ChainInfo<'_>, _data: &DataUse, _joint: Option<u8>) -> Vec<EffectSpec> {
        (2..=chain.n() as u8)
            .filter(|r| !(chain.canonical && *r == 4))
            .map(|row| EffectSpec::HayatiBeta { row })
            .collect()
    }
    fn driver(&self, spec: &EffectSpec, _guide: u8, n: u8) -> EffectDriver {
        EffectDriver::Joint(row_of(spec).clamp(2.min(n), n))
    }
}
