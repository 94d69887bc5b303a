//! `guide-angular`: the carriage pitches/yaws/rolls along the guide. After the guide joint's
//! frame g: `Rx(e_x(u)) Ry(e_y(u)) Rz(e_z(u))`, `e(u) = Σ_o e_o P_o(u)` for orders 1..=`order`
//! (parameters `guide_angular_{x,y,z}_p{o}` \[rad\]), `u` the guide position normalised to
//! [-1, 1] over its limits and `P_o` the Legendre polynomials.

use super::{
    ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook, legendre,
};
use crate::cell::EffectEntry;
use crate::params::{Axis, EffectParam, ParamId, ParamUnit};

/// The `guide-angular` effect.
#[derive(Debug, Clone, Copy)]
pub struct GuideAngular;

fn order_of(spec: &EffectSpec) -> u8 {
    match *spec {
        EffectSpec::GuideAngular { order } => order,
        _ => 0,
    }
}

/// `axis` and order `o` of a `{x,y,z}_p{o}` suffix (o >= 1).
pub(crate) fn axis_order(s: &str) -> Option<(Axis, u8)> {
    let (ax, p) = s.split_once("_p")?;
    let axis = Axis::ALL.into_iter().find(|a| a.letter() == ax)?;
    Some((axis, p.parse().ok().filter(|o| *o >= 1)?))
}

/// The guide-effect chain check (shared by the four guide effects).
pub(crate) fn check_guide(chain: &ChainInfo<'_>) -> Result<(), String> {
    match chain.guide {
        Some(_) => Ok(()),
        None => Err(format!(
            "guide effects act on a prismatic joint, and this chain of {} has none",
            chain.describe()
        )),
    }
}

impl ErrorEffect for GuideAngular {
    fn kind(&self) -> EffectKind {
        EffectKind::GuideAngular
    }
    fn name(&self) -> &'static str {
        "guide-angular"
    }
    fn meaning(&self) -> &'static str {
        "the carriage pitches/yaws/rolls along the guide (error grows with distance from the carriage)"
    }
    fn single_instance(&self) -> bool {
        true
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        (1..=order_of(spec))
            .flat_map(|o| Axis::ALL.map(|axis| ParamId::Effect(EffectParam::GuideAngular { axis, order: o })))
            .collect()
    }
    fn label(&self, spec: &EffectSpec) -> String {
        format!("{} (orders up to {})", self.name(), order_of(spec))
    }
    fn joint(&self, _spec: &EffectSpec) -> Option<u8> {
        Some(1)
    }
    fn owner(&self, param: &EffectParam) -> Option<EffectSpec> {
        match *param {
            EffectParam::GuideAngular { order, .. } => Some(EffectSpec::GuideAngular { order }),
            _ => None,
        }
    }
    fn param_name(&self, param: &EffectParam) -> String {
        match param {
            EffectParam::GuideAngular { axis, order } => format!("guide_angular_{}_p{order}", axis.letter()),
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let (axis, order) = axis_order(name.strip_prefix("guide_angular_")?)?;
        Some(EffectParam::GuideAngular { axis, order })
    }
    fn param_unit(&self, _param: &EffectParam) -> ParamUnit {
        ParamUnit::Rad
    }
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        Some((2e-3, "2 mrad"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::GuideAngular { order: entry.order.unwrap_or(2) })
    }
    fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        entry.order = Some(order_of(spec));
    }
    fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        check_guide(chain)?;
        if (1..=4).contains(&order_of(spec)) { Ok(()) } else { Err("order must be 1..=4".to_string()) }
    }
    fn candidates(&self, chain: &ChainInfo<'_>, _data: &DataUse, _joint: Option<u8>) -> Vec<EffectSpec> {
        chain.guide.map(|_| EffectSpec::GuideAngular { order: 2 }).into_iter().collect()
    }
    fn also_try(&self, candidate: &EffectSpec) -> Vec<EffectSpec> {
        (1..order_of(candidate)).map(|o| EffectSpec::GuideAngular { order: o }).collect()
    }
    fn driver(&self, _spec: &EffectSpec, guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Joint(guide)
    }
    fn contributions(
        &self,
        spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        for o in 1..=order_of(spec) {
            let p = legendre(o, x.guide_u);
            for axis in Axis::ALL {
                add(EffectParam::GuideAngular { axis, order: o }, Hook::GuideRotation(axis), p);
            }
        }
    }
}
