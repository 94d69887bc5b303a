//! `joint-cyclic-half`: periodic error of a revolute joint whose period is two joint turns
//! divided by an odd number, `theta_i += s sin(m q_i / 2) + c cos(m q_i / 2)` for odd `m`
//! (1/2, 3/2, 5/2, ... periods per joint turn; parameters `halfcyclic{i}_m{m}_sin`,
//! `halfcyclic{i}_m{m}_cos` \[rad\]).
//!
//! `joint-cyclic` is the Fourier series of a joint error over **one** turn (integer
//! harmonics). An error whose period is not a whole fraction of a turn — a gear stage, belt or
//! cable wrap whose ratio to the joint is not an integer, or any smooth error on a joint that
//! turns through more than one revolution (±360° on many arms) — is not periodic over one
//! turn; the Fourier series over **two** turns is: its terms are the integer harmonics plus
//! the odd half-integer ones this effect adds. Discovery proposes it only on joints whose
//! range spans more than one turn ([`multi_turn`]); a cell file may switch it on anywhere.

use super::{
    CandidateScope, ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect,
    Hook, entry_joint, revolute_joint,
};
use crate::cell::EffectEntry;
use crate::params::{EffectParam, ParamId, ParamUnit};
use crate::units::MAX_JOINTS;

/// This effect's id among the extensions.
pub const ID: u8 = 1;
const KIND: EffectKind = EffectKind::Extension(ID);

/// Odd multiples `m` (frequency `m/2` per turn) discovery proposes first; the next one
/// (`m + 2`, up to [`MAX_PROPOSED_M`]) once the model has the highest of them.
pub const PROPOSED_M: [u8; 3] = [1, 3, 5];

/// Highest odd multiple discovery proposes (3.5 periods per turn).
pub const MAX_PROPOSED_M: u8 = 7;

/// The `joint-cyclic-half` effect.
#[derive(Debug, Clone, Copy)]
pub struct JointCyclicHalf;

/// The instance on `joint` with odd multiple `m`.
pub fn spec(joint: u8, m: u8) -> EffectSpec {
    EffectSpec::Extension { kind: KIND, joint, index: m }
}

fn of(spec: &EffectSpec) -> (u8, u8) {
    match *spec {
        EffectSpec::Extension { joint, index, .. } => (joint, index),
        _ => (0, 0),
    }
}

/// The sine (`slot` 0) or cosine (`slot` 1) parameter of the instance on `joint`, multiple `m`.
pub fn param(joint: u8, m: u8, slot: u8) -> EffectParam {
    EffectParam::Extension { kind: KIND, joint, index: m, slot }
}

/// Whether joint `joint`'s range spans more than one turn. Only there does discovery propose
/// the two-turn terms: on a joint whose range is at most one turn, an error that is smooth over
/// the range extends to a smooth once-per-turn periodic function through the arc the joint never
/// visits, so the one-turn harmonics (`joint-cyclic`) already describe it; beyond one turn the
/// joint reaches the same angle modulo 2π at different positions of a gear stage or cable
/// wrap, and the one-turn series is incomplete.
pub fn multi_turn(chain: &ChainInfo<'_>, joint: u8) -> bool {
    chain
        .ranges
        .get(joint as usize - 1)
        .is_some_and(|(lo, hi)| hi - lo > std::f64::consts::TAU * (1.0 + 1e-6))
}

impl ErrorEffect for JointCyclicHalf {
    fn kind(&self) -> EffectKind {
        KIND
    }
    fn name(&self) -> &'static str {
        "joint-cyclic-half"
    }
    fn meaning(&self) -> &'static str {
        "periodic joint error whose period is not a whole fraction of a turn (a gear stage or cable wrap of non-integer ratio; the two-turn Fourier terms)"
    }
    fn params(&self, spec: &EffectSpec) -> Vec<ParamId> {
        let (joint, m) = of(spec);
        vec![ParamId::Effect(param(joint, m, 0)), ParamId::Effect(param(joint, m, 1))]
    }
    fn label(&self, spec: &EffectSpec) -> String {
        let (joint, m) = of(spec);
        format!("joint-cyclic-half (joint {joint}, {} per turn)", f64::from(m) / 2.0)
    }
    fn joint(&self, spec: &EffectSpec) -> Option<u8> {
        Some(of(spec).0)
    }
    fn owner(&self, p: &EffectParam) -> Option<EffectSpec> {
        match *p {
            EffectParam::Extension { kind: KIND, joint, index, .. } => Some(spec(joint, index)),
            _ => None,
        }
    }
    fn param_name(&self, p: &EffectParam) -> String {
        match *p {
            EffectParam::Extension { kind: KIND, joint, index, slot } => {
                format!("halfcyclic{joint}_m{index}_{}", if slot == 0 { "sin" } else { "cos" })
            }
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let s = name.strip_prefix("halfcyclic")?;
        let mut it = s.split('_');
        let j: u8 = it.next()?.parse().ok().filter(|j| (1..=MAX_JOINTS as u8).contains(j))?;
        let m: u8 = it.next()?.strip_prefix('m')?.parse().ok().filter(|m| m % 2 == 1)?;
        let slot = match it.next()? {
            "sin" => 0,
            "cos" => 1,
            _ => return None,
        };
        if it.next().is_some() {
            return None;
        }
        Some(param(j, m, slot))
    }
    fn param_unit(&self, _p: &EffectParam) -> ParamUnit {
        ParamUnit::Rad
    }
    fn bound(&self, _p: &ParamId) -> Option<(f64, &'static str)> {
        Some((0.5f64.to_radians(), "0.5 deg"))
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        let m = entry.harmonic.ok_or("needs `harmonic` (odd: periods per two joint turns)")?;
        if m % 2 == 0 {
            return Err(format!("`harmonic` must be odd (periods per two joint turns), got {m}"));
        }
        Ok(spec(entry_joint(entry)?, m))
    }
    fn write_entry(&self, spec: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        let (joint, m) = of(spec);
        entry.joint = Some(joint);
        entry.harmonic = Some(m);
    }
    fn check(&self, spec: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        let (joint, m) = of(spec);
        revolute_joint(joint, chain)?;
        if m % 2 == 1 { Ok(()) } else { Err(format!("harmonic must be odd (periods per two turns), got {m}")) }
    }
    fn scope(&self) -> CandidateScope {
        CandidateScope::PerRevoluteJoint
    }
    fn candidates(&self, chain: &ChainInfo<'_>, _data: &DataUse, joint: Option<u8>) -> Vec<EffectSpec> {
        let Some(joint) = joint else { return Vec::new() };
        if !multi_turn(chain, joint) {
            return Vec::new();
        }
        PROPOSED_M.iter().map(|m| spec(joint, *m)).collect()
    }
    fn follow_ups(&self, enabled: &EffectSpec) -> Vec<EffectSpec> {
        let (joint, m) = of(enabled);
        let top = PROPOSED_M[PROPOSED_M.len() - 1];
        if (top..MAX_PROPOSED_M).contains(&m) { vec![spec(joint, m + 2)] } else { Vec::new() }
    }
    fn driver(&self, spec: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Joint(of(spec).0)
    }
    fn contributions(
        &self,
        spec: &EffectSpec,
        x: &EffectInputs<'_>,
        add: &mut dyn FnMut(EffectParam, Hook, f64),
    ) {
        let (joint, m) = of(spec);
        let qj = x.q.get(joint as usize - 1).copied().unwrap_or(0.0);
        let (s, c) = (0.5 * f64::from(m) * qj).sin_cos();
        add(param(joint, m, 0), Hook::Joint(joint), s);
        add(param(joint, m, 1), Hook::Joint(joint), c);
    }
}
