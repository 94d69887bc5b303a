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
/// apart"); when the validation rows decide (`DiscoverOptions::validation_decides`, off by
/// default), a rival they show significantly worse is no longer "simpler but
/// indistinguishable", and the tool frame is kept.
#[test]
fn a_simpler_rival_the_validation_rows_reject_is_not_kept() {
    use crate::common::benchmark::{Case, DataKind, HiddenEffect, Robot, Shape, run_case_tuned};
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
    let r = run_case_tuned(case, |o| {
        o.excluded_effects = vec!["link-out-of-plane".to_string()];
        o.validation_decides = true;
    });
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
/// bending of joint 5 hidden): the greedy search adds `link-bending (joint 2)` in round 1 and
/// `link-bending (joint 6)` in round 4, look-alikes of the missing compliances of joints 3
/// and 5 (cosine ≥ 0.95 on the data), which then have nothing left to explain. When the
/// forward search stops, the swap check fits the model with both compliances in place of
/// both bendings — two parameters for four, so simplicity decides unless the held-out points
/// are predicted worse by more than one standard error; here they are predicted better
/// (paired z ≈ 3.5) — the report names the swap and the parameter counts, and the validation
/// error moves to the true-structure floor. With the swap check off, the look-alikes stay.
/// (The run with the validation rows deciding, `DiscoverOptions::validation_decides`: they
/// chose the bendings, and a carriage tilt, over the compliances. Since the τ|τ| terms are
/// proposed with their missing compliances the rounds differ and the check makes two swaps,
/// each by simplicity: the bending of link 6 for c₅, one parameter for two, then the bending of
/// link 2 and the tilt for c₂ and c₃, two for four. By default the validation rows do not
/// decide, and the swap check replaces the one stand-in left, one parameter for two.)
#[test]
fn the_swap_check_replaces_early_look_alikes_by_the_simpler_effects_the_data_hold() {
    let (with, without) = swap_on_and_off(21, 52, true);
    let compliance_3 = EffectSpec::JointCompliance { joint: 3 };
    let compliance_5 = EffectSpec::JointCompliance { joint: 5 };
    assert!(has(&with, compliance_3) && has(&with, compliance_5), "{:?}", labels(&with));
    assert!(!has(&without, compliance_5), "{:?}", labels(&without));
    let swaps: Vec<_> = with.ambiguities.iter().filter(|a| a.basis == "swap").collect();
    for compliance in [compliance_3, compliance_5] {
        assert!(swaps.iter().any(|s| s.chosen.contains(&compliance.label())), "{compliance:?} swapped in");
    }
    for swap in swaps {
        assert!(swap.sentence.contains("fewer parameters ("), "{}", swap.sentence);
        for rival in &swap.rivals {
            assert!(with.removed_effects.iter().any(|r| &r.label == rival), "{rival}");
            assert!(!labels(&with).contains(rival), "{rival}");
        }
    }
    assert!(1.02 * val(&with) < val(&without), "{} vs {}", val(&with), val(&without));
}

/// Benchmark generator v3 (frozen), seed 9001, case 10 (UR5e, probe rows with replicates,
/// noise given; the compliances of joints 2–5 missing from the start, a τ|τ| stiffness of
/// joint 4 hidden): in round 1 the compliance of joint 3 and the stiffness each pass the
/// held-out test but each alone makes the validation rows worse (the other is still missing),
/// so the veto refused both and the run ended at 10.9× the floor with nothing added. Refused
/// only by the veto (when the validation rows decide, `DiscoverOptions::validation_decides`),
/// they are now members of the round's block, confirmed and vetoed as a whole: the block
/// makes the validation rows better and is added.
#[test]
fn look_alikes_the_veto_refuses_one_at_a_time_are_added_as_a_block() {
    use crate::common::benchmark::{CaseData, Generator, generate_with, options_for};
    let mut case = generate_with(Generator::V3, 11, 9001).pop().expect("case 10");
    assert_eq!(case.id, 10);
    let data = CaseData::build(&mut case).expect("case data");
    let options = DiscoverOptions { validation_decides: true, ..options_for(&case, &data) };
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

/// Benchmark generator v3 (frozen), seed 9001, case 52 (the compliances of joints 2–6 missing
/// from the start, a τ|τ| stiffness of joint 2 hidden): the forward search lets
/// `guide-carriage-tilt` (two parameters) stand in for the compliance and the stiffness of
/// joint 2 (one each), and the run ended at 1.45× the floor. Neither of the two predicts the
/// held-out points better than the tilt alone, so the one-for-one swap never fired; the swap
/// check now also tries two look-alikes of one addition in its place (no more parameters
/// together): both are swapped in at paired z ≈ 3, the report names the swap, and the
/// validation error comes down to the floor. (Since the τ|τ| term is proposed with its missing
/// compliance, the pair is one candidate of two parameters: a one-for-one swap, z = 2.98,
/// recorded as both effects.)
#[test]
fn two_look_alikes_replace_the_one_effect_standing_in_for_both() {
    let (with, without) = swap_on_and_off(9001, 52, false);
    let compliance_2 = EffectSpec::JointCompliance { joint: 2 };
    let stiffness_2 = "joint-stiffness-nonlinear (joint 2)";
    assert!(
        has(&with, compliance_2) && labels(&with).iter().any(|l| l == stiffness_2),
        "{:?}",
        labels(&with)
    );
    assert!(!has(&with, EffectSpec::GuideCarriageTilt), "{:?}", labels(&with));
    assert!(has(&without, EffectSpec::GuideCarriageTilt), "{:?}", labels(&without));
    let swap = with
        .ambiguities
        .iter()
        .find(|a| a.basis == "swap" && a.chosen.contains(&compliance_2.label()))
        .expect("the swap is reported");
    assert!(swap.chosen.contains(stiffness_2), "{}", swap.chosen);
    assert!(swap.sentence.contains("paired z"), "{}", swap.sentence);
    assert_eq!(swap.rivals, vec![EffectSpec::GuideCarriageTilt.label()]);
    assert!(val(&with) < 0.8 * val(&without), "{} vs {}", val(&with), val(&without));
}

/// Discovery on benchmark generator v3 (frozen) case `id` of `seed`, with the swap check on
/// and off (`validation_decides`: [`DiscoverOptions::validation_decides`]).
fn swap_on_and_off(
    seed: u64,
    id: usize,
    validation_decides: bool,
) -> (vatcal_discovery::Discovery, vatcal_discovery::Discovery) {
    use crate::common::benchmark::{CaseData, Generator, generate_with, options_for};
    let mut case = generate_with(Generator::V3, id + 1, seed).pop().expect("the case");
    assert_eq!(case.id, id);
    let data = CaseData::build(&mut case).expect("case data");
    let run = |swap: bool| {
        let options =
            DiscoverOptions { lookalike_swap: swap, validation_decides, ..options_for(&case, &data) };
        discover(&data.nominal, &data.measurements, &data.params, Some(&data.validation), &options)
            .expect("discovery runs")
    };
    let (with, without) = (run(true), run(false));
    eprintln!("with: {:?}\nwithout: {:?}", labels(&with), labels(&without));
    for a in &with.ambiguities {
        eprintln!("{}", a.sentence);
    }
    (with, without)
}

/// With the swap check (`with`) the effects `ins` are named and the `outs` gone, swapped out in
/// one reported swap whose sentence says `why`; without it (`without`) the `outs` stay.
fn assert_swapped(
    (with, without): (&vatcal_discovery::Discovery, &vatcal_discovery::Discovery),
    ins: &[EffectSpec],
    outs: &[String],
    why: &str,
) {
    assert!(ins.iter().all(|c| has(with, *c)), "{:?}", labels(with));
    assert!(!labels(with).iter().any(|l| outs.contains(l)), "{:?}", labels(with));
    assert!(outs.iter().all(|l| labels(without).contains(l)), "{:?}", labels(without));
    let swap = with.ambiguities.iter().find(|a| a.basis == "swap").expect("the swap is reported");
    assert_eq!(swap.rivals, outs.to_vec());
    assert!(swap.sentence.contains(why), "{}", swap.sentence);
}

fn labels(d: &vatcal_discovery::Discovery) -> Vec<String> {
    d.added_effects.iter().map(|a| a.label.clone()).collect()
}

fn has(d: &vatcal_discovery::Discovery, s: EffectSpec) -> bool {
    d.added_effects.iter().any(|a| a.spec == s)
}

fn val(d: &vatcal_discovery::Discovery) -> f64 {
    d.final_gap.validation.as_ref().expect("validation").rms
}

/// Benchmark generator v3 (frozen), seed 60606, case 75 (canonical cell, mixed rows; the
/// compliances of joints 2–6 missing from the start): the carriage tilt (round 1) and the
/// bending of link 2 (round 2) stand in for the compliances of joints 2 and 3 so well that
/// later rounds cannot score the compliances at all (their directions lie in the model's
/// span: "not discoverable, absorbed"). The swap check now also tries candidates the model
/// absorbed: the two compliances (two parameters for four) predict the held-out points no
/// worse, so they replace the stand-ins. Each is recorded with its score at the model without
/// the stand-ins, a real test statistic. (The run with the validation rows deciding, as the
/// stand-ins were chosen when the test was written; by default only the tilt stands in, and it
/// is swapped for the absorbed compliance of joint 2.)
#[test]
fn look_alikes_the_model_absorbed_can_replace_what_absorbed_them() {
    let (with, without) = swap_on_and_off(60606, 75, true);
    let compliances = [EffectSpec::JointCompliance { joint: 2 }, EffectSpec::JointCompliance { joint: 3 }];
    let stand_ins = [EffectSpec::GuideCarriageTilt.label(), "link-bending (joint 2)".to_string()];
    assert_swapped((&with, &without), &compliances, &stand_ins, "fewer parameters (2 for 4)");
    for c in compliances {
        let record = with.added_effects.iter().find(|a| a.spec == c).expect("its record");
        assert!(record.score.dof == 1 && record.score.statistic.is_finite() && record.score.statistic > 0.0);
    }
    assert!(val(&with) <= val(&without), "{} vs {}", val(&with), val(&without));
}

/// Benchmark generator v3 (frozen), seed 8128, case 51 (canonical cell, probe rows, noise
/// given; the compliances of joints 2–6 missing from the start, a τ|τ| stiffness of joint 4
/// hidden): the carriage tilt stands in for the compliance of joint 2 and the bending of link
/// 2 for the compliance of joint 3. At the swap check three replacements pass: the tilt for
/// c_2 (paired z ≈ 3.0), the bending for c_3 (z ≈ 2.9) and both for both (z ≈ 2.75). The
/// largest z used to win, and the bending, swapped only later, was never swapped: the run ended
/// with it. Now the choice among the replacements that pass follows the rule that passes each:
/// of those within one standard error of the best z, the one leaving the fewest parameters —
/// both for both, two parameters for four.
#[test]
fn among_passing_swaps_the_smallest_model_within_one_standard_error_is_made() {
    let (with, without) = swap_on_and_off(8128, 51, false);
    let compliances = [EffectSpec::JointCompliance { joint: 2 }, EffectSpec::JointCompliance { joint: 3 }];
    let stand_ins = ["link-bending (joint 2)".to_string(), EffectSpec::GuideCarriageTilt.label()];
    assert_swapped((&with, &without), &compliances, &stand_ins, "fewer parameters (2 for 4)");
    assert!(val(&with) <= val(&without), "{} vs {}", val(&with), val(&without));
}

/// Benchmark generator v3 (frozen), seed 21, case 3 (canonical cell, probe rows with
/// replicates, no noise metadata, fixture errors; the compliances of joints 2–6 missing from
/// the start): the carriage tilt (round 1) stands in for the compliance of joint 2, and the
/// search stops in a round whose screening passes nothing. That round had no confirmation
/// baseline, and the swap check, which needs one, was skipped: the stand-in stayed. The check
/// now computes the baseline when it has look-alikes to try, and the compliance replaces the
/// tilt, one parameter for two.
#[test]
fn the_swap_check_runs_when_the_last_round_screens_nothing() {
    let (with, without) = swap_on_and_off(21, 3, false);
    let last = &with.rounds.last().expect("rounds").decision;
    let stand_in = [EffectSpec::GuideCarriageTilt.label()];
    assert_swapped((&with, &without), &[EffectSpec::JointCompliance { joint: 2 }], &stand_in, "1 for 2");
    let swap_round = with.ambiguities.iter().find(|a| a.basis == "swap").expect("the swap").round;
    let screened_nothing = without.rounds.last().expect("rounds").decision.contains("above the threshold");
    assert!(screened_nothing, "{}", without.rounds.last().expect("rounds").decision);
    assert!(swap_round > 1, "{swap_round}: {last}");
    assert!(val(&with) <= val(&without), "{} vs {}", val(&with), val(&without));
    // the search ends with a swap check that keeps the model: every replacement it tried is
    // reported with the addition kept, the look-alike and why
    let kept: Vec<&String> = with.notes.iter().filter(|n| n.contains("swap check: kept")).collect();
    assert!(!kept.is_empty() && kept.iter().all(|n| n.contains("cosine")), "{:?}", with.notes);
}

/// Discovery on benchmark generator v3 (frozen) case `id` of `seed` with the default options.
fn benchmark_case(seed: u64, id: usize) -> vatcal_discovery::Discovery {
    use crate::common::benchmark::{CaseData, Generator, generate_with, options_for};
    let mut case = generate_with(Generator::V3, id + 1, seed).pop().expect("the case");
    assert_eq!(case.id, id);
    let data = CaseData::build(&mut case).expect("case data");
    let d = discover(
        &data.nominal,
        &data.measurements,
        &data.params,
        Some(&data.validation),
        &options_for(&case, &data),
    )
    .expect("discovery runs");
    eprintln!("{:?}", labels(&d));
    d
}

/// The hierarchy principle: the τ|τ| term of a joint's spring is proposed only **with** the
/// joint's linear compliance when that is missing (`ErrorEffect::prerequisites`). Benchmark
/// generator v3 (frozen), seed 60606, case 85 (canonical cell, mixed rows; the compliances of
/// joints 2–6 missing from the start, nothing else hidden): the τ|τ| term of joint 2 used to
/// stand in for c₂ alone in round 2, its quadratic extrapolation left a misfit on the few
/// high-torque poses, and c₂ was then refused by the held-out test (5.0× the floor). Now every
/// compliance is named and no τ|τ| term is added without its joint's compliance.
#[test]
fn a_higher_order_term_never_stands_in_for_its_missing_first_order_term() {
    let d = benchmark_case(60606, 85);
    for joint in 2..=6 {
        assert!(has(&d, EffectSpec::JointCompliance { joint }), "c{joint}: {:?}", labels(&d));
    }
    for a in d.added_effects.iter().filter(|a| a.effect == "joint-stiffness-nonlinear") {
        let joint = a.joint.expect("a joint");
        assert!(has(&d, EffectSpec::JointCompliance { joint }), "{} without c{joint}", a.label);
    }
    // the start's validation error fell to the true-structure floor's level (0.0079 mm)
    assert!(val(&d) < 0.0095, "validation RMS {} mm", val(&d));
}

/// The τ|τ| term proposed with its missing compliance is recorded as two effects, each with
/// its own values: benchmark generator v3 (frozen), seed 21, case 45 (the compliances of joints
/// 2–6 missing from the start; the τ|τ| term of joint 3 and c₃ enter together in round 1).
#[test]
fn a_term_added_with_its_first_order_term_is_recorded_as_two_effects() {
    let d = benchmark_case(21, 45);
    let stiffness = d
        .added_effects
        .iter()
        .find(|a| a.label == "joint-stiffness-nonlinear (joint 3)")
        .expect("the tau|tau| term of joint 3");
    let compliance = d
        .added_effects
        .iter()
        .find(|a| a.spec == EffectSpec::JointCompliance { joint: 3 })
        .expect("the compliance of joint 3");
    assert_eq!(stiffness.round, compliance.round);
    assert!(
        compliance
            .how
            .contains("the first-order term of joint-stiffness-nonlinear (joint 3), fitted with it"),
        "{}",
        compliance.how
    );
    assert_eq!(stiffness.values.keys().collect::<Vec<_>>(), vec!["compliance_quadratic3"]);
    let c3: Vec<(&String, &f64)> = compliance.values.iter().collect();
    assert_eq!(c3.len(), 1, "{c3:?}");
    assert!(c3[0].0.starts_with("c_3") && *c3[0].1 > 0.0, "{c3:?}");
}
