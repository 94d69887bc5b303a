//! `link-out-of-plane`: link frame i moves out of its joint's plane of rotation — along the
//! joint axis (`axial`) or tilting about the frame's x or y axis (`tilt-x`, `tilt-y`) — as a
//! smooth function of its own joint angle and the preceding joint's: the first Fourier terms in
//! both angles and their products,
//!
//! `s(q) = Σ_k c_k φ_k(q_{i-1}, q_i)`, with `φ = (cos q_{i-1}, sin q_{i-1}, cos q_i, sin q_i,
//! cos q_{i-1} cos q_i, cos q_{i-1} sin q_i, sin q_{i-1} cos q_i, sin q_{i-1} sin q_i)`.
//!
//! The catalog's other effects describe a link's errors in its plane of motion (joint angle
//! errors about the joint axis, length changes) or out of it under a named load (gravity
//! bending, `link-bending`). What they leave out is an out-of-plane motion whose cause is not a
//! modelled load or whose shape is not the load's: the axial runout and wobble of a bearing
//! over its turn (the terms in `q_i` alone), a bending or cable force that depends on the
//! arm's configuration through two joints (the products). This effect is the generic
//! description of such a motion, one component per instance with 8 coefficients
//! (`oop{i}_{axial|rx|ry}_{term}`, mm or rad): discovery proposes it on every revolute joint
//! that follows a revolute joint, after the physical effects have had their turn (it is
//! preferred only when it predicts held-out data better; among rivals that the data cannot
//! tell apart the simpler one is kept). Its bound applies to the motion's largest excursion
//! over the two angles (0.5 mm along the axis, 0.25° of tilt), not to each coefficient.

use super::{
    CandidateScope, ChainInfo, DataUse, EffectDriver, EffectInputs, EffectKind, EffectSpec, ErrorEffect,
    Hook, entry_joint, revolute_joint,
};
use crate::cell::EffectEntry;
use crate::params::{Axis, EffectParam, ParamId, ParamUnit};
use crate::units::MAX_JOINTS;

/// This effect's id among the extensions.
pub const ID: u8 = 3;
const KIND: EffectKind = EffectKind::Extension(ID);

/// Number of coefficients (Fourier terms) of one instance.
pub const TERMS: usize = 8;

/// Largest plausible excursion of the link frame along its joint axis \[mm\].
pub const MAX_AXIAL_MM: f64 = 0.5;

/// Largest plausible tilt of the link frame \[rad\] (0.25°).
pub const MAX_TILT_RAD: f64 = 0.25 * std::f64::consts::PI / 180.0;

/// Which motion of the link frame an instance describes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Component {
    /// translation along the joint axis (frame i's z) \[mm\]
    Axial,
    /// rotation about frame i's x axis \[rad\]
    TiltX,
    /// rotation about frame i's y axis \[rad\]
    TiltY,
}

impl Component {
    /// Every component, in instance-index order.
    pub const ALL: [Component; 3] = [Component::Axial, Component::TiltX, Component::TiltY];

    fn index(self) -> u8 {
        self as u8
    }
    fn from_index(i: u8) -> Option<Self> {
        Self::ALL.get(i as usize).copied()
    }
    /// The name in cell files and labels (`axial`, `tilt-x`, `tilt-y`).
    pub fn name(self) -> &'static str {
        match self {
            Component::Axial => "axial",
            Component::TiltX => "tilt-x",
            Component::TiltY => "tilt-y",
        }
    }
    /// The short name in parameter names (`axial`, `rx`, `ry`).
    fn short(self) -> &'static str {
        match self {
            Component::Axial => "axial",
            Component::TiltX => "rx",
            Component::TiltY => "ry",
        }
    }
    fn hook(self, joint: u8) -> Hook {
        match self {
            Component::Axial => Hook::LinkShift { joint, axis: Axis::Z },
            Component::TiltX => Hook::LinkRotation { joint, axis: Axis::X },
            Component::TiltY => Hook::LinkRotation { joint, axis: Axis::Y },
        }
    }
}

/// The `link-out-of-plane` effect.
#[derive(Debug, Clone, Copy)]
pub struct LinkOutOfPlane;

/// The instance on link frame `joint` for `component`.
pub fn spec(joint: u8, component: Component) -> EffectSpec {
    EffectSpec::Extension { kind: KIND, joint, index: component.index() }
}

/// Coefficient `term` (0..[`TERMS`]) of the instance on `joint`, `component`.
pub fn param(joint: u8, component: Component, term: u8) -> EffectParam {
    EffectParam::Extension { kind: KIND, joint, index: component.index(), slot: term }
}

fn of(spec: &EffectSpec) -> (u8, Component) {
    match *spec {
        EffectSpec::Extension { joint, index, .. } => (joint, Component::from_index(index).unwrap_or(Component::Axial)),
        _ => (0, Component::Axial),
    }
}

/// The Fourier terms `φ_k(q_{i-1}, q_i)` (module docs), `a = q_{i-1}`, `b = q_i` \[rad\].
pub fn terms(a: f64, b: f64) -> [f64; TERMS] {
    let (sa, ca) = a.sin_cos();
    let (sb, cb) = b.sin_cos();
    [ca, sa, cb, sb, ca * cb, ca * sb, sa * cb, sa * sb]
}

/// The name of term `k` of the instance on `joint` (e.g. `cos3sin4`).
fn term_name(joint: u8, k: u8) -> String {
    let (a, b) = (joint.saturating_sub(1), joint);
    match k {
        0 => format!("cos{a}"),
        1 => format!("sin{a}"),
        2 => format!("cos{b}"),
        3 => format!("sin{b}"),
        4 => format!("cos{a}cos{b}"),
        5 => format!("cos{a}sin{b}"),
        6 => format!("sin{a}cos{b}"),
        _ => format!("sin{a}sin{b}"),
    }
}

/// Largest |value| of the map with `coefficients` over both angles (a 72 × 72 grid of full
/// turns: the map is a trigonometric polynomial of degree one in each angle, so the grid's
/// 5° spacing resolves its extrema to a fraction of a percent).
pub fn peak(coefficients: &[f64; TERMS]) -> f64 {
    const N: u32 = 72;
    let step = std::f64::consts::TAU / f64::from(N);
    let mut best = 0.0f64;
    for i in 0..N {
        for j in 0..N {
            let phi = terms(f64::from(i) * step, f64::from(j) * step);
            let v: f64 = phi.iter().zip(coefficients).map(|(p, c)| p * c).sum();
            best = best.max(v.abs());
        }
    }
    best
}

impl ErrorEffect for LinkOutOfPlane {
    fn kind(&self) -> EffectKind {
        KIND
    }
    fn name(&self) -> &'static str {
        "link-out-of-plane"
    }
    fn generic(&self) -> bool {
        true
    }
    fn meaning(&self) -> &'static str {
        "the link frame moves along its joint axis or tilts out of the joint's plane as a smooth function of its own and the preceding joint's angle (bearing runout and wobble, configuration-dependent out-of-plane bending; the first Fourier terms in both angles)"
    }
    fn params(&self, s: &EffectSpec) -> Vec<ParamId> {
        let (joint, c) = of(s);
        (0..TERMS as u8).map(|k| ParamId::Effect(param(joint, c, k))).collect()
    }
    fn label(&self, s: &EffectSpec) -> String {
        let (joint, c) = of(s);
        format!("link-out-of-plane (joint {joint}, {})", c.name())
    }
    fn joint(&self, s: &EffectSpec) -> Option<u8> {
        Some(of(s).0)
    }
    fn owner(&self, p: &EffectParam) -> Option<EffectSpec> {
        match *p {
            EffectParam::Extension { kind: KIND, joint, index, slot } if (slot as usize) < TERMS => {
                Component::from_index(index).map(|c| spec(joint, c))
            }
            _ => None,
        }
    }
    fn param_name(&self, p: &EffectParam) -> String {
        match *p {
            EffectParam::Extension { kind: KIND, joint, index, slot } => {
                let c = Component::from_index(index).unwrap_or(Component::Axial);
                format!("oop{joint}_{}_{}", c.short(), term_name(joint, slot))
            }
            _ => String::new(),
        }
    }
    fn parse_param(&self, name: &str) -> Option<EffectParam> {
        let mut it = name.strip_prefix("oop")?.split('_');
        let joint: u8 = it.next()?.parse().ok().filter(|j| (2..=MAX_JOINTS as u8).contains(j))?;
        let short = it.next()?;
        let c = Component::ALL.into_iter().find(|c| c.short() == short)?;
        let term = it.next()?;
        if it.next().is_some() {
            return None;
        }
        let k = (0..TERMS as u8).find(|k| term_name(joint, *k) == term)?;
        Some(param(joint, c, k))
    }
    fn param_unit(&self, p: &EffectParam) -> ParamUnit {
        match *p {
            EffectParam::Extension { index: 0, .. } => ParamUnit::Mm,
            _ => ParamUnit::Rad,
        }
    }
    fn bound(&self, p: &ParamId) -> Option<(f64, &'static str)> {
        // of the map's largest excursion over both angles (`bounded_magnitudes`)
        match p {
            ParamId::Effect(EffectParam::Extension { index: 0, .. }) => Some((MAX_AXIAL_MM, "0.5 mm")),
            _ => Some((MAX_TILT_RAD, "0.25 deg")),
        }
    }
    fn bounded_magnitudes(&self, s: &EffectSpec, changes: &[(ParamId, f64)]) -> Option<Vec<(ParamId, f64, String)>> {
        let (joint, c) = of(s);
        let mut coefficients = [0.0; TERMS];
        for (id, v) in changes {
            if let ParamId::Effect(EffectParam::Extension { kind: KIND, joint: j, index, slot }) = id
                && *j == joint
                && *index == c.index()
                && (*slot as usize) < TERMS
            {
                coefficients[*slot as usize] = *v;
            }
        }
        Some(vec![(
            ParamId::Effect(param(joint, c, 0)),
            peak(&coefficients),
            format!("the {} motion of {} (largest over both angles)", c.name(), self.label(s)),
        )])
    }
    fn read_entry(&self, entry: &EffectEntry) -> Result<EffectSpec, String> {
        let joint = entry_joint(entry)?;
        let name = entry.component.as_deref().ok_or("needs `component` (`axial`, `tilt-x` or `tilt-y`)")?;
        let c = Component::ALL
            .into_iter()
            .find(|c| c.name() == name)
            .ok_or_else(|| format!("`component` must be `axial`, `tilt-x` or `tilt-y`, got `{name}`"))?;
        Ok(spec(joint, c))
    }
    fn write_entry(&self, s: &EffectSpec, entry: &mut EffectEntry, _t: f64) {
        let (joint, c) = of(s);
        entry.joint = Some(joint);
        entry.component = Some(c.name().to_string());
    }
    fn check(&self, s: &EffectSpec, chain: &ChainInfo<'_>) -> Result<(), String> {
        let (joint, _) = of(s);
        revolute_joint(joint, chain)?;
        if joint >= 2 && chain.is_revolute(joint - 1) {
            Ok(())
        } else {
            Err(format!("joint {joint} must follow a revolute joint (the map's second angle) on this chain of {}", chain.describe()))
        }
    }
    fn scope(&self) -> CandidateScope {
        CandidateScope::PerRevoluteJoint
    }
    fn candidates(&self, chain: &ChainInfo<'_>, _data: &DataUse, joint: Option<u8>) -> Vec<EffectSpec> {
        match joint {
            Some(j) if j >= 2 && chain.is_revolute(j) && chain.is_revolute(j - 1) => {
                Component::ALL.iter().map(|c| spec(j, *c)).collect()
            }
            _ => Vec::new(),
        }
    }
    fn driver(&self, s: &EffectSpec, _guide: u8, _n: u8) -> EffectDriver {
        EffectDriver::Joint(of(s).0)
    }
    fn contributions(&self, s: &EffectSpec, x: &EffectInputs<'_>, add: &mut dyn FnMut(EffectParam, Hook, f64)) {
        let (joint, c) = of(s);
        let q = |j: u8| x.q.get((j as usize).wrapping_sub(1)).copied().unwrap_or(0.0);
        let phi = terms(q(joint.saturating_sub(1)), q(joint));
        let hook = c.hook(joint);
        for (k, v) in phi.iter().enumerate() {
            add(param(joint, c, k as u8), hook, *v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::JointKind;

    #[test]
    fn names_round_trip_and_the_hooks_carry_the_fourier_terms() {
        let s = spec(4, Component::Axial);
        assert_eq!(s.label(), "link-out-of-plane (joint 4, axial)");
        let names: Vec<String> = s.params().iter().map(ParamId::name).collect();
        assert_eq!(names[0], "oop4_axial_cos3");
        assert_eq!(names[7], "oop4_axial_sin3sin4");
        for c in Component::ALL {
            for p in spec(4, c).params() {
                assert_eq!(ParamId::from_name(&p.name()), Some(p), "{}", p.name());
                assert_eq!(p.unit(), if c == Component::Axial { ParamUnit::Mm } else { ParamUnit::Rad });
            }
        }
        assert!(ParamId::from_name("oop4_axial_cos4cos4").is_none());
        assert!(ParamId::from_name("oop4_rz_cos3").is_none());
        let q = [0.0, 0.3, -1.1, 0.0, 0.0, 0.0, 0.0];
        let ctx = crate::measurement::MeasurementContext::default();
        let x = EffectInputs { ..EffectInputs::at(&q, &ctx) };
        let phi = terms(0.3, -1.1);
        assert_eq!(
            super::super::hook_of(param(3, Component::TiltY, 5), &x),
            Some((Hook::LinkRotation { joint: 3, axis: Axis::Y }, phi[5]))
        );
        assert_eq!(
            super::super::hook_of(param(3, Component::Axial, 7), &x),
            Some((Hook::LinkShift { joint: 3, axis: Axis::Z }, 0.3f64.sin() * (-1.1f64).sin()))
        );
    }

    #[test]
    fn the_bound_applies_to_the_largest_excursion() {
        let s = spec(3, Component::Axial);
        let change = |v: f64| -> Vec<(ParamId, f64)> {
            // cos q2 cos q3 + sin q2 sin q3 = cos(q3 - q2): peak |v|
            vec![(ParamId::Effect(param(3, Component::Axial, 4)), v), (ParamId::Effect(param(3, Component::Axial, 7)), v)]
        };
        let peaks = LinkOutOfPlane.bounded_magnitudes(&s, &change(0.3)).expect("a profile");
        assert!((peaks[0].1 - 0.3).abs() < 1e-9, "{peaks:?}");
        assert!(super::super::plausibility(&s, &change(0.3)).is_ok());
        assert!(super::super::plausibility(&s, &change(0.6)).is_err());
    }

    #[test]
    fn it_is_proposed_only_after_a_revolute_joint() {
        let kinds = [JointKind::Prismatic, JointKind::Revolute, JointKind::Revolute];
        let chain = ChainInfo { kinds: &kinds, guide: Some(1), tcps: &[], positions: &[], canonical: false, ranges: &[] };
        assert!(LinkOutOfPlane.candidates(&chain, &DataUse::default(), Some(2)).is_empty());
        assert_eq!(LinkOutOfPlane.candidates(&chain, &DataUse::default(), Some(3)).len(), 3);
        assert!(LinkOutOfPlane.check(&spec(2, Component::TiltX), &chain).is_err());
        assert!(LinkOutOfPlane.check(&spec(3, Component::TiltX), &chain).is_ok());
        let mut entry = EffectEntry {
            effect: "link-out-of-plane".into(),
            joint: Some(3),
            ..EffectEntry::default()
        };
        assert!(LinkOutOfPlane.read_entry(&entry).is_err_and(|m| m.contains("component")));
        LinkOutOfPlane.write_entry(&spec(3, Component::TiltY), &mut entry, 20.0);
        assert_eq!(LinkOutOfPlane.read_entry(&entry), Ok(spec(3, Component::TiltY)));
        entry.component = Some("tilt-z".into());
        assert!(LinkOutOfPlane.read_entry(&entry).is_err_and(|m| m.contains("tilt-z")));
    }
}
