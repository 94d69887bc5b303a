//! `guide-straightness`: the carriage path bows sideways along the guide. After the guide
//! joint's frame g: `T(s_x(u), s_y(u), 0)`, `s(u) = Σ_o s_o P_o(u)` for orders 2..=`order`
//! (order 1 is a tilted guide, absorbed by the base pose; parameters
//! `guide_straightness_{x,y}_p{o}` \[mm\]).
//!
//! **Order chosen by the data.** A real guide's sideways error is not only a bow: rail
//! waviness, the joints between rail segments and the ball recirculation give profiles with
//! several periods over the travel, which a quadratic misses entirely (it is nearly
//! orthogonal to them). Discovery therefore proposes the profile at a ladder of sizes,
//! [`PROPOSED_ORDERS`] (2, 4, 8, 16: each doubling the resolution along the travel, up to 16
//! — a period down to about an eighth of the travel — and nothing tuned to a particular
//! period); each is scored with its own number of new parameters (its price in the score
//! test), and an addition must then shrink the held-out error, so the size kept is the one
//! the data support. A cell file may give any order in 2..=[`MAX_ORDER`].

use super::guide_angular::{axis_order, check_guide};
use super::{
    ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect, Hook, legendre,
};
use crate::cell::EffectEntry;
use crate::params::{Axis, EffectParam, ParamId, ParamUnit};

/// Highest polynomial order of a straightness profile (cell file and discovery).
pub const MAX_ORDER: u8 = 16;

/// The orders discovery proposes (module docs).
pub const PROPOSED_ORDERS: [u8; 4] = [2, 4, 8, MAX_ORDER];

/// The `guide-straightness` effect.
#[derive(Debug, Clone, Copy)]
pub struct GuideStraightness;

fn order_of(spec: &EffectSpec) -> u8 {
    match *spec {
        EffectSpec::GuideStraightness { order } => order,
        _ => 0,
    }
}

impl ErrorEffect for GuideStraightness {
    fn kind(&self) -> EffectKind {
        EffectKind::GuideStraightness
    }
    fn name(&self) -> &'static str {
        "guide-straightness"
    }
    fn meaning(&self) -> &'static str {
        "the carriage path bows sideways along the guide"
    }
    fn single_instance(&self) -> bool {
        true
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        (2..=order_of(spec).max(2))
            .flat_map(|o| {
                [Axis::X, Axis::Y]
                    .map(|axis| ParamId::Effect(EffectParam::GuideStraightness { axis, order: o }))
            })
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
            EffectParam::GuideStraightness { axis: Axis::X | Axis::Y, order } => {
                Some(EffectSpec::GuideStraightness { order })
            }
            _ => None,
        }
    }
    fn param_name(&self, param: &EffectParam) -> String {
        match param {
            EffectParam::GuideStraightness { axis, order } => {
                format!("guide_straightness_{}_p{order}", axis.letter())
            }
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let (axis, order) = axis_order(name.strip_prefix("guide_straightness_")?)?;
        (axis != Axis::Z).then_some(EffectParam::GuideStraightness { axis, order })
    }
    fn param_unit(&self, _param: &EffectParam) -> ParamUnit {
        ParamUnit::Mm
    }
    fn bound(&self, _param: &ParamId) -> Option<(f64, &'static str)> {
        // of the profile's largest sideways excursion over the travel (`bounded_magnitudes`)
        Some((0.5, "0.5 mm"))
    }
    fn bounded_magnitudes(
        &self,
        spec: &EffectSpec,
        changes: &[(ParamId, f64)],
    ) -> Option<Vec<(ParamId, f64, String)>> {
        let peak = |axis: Axis| {
            let profile = |u: f64| {
                changes
                    .iter()
                    .filter_map(|(id, c)| match id {
                        ParamId::Effect(EffectParam::GuideStraightness { axis: a, order }) if *a == axis => {
                            Some(c * legendre(*order, u))
                        }
                        _ => None,
                    })
                    .sum::<f64>()
            };
            // the largest magnitude on a fine grid over the travel (u in [-1, 1]; 400 points
            // resolve the order-16 polynomial's extrema to well under a percent)
            (0..=400).map(|k| profile(-1.0 + f64::from(k) / 200.0).abs()).fold(0.0, f64::max)
        };
        Some(
            [Axis::X, Axis::Y]
                .map(|axis| {
                    (
                        ParamId::Effect(EffectParam::GuideStraightness { axis, order: 2 }),
                        peak(axis),
                        format!(
                            "the {} profile of {} (largest over the travel)",
                            axis.letter(),
                            self.label(spec)
                        ),
                    )
                })
                .to_vec(),
        )
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        Ok(EffectSpec::GuideStraightness { order: entry.order.unwrap_or(2) })
    }
    fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        entry.order = Some(order_of(spec));
    }
    fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        check_guide(chain)?;
        if (2..=MAX_ORDER).contains(&order_of(spec)) {
            Ok(())
        } else {
            Err(format!(
                "order must be 2..={MAX_ORDER} (order 1 is a tilted guide, absorbed by the base pose)"
            ))
        }
    }
    fn candidates(&self, chain: &ChainInfo<'_>, _data: &DataUse, _joint: Option<u8>) -> Vec<EffectSpec> {
        match chain.guide {
            Some(_) => PROPOSED_ORDERS.map(|order| EffectSpec::GuideStraightness { order }).to_vec(),
            None => Vec::new(),
        }
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
        for o in 2..=order_of(spec) {
            let p = legendre(o, x.guide_u);
            for axis in [Axis::X, Axis::Y] {
                add(EffectParam::GuideStraightness { axis, order: o }, Hook::GuideShift(axis), p);
            }
        }
    }
}
