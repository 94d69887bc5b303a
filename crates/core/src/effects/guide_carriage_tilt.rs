//! `guide-carriage-tilt`: the guide carriage tilts under the moving weight of the arm. After
//! the guide joint's frame g: `Rx(k_x M_x) Ry(k_y M_y)`, `M` the gravity moment of links
//! g+1..N and the tool about the carriage origin (carriage axes, undeflected geometry;
//! parameters `carriage_tilt_{x,y}` \[rad/(N·m)\]).

use super::guide_angular::check_guide;
use super::{ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook};
use crate::cell::EffectEntry;
use crate::params::{Axis, EffectParam, ParamId, ParamUnit};

/// The `guide-carriage-tilt` effect.
#[derive(Debug, Clone, Copy)]
pub struct GuideCarriageTilt;

impl ErrorEffect for GuideCarriageTilt {
    fn kind(&self) -> EffectKind {
        EffectKind::GuideCarriageTilt
    }
    fn name(&self) -> &'static str {
        "guide-carriage-tilt"
    }
    fn meaning(&self) -> &'static str {
        "the guide carriage tilts under the moving weight of the arm (angle proportional to the gravity moment)"
    }
    fn params(&self, _spec: &EffectSpec) -> Vec<ParamId> {
        [Axis::X, Axis::Y].map(|axis| ParamId::Effect(EffectParam::CarriageTilt { axis })).to_vec()
    }
    fn joint(&self, _spec: &EffectSpec) -> Option<u8> {
        Some(1)
    }
    fn owner(&self, param: &EffectParam) -> Option<EffectSpec> {
        matches!(param, EffectParam::CarriageTilt { axis: Axis::X | Axis::Y })
            .then_some(EffectSpec::GuideCarriageTilt)
    }
    fn param_name(&self, param: &EffectParam) -> String {
        match param {
            EffectParam::CarriageTilt { axis } => format!("carriage_tilt_{}", axis.letter()),
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let s = name.strip_prefix("carriage_tilt_")?;
        [Axis::X, Axis::Y]
            .into_iter()
            .find(|a| a.letter() == s)
            .map(|axis| EffectParam::CarriageTilt { axis })
    }
    fn param_unit(&self, _param: &EffectParam) -> ParamUnit {
        ParamUnit::RadPerNm
    }
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        Some((1e-3, "1e-3 rad/(N*m)"))
    }
    fn read_entry(&self, _entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::GuideCarriageTilt)
    }
    fn check(&self, _spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        check_guide(chain)
    }
    fn candidates(&self, chain: &ChainInfo<'_>, _data: &DataUse, _joint: Option<u8>) -> Vec<EffectSpec> {
        chain.guide.map(|_| EffectSpec::GuideCarriageTilt).into_iter().collect()
    }
    fn driver(&self, _spec: &EffectSpec, guide: u8, n: u8) -> EffectDriver {
        // the moment about the carriage is dominated by the shoulder load (J2 of the Meca500
        // on the canonical cell: the second joint after the guide)
        EffectDriver::Torque((guide + 2).min(n))
    }
    fn needs_carriage_moment(&self) -> bool {
        true
    }
    fn contributions(
        &self,
        _spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let m = x.carriage_moment;
        add(EffectParam::CarriageTilt { axis: Axis::X }, Hook::GuideRotation(Axis::X), m[0]);
        add(EffectParam::CarriageTilt { axis: Axis::Y }, Hook::GuideRotation(Axis::Y), m[1]);
    }
}
