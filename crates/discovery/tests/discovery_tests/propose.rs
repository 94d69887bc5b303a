//! `vatcal_discovery::propose`: the measurements a borderline candidate needs, simulated on the
//! truth, settle it; as many random measurements from the same pool determine it less well.

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use vatcal_core::Measurement;
use vatcal_core::effects::EffectSpec;
use vatcal_discovery::propose::{design_quality, focus_effects, propose};
use vatcal_discovery::{Discovery, discover};
use vatcal_identification::KindWeights;

use crate::common::benchmark::{CaseData, discover_probe_case, probe_case_with};

fn case_with(seed: u64, spec: EffectSpec, m: f64) -> CaseData {
    probe_case_with(seed, spec, m)
}

fn run(d: &CaseData, ms: &[Measurement], seed: u64) -> Discovery {
    discover_probe_case(d, ms, seed)
}

fn added(d: &Discovery, spec: &EffectSpec) -> bool {
    d.added_effects.iter().any(|a| a.spec == *spec)
}

/// A first-harmonic gear error on joint 5 at 0.8 × the noise, 120 probe rows: discovery sees it
/// (best candidate) but calls it negligible. 40 measurements proposed for it from a pool of 300
/// poses, measured on the truth, settle it (added on the rerun); the proposal's predicted
/// standard deviations of its two parameters are below those of 40 random poses of the same
/// pool (which, measured, leave it undecided on this seed).
#[test]
fn proposed_measurements_settle_a_borderline_effect_better_than_random_ones() {
    let seed = 1;
    let spec = EffectSpec::JointCyclic { joint: 5, harmonic: 1 };
    let d = case_with(seed, spec, 0.8);
    let first = run(&d, &d.measurements, seed);
    assert!(!added(&first, &spec), "not borderline: already added");
    // the proposal for the borderline effect alone (with two, the second borderline candidate —
    // a generic `link-out-of-plane` tilt of the wrist that explains the same few micrometres —
    // takes half of the 40 measurements' information, and the rerun calls the 0.8× effect
    // negligible: 3.4 µm against 3.5 µm)
    let focus = focus_effects(&first, &d.measurements, 1);
    assert!(focus.contains(&spec), "focus {:?}", focus.iter().map(EffectSpec::label).collect::<Vec<_>>());
    let pool = vatcal_sim::truth::probe_start_poses(&d.nominal, 300, seed + 1000);
    let n = 40;
    let w = KindWeights::default();
    let p = propose(&first.model, &first.params, &d.measurements, &focus, &pool, n, &w).expect("propose");
    assert_eq!(p.selected.len(), n);
    let proposed: Vec<Measurement> = p.selected.iter().map(|i| pool[*i]).collect();
    let mut idx: Vec<usize> = (0..pool.len()).collect();
    idx.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let random: Vec<Measurement> = idx[..n].iter().map(|i| pool[*i]).collect();
    let (ln_ds_random, std_random) =
        design_quality(&first.model, &first.params, &d.measurements, &focus, &random, &w).expect("quality");
    let (ln_ds_check, std_check) =
        design_quality(&first.model, &first.params, &d.measurements, &focus, &proposed, &w).expect("quality");
    eprintln!(
        "std before {:?}, proposed {:?}, random {:?}; ln Ds {:.2} -> {:.2} (random {:.2})",
        p.std_before, p.std_after, std_random, p.ln_ds_before, p.ln_ds_after, ln_ds_random
    );
    // the proposal's own bookkeeping agrees with a fresh evaluation of the same design
    assert!((ln_ds_check - p.ln_ds_after).abs() < 1e-6 * p.ln_ds_after.abs().max(1.0));
    for (a, b) in std_check.iter().zip(&p.std_after) {
        assert!((a - b).abs() <= 1e-6 * b, "{a} vs {b}");
    }
    assert!(p.ln_ds_after > ln_ds_random, "Ds: proposed {} <= random {ln_ds_random}", p.ln_ds_after);
    for (k, (a, r)) in p.std_after.iter().zip(&std_random).enumerate() {
        assert!(a < r, "{}: proposed σ {a} >= random σ {r}", p.focus_params[k]);
    }
    let with = |extra: &[Measurement]| {
        let more = d.measure_more(extra, seed + 7);
        let all: Vec<Measurement> = d.measurements.iter().chain(&more).copied().collect();
        run(&d, &all, seed)
    };
    let after_proposed = with(&proposed);
    let after_random = with(&random);
    eprintln!(
        "rerun with proposed: {:?}; with random: {:?}",
        after_proposed.added_effects.iter().map(|a| a.label.clone()).collect::<Vec<_>>(),
        after_random.added_effects.iter().map(|a| a.label.clone()).collect::<Vec<_>>()
    );
    assert!(added(&after_proposed, &spec), "the proposed measurements did not settle it");
}

/// The worked example of `docs/discovery.md` ("Asking for the data it needs"), on a case of
/// the benchmark: seed 21, case 5 (canonical cell, 120 probe rows, noise given; a gear error
/// `joint-cyclic (joint 5, harmonic 1)` of 1.0× the noise and a backlash of joint 3 of 0.6×
/// hidden, nothing added). 40 measurements proposed for the borderline candidates from a pool
/// of 300 probe poses, measured on the case's truth, against 40 random poses of the same pool.
/// Prints the numbers the guide quotes; asserts only that the proposal is at least as
/// informative on its focus as the random poses (the guide reports what the reruns add).
#[test]
#[ignore = "a worked example (about a minute): --ignored --nocapture"]
fn benchmark_case_worked_example() {
    use crate::common::benchmark::{generate, options_for};
    let mut case = generate(6, 21).remove(5);
    let d = CaseData::build(&mut case).expect("case 5");
    let options = options_for(&case, &d);
    let run = |ms: &[Measurement]| {
        discover(&d.nominal, ms, &d.params, Some(&d.validation), &options).expect("discover")
    };
    let validation = |x: &Discovery| x.final_gap.validation.as_ref().map_or(f64::NAN, |v| v.mean);
    let labels = |x: &Discovery| x.added_effects.iter().map(|a| a.label.clone()).collect::<Vec<_>>();
    let first = run(&d.measurements);
    eprintln!("hidden: {:?}", case.hidden.iter().map(|h| (h.shape.label(), h.multiple)).collect::<Vec<_>>());
    eprintln!("first run: added {:?}, validation {:.4} mm", labels(&first), validation(&first));
    if let Some(r) = first.rounds.last() {
        eprintln!("last round: {}", r.decision);
    }
    let focus = focus_effects(&first, &d.measurements, 2);
    eprintln!("focus: {:?}", focus.iter().map(EffectSpec::label).collect::<Vec<_>>());
    let pool = vatcal_sim::truth::probe_start_poses(&d.nominal, 300, 1021);
    let n = 40;
    let w = KindWeights::default();
    let p = propose(&first.model, &first.params, &d.measurements, &focus, &pool, n, &w).expect("propose");
    let proposed: Vec<Measurement> = p.selected.iter().map(|i| pool[*i]).collect();
    let mut idx: Vec<usize> = (0..pool.len()).collect();
    idx.shuffle(&mut ChaCha8Rng::seed_from_u64(21));
    let random: Vec<Measurement> = idx[..n].iter().map(|i| pool[*i]).collect();
    let (ln_ds_random, std_random) =
        design_quality(&first.model, &first.params, &d.measurements, &focus, &random, &w).expect("quality");
    eprintln!(
        "focus parameters {:?}: std per unit noise before {:?}, proposed {:?}, random {:?}; ln Ds {:.2} -> {:.2} (random {:.2})",
        p.focus_params, p.std_before, p.std_after, std_random, p.ln_ds_before, p.ln_ds_after, ln_ds_random
    );
    for (name, extra) in [("proposed", &proposed), ("random", &random)] {
        let more = d.measure_more(extra, 21 + 7);
        let all: Vec<Measurement> = d.measurements.iter().chain(&more).copied().collect();
        let x = run(&all);
        eprintln!("rerun with the {n} {name}: added {:?}, validation {:.4} mm", labels(&x), validation(&x));
    }
    assert!(p.ln_ds_after >= ln_ds_random, "Ds: proposed {} < random {ln_ds_random}", p.ln_ds_after);
}
