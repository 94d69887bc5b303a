//! `guide-scale`: the guide's lead-screw pitch differs from nominal, `d_g = (1 + s) q_g +
//! d_offset` on the guide joint g (parameter `guide_scale`).

use super::guide_angular::check_guide;
use super::{ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook};
use crate::cell::EffectEntry;
use crate::params::{EffectParam, ParamId, ParamUnit};

/// The `guide-scale` effect.
#[derive(Debug, Clone, Copy)]
pub struct GuideScale;

impl ErrorEffect for GuideScale {
    fn kind(&self) -> EffectKind {
        EffectKind::GuideScale
    }
    fn name(&self) -> &'static str {
        "guide-scale"
    }
    fn meaning(&self) -> &'static str {
        "the guide's lead-screw pitch (or its temperature) differs from nominal"
    }
    fn params(&self, _spec: &EffectSpec) -> Vec<ParamId> {
        vec![ParamId::Effect(EffectParam::GuideScale)]
    }
    fn joint(&self, _spec: &EffectSpec) -> Option<u8> {
        Some(1)
    }
    fn owner(&self, param: &EffectParam) -> Option<EffectSpec> {
        (*param == EffectParam::GuideScale).then_some(EffectSpec::GuideScale)
    }
    fn param_name(&self, _param: &EffectParam) -> String {
        "guide_scale".to_string()
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        (name == "guide_scale").then_some(EffectParam::GuideScale)
    }
    fn param_unit(&self, _param: &EffectParam) -> ParamUnit {
        ParamUnit::Ratio
    }
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        Some((2e-3, "2000 ppm"))
    }
    fn read_entry(&self, _entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::GuideScale)
    }
    fn check(&self, _spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        check_guide(chain)
    }
    fn candidates(&self, chain: &ChainInfo<'_>, _data: &DataUse, _joint: Option<u8>) -> Vec<EffectSpec> {
        chain.guide.map(|_| EffectSpec::GuideScale).into_iter().collect()
    }
    fn driver(&self, _spec: &EffectSpec, guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Joint(guide)
    }
    fn contributions(
        &self,
        _spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        if let Some(g) = x.guide {
            let qg = x.q.get(g as usize - 1).copied().unwrap_or(0.0);
            add(EffectParam::GuideScale, Hook::Joint(g), qg);
        }
    }
}
