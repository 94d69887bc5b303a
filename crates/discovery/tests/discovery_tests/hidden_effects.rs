//! Discovery on simulated data in which an effect is hidden: the true cell contains it, the
//! workflow starts from the nominal model without it and is not told what it is. It must name
//! the right effect (and joint), add nothing else, and the validation gap must shrink to near
//! what a fit with the true structure achieves.
//!
//! Data: 180 probe poses (paper noise budget, 2 µm per axis), 250 tracker validation poses
//! (5 µm per axis), realistic geometric errors and compliances in the truth.

use crate::common;

use common::{Hidden, Scenario, cyclic_h, oracle_validation, scenario, tool_frame, truth_validation};
use vatcal_core::effects::{EffectKind, EffectSpec};
use vatcal_core::params::{Axis, EffectParam};
use vatcal_core::{ParamId, ParamSet};
use vatcal_discovery::{DiscoverOptions, Discovery, discover};

const N_PROBE: usize = 180;

fn run(s: &Scenario, params: &ParamSet) -> Discovery {
    let d = discover(&common::nominal(), &s.probe, params, Some(&s.validation), &DiscoverOptions::default())
        .expect("discovery runs");
    for round in &d.rounds {
        eprintln!("round {}: {}", round.index, round.decision);
        for top in round.location.iter().take(3) {
            eprintln!("   where: {}", top.sentence());
        }
    }
    eprintln!("gap {:.4} -> {:.4} mm", d.initial_gap_mm, d.final_gap_mm);
    d
}

fn names(d: &Discovery) -> Vec<(String, Option<u8>)> {
    d.added_effects.iter().map(|a| (a.effect.clone(), a.joint)).collect()
}

/// The final validation gap is within 30 % of a fit with the true structure, and smaller than
/// at the start.
fn assert_gap_closed(s: &Scenario, d: &Discovery, params: &ParamSet, hidden: &[Hidden]) {
    let oracle = oracle_validation(s, params, hidden).mean;
    let floor = truth_validation(s).mean;
    eprintln!(
        "validation mean: start {:.4}, discovered {:.4}, true-structure fit {oracle:.4}, truth itself {floor:.4} mm",
        d.initial_gap_mm, d.final_gap_mm
    );
    assert!(d.final_gap_mm < d.initial_gap_mm, "the gap did not shrink");
    assert!(
        d.final_gap_mm <= 1.3 * oracle,
        "final gap {} mm vs true-structure fit {oracle} mm",
        d.final_gap_mm
    );
    for a in &d.added_effects {
        assert!(
            a.gap_after_mm < a.gap_before_mm,
            "{}: gap {} -> {}",
            a.label,
            a.gap_before_mm,
            a.gap_after_mm
        );
    }
}

#[test]
fn null_case_adds_nothing() {
    let s = scenario(11, &[], None, N_PROBE);
    let d = run(&s, &ParamSet::paper34());
    assert!(d.added_effects.is_empty(), "invented effects: {:?}", names(&d));
    // the report still shows candidates were scored and which ones cannot be seen at all
    let round = &d.rounds[0];
    assert!(round.candidates.iter().filter(|c| c.score.is_some()).count() > 20);
    assert!(d.notes.iter().any(|n| n.contains("joint-backlash")), "{:?}", d.notes);
}

#[test]
fn hidden_compliance_is_found_from_a_geometric_only_model() {
    // only joint 3 (the shoulder, J2) yields: 3e-4 rad/(N·m)
    let c = [0.0, 3e-4, 0.0, 0.0, 0.0, 0.0];
    let s = scenario(21, &[], Some(c), N_PROBE);
    let d = run(&s, &ParamSet::geometric());
    assert_eq!(names(&d), vec![("joint-compliance".to_string(), Some(3))]);
    let v = d.added_effects[0].values["c_3"];
    assert!((v - 3e-4).abs() < 0.3e-4, "c_3 = {v}");
    let hidden = [Hidden { spec: EffectSpec::JointCompliance { joint: 3 }, values: vec![] }];
    assert_gap_closed(&s, &d, &ParamSet::geometric(), &hidden);
}

#[test]
fn all_hidden_compliances_are_added_as_compliances() {
    // realistic truth: every joint yields (1e-4..4e-4 rad/(N·m)); a geometric-only model misses
    // all of them
    let s = scenario(22, &[], None, N_PROBE);
    let d = run(&s, &ParamSet::geometric());
    assert!(!d.added_effects.is_empty());
    // the carriage's gravity moment about its y axis is tau_2 (J1's axis is the carriage y
    // axis), so a carriage tilt about y is the same correction as the compliance of joint 2;
    // likewise J1's bending moment (J1 sits on the carriage: nearly the carriage's moment)
    // tilts the arm about the horizontal axis across its plane, nearly the shoulder's
    // compliance: `link-bending (joint 2)` is a gravity deflection too, and names that part
    // of the gap as well (seed 22: it is added in place of c_3). Nothing else may be added
    let link_bending = EffectKind::Extension(vatcal_core::effects::link_bending::ID);
    assert!(
        d.added_effects
            .iter()
            .all(|a| matches!(a.spec.kind(), EffectKind::JointCompliance | EffectKind::GuideCarriageTilt)
                || (a.spec.kind() == link_bending && a.spec.joint() == Some(2))),
        "{:?}",
        names(&d)
    );
    assert!(d.added_effects.iter().any(|a| a.spec.kind() == EffectKind::JointCompliance), "{:?}", names(&d));
    assert!(d.final_gap_mm < 0.5 * d.initial_gap_mm, "{} -> {}", d.initial_gap_mm, d.final_gap_mm);
}

fn cyclic(joint: u8, amplitude_deg: f64, phase_deg: f64) -> Hidden {
    let a = amplitude_deg.to_radians();
    let (s, c) = phase_deg.to_radians().sin_cos();
    Hidden {
        spec: EffectSpec::JointCyclic { joint, harmonic: 1 },
        values: vec![
            (ParamId::Effect(EffectParam::CyclicSin { joint, harmonic: 1 }), a * c),
            (ParamId::Effect(EffectParam::CyclicCos { joint, harmonic: 1 }), a * s),
        ],
    }
}

#[test]
fn hidden_cyclic_error_names_the_joint() {
    let hidden = [cyclic(5, 0.02, 30.0)];
    let s = scenario(31, &hidden, None, N_PROBE);
    let d = run(&s, &ParamSet::paper34());
    assert_eq!(names(&d), vec![("joint-cyclic".to_string(), Some(5))]);
    assert_eq!(d.added_effects[0].spec, EffectSpec::JointCyclic { joint: 5, harmonic: 1 });
    assert_gap_closed(&s, &d, &ParamSet::paper34(), &hidden);
}

fn guide_pitch(per_100mm_urad: f64) -> Hidden {
    // P1 coefficient over the 300 mm stroke: u goes from -1 to 1, i.e. 150 mm per unit
    let coeff = per_100mm_urad * 1e-6 * 1.5;
    Hidden {
        spec: EffectSpec::GuideAngular { order: 1 },
        values: vec![(ParamId::Effect(EffectParam::GuideAngular { axis: Axis::X, order: 1 }), coeff)],
    }
}

#[test]
fn hidden_guide_angular_error_is_found() {
    let hidden = [guide_pitch(40.0)];
    let s = scenario(41, &hidden, None, N_PROBE);
    let d = run(&s, &ParamSet::paper34());
    assert_eq!(names(&d), vec![("guide-angular".to_string(), Some(1))]);
    assert_gap_closed(&s, &d, &ParamSet::paper34(), &hidden);
}

#[test]
fn hidden_tool_frame_offset_is_found() {
    let hidden = [tool_frame()];
    let s = scenario(51, &hidden, None, N_PROBE);
    let d = run(&s, &ParamSet::paper34());
    assert_eq!(names(&d), vec![("tool-frame".to_string(), None)]);
    let tx = d.added_effects[0].values["tool_tx_mm"];
    assert!((tx - 0.030).abs() < 0.01, "tool_tx = {tx}");
    assert_gap_closed(&s, &d, &ParamSet::paper34(), &hidden);
}

#[test]
fn two_hidden_effects_are_both_found() {
    let hidden = [cyclic(3, 0.015, -60.0), tool_frame()];
    let s = scenario(61, &hidden, None, N_PROBE);
    let d = run(&s, &ParamSet::paper34());
    let mut found = names(&d);
    found.sort();
    assert_eq!(found, vec![("joint-cyclic".to_string(), Some(3)), ("tool-frame".to_string(), None)]);
    assert_gap_closed(&s, &d, &ParamSet::paper34(), &hidden);
}

/// Several effects at once, on top of one the catalog does not propose (a 3rd gear harmonic):
/// σ̂ of every fit stays far above the instruments' noise, so the size rule must use the known
/// instrument noise (`instrument_sigmas`) to add the catalog effects over several rounds.
#[test]
fn several_effects_are_added_over_rounds_with_the_known_instrument_noise() {
    let hidden = [
        cyclic_h(2, 1, 0.012, 20.0),
        cyclic_h(3, 2, 0.012, -70.0),
        cyclic_h(5, 1, 0.015, 110.0),
        tool_frame(),
        cyclic_h(4, 3, 0.03, 45.0),
    ];
    let s = scenario(71, &hidden, None, N_PROBE);
    let probe_sigma_mm = 0.002;
    let options = DiscoverOptions {
        instrument_sigmas: Some(vatcal_identification::KindSigmas {
            probe_mm: Some(probe_sigma_mm),
            tracker_mm: Some(0.005),
        }),
        ..DiscoverOptions::default()
    };
    let d = discover(&common::nominal(), &s.probe, &ParamSet::paper34(), Some(&s.validation), &options)
        .expect("discovery runs");
    for round in &d.rounds {
        eprintln!("round {} (sigma-hat {:.4} mm): {}", round.index, round.fit.sigma_hat_mm, round.decision);
    }
    // the misfit of the uncatalogued harmonic keeps σ̂ well above the instrument noise
    assert!(d.rounds[0].fit.sigma_hat_mm > 3.0 * probe_sigma_mm, "{}", d.rounds[0].fit.sigma_hat_mm);
    // the size rule compares with the instrument noise, not with σ̂
    for c in d.rounds.iter().flat_map(|r| &r.candidates) {
        if let Some(r) = &c.refit {
            assert!((r.negligible_below_mm - 3f64.sqrt() * probe_sigma_mm).abs() < 1e-12, "{}", c.label);
        }
    }
    let found = names(&d);
    for want in [("joint-cyclic", 2), ("joint-cyclic", 3), ("joint-cyclic", 5)] {
        assert!(found.contains(&(want.0.to_string(), Some(want.1))), "{want:?} not in {found:?}");
    }
    assert!(found.contains(&("tool-frame".to_string(), None)), "{found:?}");
    // nothing unrelated: every addition is a hidden effect or stands in for the joint-4 harmonic
    for (name, joint) in &found {
        let ok = name == "tool-frame" || matches!(joint, Some(2..=5));
        assert!(ok, "unexpected {name} {joint:?} in {found:?}");
    }
    assert!(d.final_gap_mm < 0.5 * d.initial_gap_mm, "{} -> {}", d.initial_gap_mm, d.final_gap_mm);
}
