//! Discovery on campaign-like data (`common::campaign`): Detmax-selected probe poses measured
//! from both approach directions with time and temperature recorded, centring truncation with
//! the final offsets recorded, ~1 µm CMM errors in the truth, tracker validation poses.
//!
//! * the null case (nothing beyond the model but the CMM errors) adds nothing and the held-out
//!   error does not grow;
//! * every catalog effect hidden alone at a realistic size is named, with the right joint.
//!
//! The seed sweep (detection and false-positive rates) is `sweep_campaign` below, ignored by
//! default: `cargo test -p vatcal-discovery --release --test discovery_tests campaign_like:: -- --ignored --nocapture`.

use crate::common;

use common::Hidden;
use common::campaign::campaign;
use vatcal_core::effects::{EffectSpec, ThermalDriver};
use vatcal_core::params::{Axis, EffectParam, ToolFrameDof};
use vatcal_core::{ParamId, ParamSet};
use vatcal_discovery::{DiscoverOptions, Discovery, discover};

/// Discovery with the default options; with `SWEEP_INSTRUMENT=1` in the environment, with the
/// data's known instrument noise (`instrument_sigmas`: probe σ of the recorded gauge reading and
/// the unrecorded noise, tracker 5 µm), as the demo runs it.
fn run(s: &common::Scenario) -> Discovery {
    let instrument = std::env::var("SWEEP_INSTRUMENT").is_ok_and(|v| v == "1");
    let options = DiscoverOptions {
        instrument_sigmas: instrument.then(|| vatcal_identification::KindSigmas {
            probe_mm: Some(common::campaign::GAUGE_SIGMA_MM.hypot(common::campaign::UNMODELLED_SIGMA_MM)),
            tracker_mm: Some(0.005),
        }),
        ..DiscoverOptions::default()
    };
    discover(&common::nominal(), &s.probe, &ParamSet::paper34(), Some(&s.validation), &options)
        .expect("discovery runs")
}

fn describe(d: &Discovery) -> String {
    let mut out = String::new();
    for r in &d.rounds {
        out.push_str(&format!("round {}: {}\n", r.index, r.decision));
    }
    for n in &d.negligible_effects {
        out.push_str(&format!("negligible: {} ({:.1} um)\n", n.label, n.change_um));
    }
    out.push_str(&format!("gap {:.4} -> {:.4} mm", d.initial_gap_mm, d.final_gap_mm));
    out
}

fn names(d: &Discovery) -> Vec<(String, Option<u8>)> {
    d.added_effects.iter().map(|a| (a.effect.clone(), a.joint)).collect()
}

fn p(e: EffectParam) -> ParamId {
    ParamId::Effect(e)
}

/// Every catalog effect at a realistic size, with the (effect name, joint) discovery must name.
pub fn catalog_cases() -> Vec<(Hidden, (&'static str, Option<u8>))> {
    let deg = |v: f64| v.to_radians();
    let mut v = Vec::new();
    for joint in 2..=7u8 {
        // strain-wave gear first harmonic: 0.01° (≈ 35 µm at 200 mm)
        v.push((
            Hidden {
                spec: EffectSpec::JointCyclic { joint, harmonic: 1 },
                values: vec![
                    (p(EffectParam::CyclicSin { joint, harmonic: 1 }), deg(0.008)),
                    (p(EffectParam::CyclicCos { joint, harmonic: 1 }), deg(-0.006)),
                ],
            },
            ("joint-cyclic", Some(joint)),
        ));
    }
    v.push((
        Hidden {
            spec: EffectSpec::JointCyclic { joint: 4, harmonic: 2 },
            values: vec![
                (p(EffectParam::CyclicSin { joint: 4, harmonic: 2 }), deg(0.006)),
                (p(EffectParam::CyclicCos { joint: 4, harmonic: 2 }), deg(0.008)),
            ],
        },
        ("joint-cyclic", Some(4)),
    ));
    v.push((
        Hidden {
            spec: EffectSpec::JointScale { joint: 6 },
            values: vec![(p(EffectParam::JointScale { joint: 6 }), 3e-4)],
        },
        ("joint-scale", Some(6)),
    ));
    for joint in [3u8, 5] {
        // lost motion 0.005° (≈ 90 µrad)
        v.push((
            Hidden {
                spec: EffectSpec::JointBacklash { joint },
                values: vec![(p(EffectParam::Backlash { joint }), deg(0.005))],
            },
            ("joint-backlash", Some(joint)),
        ));
    }
    v.push((
        Hidden {
            spec: EffectSpec::GuideAngular { order: 1 },
            values: vec![(p(EffectParam::GuideAngular { axis: Axis::Y, order: 1 }), 50e-6 * 1.5)],
        },
        ("guide-angular", Some(1)),
    ));
    v.push((
        Hidden {
            spec: EffectSpec::GuideStraightness { order: 2 },
            values: vec![(p(EffectParam::GuideStraightness { axis: Axis::X, order: 2 }), 0.025)],
        },
        ("guide-straightness", Some(1)),
    ));
    v.push((
        Hidden { spec: EffectSpec::GuideScale, values: vec![(p(EffectParam::GuideScale), 2e-4)] },
        ("guide-scale", Some(1)),
    ));
    let tool = |d| p(EffectParam::ToolFrame(d));
    v.push((
        Hidden {
            spec: EffectSpec::ToolFrame,
            values: vec![
                (tool(ToolFrameDof::Tx), 0.030),
                (tool(ToolFrameDof::Ty), -0.020),
                (tool(ToolFrameDof::Rx), deg(0.02)),
                (tool(ToolFrameDof::Ry), deg(-0.03)),
            ],
        },
        ("tool-frame", None),
    ));
    v.push((
        Hidden {
            spec: EffectSpec::TcpOffset { tcp: 2 },
            values: vec![
                (ParamId::Tcp { id: 2, axis: Axis::X }, 0.020),
                (ParamId::Tcp { id: 2, axis: Axis::Y }, -0.015),
                (ParamId::Tcp { id: 2, axis: Axis::Z }, 0.010),
            ],
        },
        ("tcp-offset", None),
    ));
    v.push((
        Hidden {
            spec: EffectSpec::PositionOffset { position: 2 },
            values: vec![
                (ParamId::Position { id: 2, axis: Axis::X }, 0.020),
                (ParamId::Position { id: 2, axis: Axis::Y }, 0.015),
                (ParamId::Position { id: 2, axis: Axis::Z }, -0.010),
            ],
        },
        ("position-offset", None),
    ));
    v.push((
        Hidden {
            spec: EffectSpec::ThermalDrift { driver: ThermalDriver::Time },
            values: vec![(p(EffectParam::ThermalPerSecond), 1.5e-8)],
        },
        ("thermal-drift", None),
    ));
    v.push((
        Hidden {
            spec: EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature },
            values: vec![(p(EffectParam::ThermalPerKelvin), 4e-5)],
        },
        ("thermal-drift", None),
    ));
    v
}

#[test]
fn null_campaign_adds_nothing_and_the_heldout_error_does_not_grow() {
    for (seed, n) in [(3u64, 60usize), (4, 120)] {
        let s = campaign(seed, &[], n);
        assert_eq!(s.probe.len(), n);
        assert!(s.probe.iter().all(|m| m.probe_offset_mm.is_some_and(|o| o.norm() < 0.009)));
        let d = run(&s);
        eprintln!("null seed {seed}, {n} measurements:\n{}", describe(&d));
        assert!(d.added_effects.is_empty(), "invented effects: {:?}", names(&d));
        assert!(d.final_gap_mm <= d.initial_gap_mm, "{} -> {}", d.initial_gap_mm, d.final_gap_mm);
        assert!(d.final_gap.heldout.mean <= d.initial_gap.heldout.mean);
        // screening and confirmation are disjoint halves
        assert_eq!(d.split[0] + d.split[1], n);
        assert!(d.split[0] >= n / 2 - 3 && d.split[1] >= n / 2 - 3, "{:?}", d.split);
        let u = d.uncertainty.as_ref().expect("uncertainty");
        assert!(u.with_cmm_mean_mm > u.statistical_mean_mm, "{u:?}");
    }
}

#[test]
fn recorded_centring_offsets_lower_the_residual() {
    let s = campaign(5, &[], 80);
    let with =
        discover(&common::nominal(), &s.probe, &ParamSet::paper34(), None, &DiscoverOptions::default())
            .expect("discovery");
    let stripped: Vec<_> =
        s.probe.iter().map(|m| vatcal_core::Measurement { probe_offset_mm: None, ..*m }).collect();
    let without =
        discover(&common::nominal(), &stripped, &ParamSet::paper34(), None, &DiscoverOptions::default())
            .expect("discovery");
    let (a, b) = (with.rounds[0].fit.sigma_hat_mm, without.rounds[0].fit.sigma_hat_mm);
    eprintln!("sigma hat with offsets {a:.5} mm, without {b:.5} mm");
    // 1.5 µm unrecorded + 0.7 µm gauge noise vs + 2.2 µm per axis of truncation
    assert!(a < 0.8 * b, "{a} vs {b}");
    assert!(with.initial_gap.heldout.rms < without.initial_gap.heldout.rms);
}

#[test]
fn every_catalog_effect_hidden_alone_is_named() {
    let mut failures = Vec::new();
    for (k, (hidden, expect)) in catalog_cases().into_iter().enumerate() {
        let label = hidden.spec.label();
        let s = campaign(40 + k as u64, std::slice::from_ref(&hidden), 120);
        let d = run(&s);
        let found = names(&d);
        // the right effect, joint, harmonic and driver (e.g. time vs temperature)
        let ok = found.first().is_some_and(|(e, j)| e == expect.0 && *j == expect.1)
            && d.added_effects.first().is_some_and(|a| a.spec == hidden.spec);
        eprintln!("{label}: found {found:?}\n{}", describe(&d));
        if !ok {
            failures.push(format!("{label}: found {found:?}"));
        }
    }
    assert!(failures.is_empty(), "misnamed: {failures:#?}");
}

/// Detection rate (every catalog case, several seeds) and false-positive rate (null data, many
/// seeds) on campaign-like data. Prints one line per data set and the two rates; fails only if
/// the data cannot be generated. Run in release:
/// `cargo test -p vatcal-discovery --release --test discovery_tests campaign_like:: -- --ignored --nocapture`
/// (`SWEEP_SEEDS` = seeds per catalog case, default 3; `SWEEP_NULL` = null data sets, default 60;
/// `SWEEP_N` = probe measurements per data set, default 120).
#[test]
#[ignore = "seed sweep, ~1-2 min in release"]
fn sweep_campaign() {
    let env = |k: &str, d: usize| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    let (seeds, nulls, n) = (env("SWEEP_SEEDS", 3), env("SWEEP_NULL", 60), env("SWEEP_N", 120));
    let started = std::time::Instant::now();
    let (mut named, mut total) = (0usize, 0usize);
    let mut misses = Vec::new();
    for (k, (hidden, expect)) in catalog_cases().into_iter().enumerate() {
        for s in 0..seeds {
            let seed = 1000 + 100 * k as u64 + s as u64;
            let data = campaign(seed, std::slice::from_ref(&hidden), n);
            let d = run(&data);
            let found = names(&d);
            let ok = found.first().is_some_and(|(e, j)| e == expect.0 && *j == expect.1)
                && d.added_effects.first().is_some_and(|a| a.spec == hidden.spec);
            total += 1;
            named += usize::from(ok);
            println!(
                "{:<40} seed {seed}: {} found {found:?}, gap {:.4} -> {:.4} mm",
                hidden.spec.label(),
                if ok { "OK  " } else { "MISS" },
                d.initial_gap_mm,
                d.final_gap_mm
            );
            if !ok {
                misses.push(format!("{} seed {seed}: {found:?}", hidden.spec.label()));
            }
        }
    }
    let (mut false_alarms, mut grew) = (0usize, 0usize);
    for s in 0..nulls {
        let seed = 5000 + s as u64;
        let d = run(&campaign(seed, &[], n));
        let found = names(&d);
        false_alarms += usize::from(!found.is_empty());
        grew += usize::from(d.final_gap_mm > d.initial_gap_mm);
        println!(
            "null seed {seed}: added {found:?}, negligible {:?}, gap {:.4} -> {:.4} mm",
            d.negligible_effects
                .iter()
                .map(|x| format!("{} {:.1} um", x.label, x.change_um))
                .collect::<Vec<_>>(),
            d.initial_gap_mm,
            d.final_gap_mm
        );
    }
    println!("misses: {misses:#?}");
    println!(
        "SWEEP ({n} probe measurements per data set): detection {named}/{total} = {:.1} %; false positives on null data {false_alarms}/{nulls} = {:.1} %; validation gap grew in {grew}/{nulls} null data sets; {:.0} s",
        100.0 * named as f64 / total.max(1) as f64,
        100.0 * false_alarms as f64 / nulls.max(1) as f64,
        started.elapsed().as_secs_f64()
    );
}

/// The paper-like cell's temperature (`vatcal_sim`'s `PaperLikePhysics::paper`): a 1.5 K
/// warm-up with a 20 min time constant and a ±0.3 K air-conditioning cycle of one hour.
fn paper_temperature(t: f64, _total_s: f64) -> f64 {
    vatcal_sim::truth::PaperLikePhysics::paper().temperature.at(t)
}

/// The demo's discovery campaign as the virtual cell records it: each Detmax pose once, 12
/// two-sided repeats, the paper-like temperature read by the simulated thermometer (σ 0.02 K,
/// 0.01 K resolution).
fn demo_style() -> common::campaign::Style {
    let t = vatcal_sim::ThermometerSpec::default();
    common::campaign::Style {
        two_sided_repeats: Some(12),
        temperature: paper_temperature,
        thermometer: (t.sigma_k, t.resolution_k),
    }
}

/// A warmer day: the same cell without the air conditioning's help, 3 K of warm-up.
fn warm_day_temperature(t: f64, _total_s: f64) -> f64 {
    20.5 + 3.0 * (1.0 - (-t / 1200.0).exp()) + 0.3 * (std::f64::consts::TAU * t / 3600.0).sin()
}

/// Whether discovery named `label` in round 1: added, or reported *detected, negligible* as
/// the largest of the negligible ones.
fn named_first(d: &Discovery, label: &str) -> bool {
    let added = d.added_effects.first().is_some_and(|a| a.label == label);
    let negligible = d
        .negligible_effects
        .iter()
        .filter(|n| n.round == 1)
        .max_by(|a, b| a.change_um.total_cmp(&b.change_um))
        .is_some_and(|n| n.label == label);
    added || (d.added_effects.is_empty() && negligible)
}

/// Thermal growth of the paper-like truth's size (aluminium, 23e-6 /K) hidden alone, recorded
/// through the thermometer, on the demo's campaign shape (120 measurements, 45 s apart).
/// * Paper-like warm-up (1.5 K): the temperature-driven drift is the best candidate, ahead of
///   the time-driven one; its change of the predictions (measured: 3.3 µm on seed 61) is at the
///   noise threshold (√3 σ̂ = 3.4 µm), so it is added or reported *detected, negligible* — the
///   size rule working as designed, not a miss.
/// * 3 K warm-up: added, with its coefficient.
#[test]
fn realistic_thermal_growth_is_named_from_the_temperature_channel() {
    let k = vatcal_sim::truth::PaperLikePhysics::paper().thermal_per_k;
    let hidden = Hidden {
        spec: EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature },
        values: vec![(p(EffectParam::ThermalPerKelvin), k)],
    };
    let label = hidden.spec.label();
    for seed in [61u64, 62] {
        let s = common::campaign::campaign_with(seed, std::slice::from_ref(&hidden), 120, demo_style());
        assert!(s.probe.iter().all(|m| m.context.temperature_c.is_some()));
        let d = run(&s);
        eprintln!("thermal (1.5 K) seed {seed}: found {:?}\n{}", names(&d), describe(&d));
        assert!(named_first(&d, &label), "seed {seed}: {:?}\n{}", names(&d), describe(&d));
    }
    let style = common::campaign::Style { temperature: warm_day_temperature, ..demo_style() };
    for seed in [63u64, 64] {
        let s = common::campaign::campaign_with(seed, std::slice::from_ref(&hidden), 120, style);
        let d = run(&s);
        eprintln!("thermal (3 K) seed {seed}: found {:?}\n{}", names(&d), describe(&d));
        let first = d.added_effects.first().expect("an effect is added");
        assert_eq!(first.spec, hidden.spec, "seed {seed}: {:?}", names(&d));
        let fitted = d.model.param(p(EffectParam::ThermalPerKelvin)).expect("coefficient");
        assert!((fitted / k - 1.0).abs() < 0.3, "seed {seed}: fitted {fitted:e} /K, true {k:e} /K");
        assert!(d.final_gap.heldout.rms < d.initial_gap.heldout.rms);
    }
}

/// Backlash of one joint hidden alone at 0.06 arcmin (the top of the paper-like range,
/// 17 µrad), demo campaign shape (each pose once, 12 two-sided repeats): joint 3 is added; joint
/// 5 (shorter lever arm: 2.9 µm change of the predictions on seed 72, at the noise threshold)
/// is named, added or *detected, negligible*. Without the repeats the same data set (each pose
/// once, random approach sides) is printed for comparison: measured, the repeats add little
/// when the approach sides are already random (joint 3: z 6.3 with, 6.1 without; joint 5:
/// 2.9 vs 2.7 µm change of the predictions).
#[test]
fn backlash_is_named_with_two_sided_repeats() {
    let b = (0.06f64 / 60.0).to_radians();
    for (seed, joint) in [(71u64, 3u8), (72, 5)] {
        let hidden = Hidden {
            spec: EffectSpec::JointBacklash { joint },
            values: vec![(p(EffectParam::Backlash { joint }), b)],
        };
        let s = common::campaign::campaign_with(seed, std::slice::from_ref(&hidden), 120, demo_style());
        let d = run(&s);
        eprintln!("backlash j{joint} seed {seed}, 12 repeats: found {:?}\n{}", names(&d), describe(&d));
        let none = common::campaign::Style { two_sided_repeats: Some(0), ..demo_style() };
        let d0 = run(&common::campaign::campaign_with(seed, std::slice::from_ref(&hidden), 120, none));
        eprintln!("backlash j{joint} seed {seed}, no repeats: found {:?}\n{}", names(&d0), describe(&d0));
        if joint == 3 {
            assert_eq!(
                names(&d).first(),
                Some(&("joint-backlash".to_string(), Some(joint))),
                "seed {seed}: {:?}",
                names(&d)
            );
        } else {
            assert!(named_first(&d, &hidden.spec.label()), "seed {seed}: {:?}\n{}", names(&d), describe(&d));
        }
    }
}
