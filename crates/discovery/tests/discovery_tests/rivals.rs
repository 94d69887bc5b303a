//! Near-equivalent candidates (issue 21, item 2): on the canonical cell the compliance of
//! joint 2 and a carriage tilt correct nearly the same thing on probe data near the tank (the
//! carriage's gravity moment is τ₂). With the compliance hidden, the rival with fewer
//! parameters or the better validation predictions must be kept, and the report must name the
//! ambiguity.

use crate::common;

use common::scenario;
use vatcal_core::ParamSet;
use vatcal_core::effects::{EffectKind, EffectSpec};
use vatcal_discovery::{DiscoverOptions, discover};

#[test]
fn hidden_joint_2_compliance_is_not_replaced_by_a_carriage_tilt() {
    // only joint 2 yields
    let s = scenario(23, &[], Some([4e-4, 0.0, 0.0, 0.0, 0.0, 0.0]), 180);
    let d = discover(
        &common::nominal(),
        &s.probe,
        &ParamSet::geometric(),
        Some(&s.validation),
        &DiscoverOptions::default(),
    )
    .expect("discovery runs");
    for r in &d.rounds {
        eprintln!("round {}: {}", r.index, r.decision);
    }
    for a in &d.ambiguities {
        eprintln!("ambiguity: {}", a.sentence);
    }
    let kinds: Vec<EffectKind> = d.added_effects.iter().map(|a| a.spec.kind()).collect();
    assert!(
        d.added_effects.iter().any(|a| a.spec == EffectSpec::JointCompliance { joint: 2 }),
        "{:?}",
        d.added_effects.iter().map(|a| &a.label).collect::<Vec<_>>()
    );
    assert!(!kinds.contains(&EffectKind::GuideCarriageTilt), "{kinds:?}");
}

/// Benchmark seed 21, case 35 (UR5e, tracker rows with replicates, noise given; a tool-frame
/// offset of 0.9× the noise and an out-of-plane bending of 1.0× hidden): `tool-frame` and
/// `tcp-offset (TCP 1)` are rivals on the screening data, and the validation rows favour the
/// tool frame at z ≈ 6. The simpler TCP offset used to be kept ("the data cannot tell them
/// apart"); a rival the validation rows show significantly worse is no longer "simpler but
/// indistinguishable", and the tool frame is kept.
#[test]
fn a_simpler_rival_the_validation_rows_reject_is_not_kept() {
    use crate::common::benchmark::{Case, DataKind, HiddenEffect, Robot, Shape, run_case_with};
    // the case as the generator drew it before its third round (the stream changed since)
    let hidden = |shape, m| HiddenEffect { shape, values: Vec::new(), requested_multiple: m, multiple: m };
    let case = Case {
        id: 35,
        seed: 38_928_441_377_684,
        robot: Robot::Ur5e,
        data: DataKind::Tracker,
        replicates: true,
        noise_metadata: true,
        hidden: vec![
            hidden(Shape::Catalog(EffectSpec::ToolFrame), 0.856_867_792_346_727_3),
            hidden(Shape::LinkBending { shoulder: 2, elbow: 3 }, 1.010_112_906_414_332_6),
        ],
    };
    // the catalog as it was: `link-out-of-plane` now names the 1.0× bending first, after which
    // the 0.9× tool frame is not reached (the rivalry this test is about does not arise)
    let r = run_case_with(case, &["link-out-of-plane"]);
    eprintln!(
        "added {:?}; validation {:.4} -> {:.4} mm, floor {:?}",
        r.added, r.start_mm, r.discovered_mm, r.floor_mm
    );
    assert!(r.error.is_none(), "{:?}", r.error);
    assert!(r.added.iter().any(|a| a == "tool-frame"), "{:?}", r.added);
    assert!(!r.added.iter().any(|a| a == "tcp-offset (TCP 1)"), "{:?}", r.added);
}

/// Benchmark generator v3 (frozen), seed 21, case 52 (canonical cell, probe rows with
/// replicates, noise given; the compliances of joints 2–6 missing from the start, a link
/// bending of joint 5 hidden): the greedy search adds `link-bending (joint 6)` in round 4, a
/// look-alike of the missing `joint-compliance (joint 5)` (cosine 0.96 on the data), which
/// then has nothing left to explain. When the forward search stops, the swap check fits the
/// model with the compliance in its place: it predicts the held-out points better (paired
/// z ≈ 3.1), so it is swapped in, the report names the swap, and the validation error moves
/// toward the true-structure floor. With the swap check off, the look-alike stays.
#[test]
fn the_swap_check_replaces_an_early_look_alike_by_the_effect_the_data_hold() {
    use crate::common::benchmark::{CaseData, Generator, generate_with, options_for};
    let mut case = generate_with(Generator::V3, 53, 21).pop().expect("case 52");
    assert_eq!(case.id, 52);
    let data = CaseData::build(&mut case).expect("case data");
    let run = |swap: bool| {
        let options = DiscoverOptions { lookalike_swap: swap, ..options_for(&case, &data) };
        discover(&data.nominal, &data.measurements, &data.params, Some(&data.validation), &options)
            .expect("discovery runs")
    };
    let with = run(true);
    let without = run(false);
    let compliance_5 = EffectSpec::JointCompliance { joint: 5 };
    let has = |d: &vatcal_discovery::Discovery, s: EffectSpec| d.added_effects.iter().any(|a| a.spec == s);
    assert!(
        has(&with, compliance_5),
        "{:?}",
        with.added_effects.iter().map(|a| &a.label).collect::<Vec<_>>()
    );
    assert!(!has(&without, compliance_5));
    let swap = with.ambiguities.iter().find(|a| a.basis == "swap").expect("the swap is reported");
    assert_eq!(swap.chosen, compliance_5.label());
    assert!(swap.sentence.contains("paired z"), "{}", swap.sentence);
    assert!(with.removed_effects.iter().any(|r| r.label == swap.rivals[0]));
    let val = |d: &vatcal_discovery::Discovery| d.final_gap.validation.as_ref().expect("validation").rms;
    assert!(val(&with) < val(&without), "{} vs {}", val(&with), val(&without));
}

/// Benchmark generator v3 (frozen), seed 9001, case 10 (UR5e, probe rows with replicates,
/// noise given; the compliances of joints 2–5 missing from the start, a τ|τ| stiffness of
/// joint 4 hidden): in round 1 the compliance of joint 3 and the stiffness each pass the
/// held-out test but each alone makes the validation rows worse (the other is still missing),
/// so the veto refused both and the run ended at 10.9× the floor with nothing added. Refused
/// only by the veto, they are now members of the round's block, confirmed and vetoed as a
/// whole: the block makes the validation rows better and is added.
#[test]
fn look_alikes_the_veto_refuses_one_at_a_time_are_added_as_a_block() {
    use crate::common::benchmark::{CaseData, Generator, generate_with, options_for};
    let mut case = generate_with(Generator::V3, 11, 9001).pop().expect("case 10");
    assert_eq!(case.id, 10);
    let data = CaseData::build(&mut case).expect("case data");
    let options = options_for(&case, &data);
    let d = discover(&data.nominal, &data.measurements, &data.params, Some(&data.validation), &options)
        .expect("discovery runs");
    let round1 = &d.rounds[0].decision;
    assert!(round1.contains("added together as a block"), "{round1}");
    let added: Vec<EffectSpec> = d.added_effects.iter().map(|a| a.spec).collect();
    assert!(added.contains(&EffectSpec::JointCompliance { joint: 3 }), "{added:?}");
    let val = |g: &vatcal_discovery::workflow::Gap| g.validation.as_ref().expect("validation").mean;
    assert!(
        val(&d.final_gap) < 0.1 * val(&d.initial_gap),
        "{} -> {}",
        val(&d.initial_gap),
        val(&d.final_gap)
    );
}
