//! The default on other chains (issue 29): a MAP fit of the richest set with realistic prior
//! widths, the prior scale chosen by the lowest cross-validated score; priors with any named
//! set; weak directions found from the design.

use nalgebra::{Rotation3, Vector3};
use vatcal_core::{Axis, Measurement, ParamId, ParamSet};
use vatcal_identification::{
    CvOptions, IdentificationReport, IdentifyOptions, KindWeights, PriorKind, PriorOverride, PriorSpec,
    PriorWidths, calibrate, validate, weak_directions,
};
use vatcal_kinematics::Model;
use vatcal_observability::sets::{DataDesign, GenericSet};
use vatcal_sim::truth::{ErrorBudget, perturbed_truth_any_chain, synthetic_tracker_measurements_in_frame};

use crate::common::{set_tcp1, ur5e};

/// Truth with the realistic budget, the marker `marker_mm` from the nominal TCP 1.
fn truth(nominal: &Model, seed: u64, marker_mm: [f64; 3]) -> Model {
    let mut t = perturbed_truth_any_chain(nominal, seed, &ErrorBudget::realistic());
    let tcp = nominal.tcp(1).expect("tcp 1") + Vector3::from(marker_mm);
    set_tcp1(&mut t, tcp);
    t
}

/// Tracker rows of TCP 1 in the instrument frame `y = R x + t`.
fn rows(truth: &Model, n: usize, sigma_mm: f64, seed: u64) -> Vec<Measurement> {
    let r = Rotation3::from_euler_angles(0.4, -1.1, 2.0);
    let t = Vector3::new(900.0, -1700.0, 300.0);
    synthetic_tracker_measurements_in_frame(truth, n, sigma_mm, seed, 1, &r, &t)
}

/// The default fits `kinematic+compliance` with priors, chooses the scale with the lowest CV
/// score (whatever the standard errors say), and every parameter of the robot has its prior
/// in the report while the frame and marker are free.
#[test]
fn the_default_is_the_richest_set_with_the_lowest_scoring_prior_scale() {
    let nominal = ur5e();
    let truth = truth(&nominal, 3, [20.0, -60.0, 40.0]);
    let train = rows(&truth, 40, 0.05, 31);
    let held_out = rows(&truth, 200, 0.0, 32);
    let cal = calibrate(
        &nominal,
        &train,
        "default",
        &DataDesign::default(),
        &IdentifyOptions::default(),
        &CvOptions::default(),
    )
    .expect("calibration");
    let sel = cal.selection.as_ref().expect("cross-validated scale");
    assert_eq!(sel.candidates.len(), CvOptions::default().prior_scales.len());
    assert!(
        sel.candidates.iter().all(|c| c.set == GenericSet::KinematicCompliance && c.prior_scale.is_some())
    );
    assert_eq!(sel.repeats, 3);
    let best = sel
        .candidates
        .iter()
        .filter(|c| c.rejected.is_none())
        .map(|c| c.cv_mse_mm2)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(sel.chosen().cv_mse_mm2, best, "{}", sel.reason);
    assert!(cal.fit.params.iter().any(|p| matches!(p, ParamId::Compliance(_))));
    assert_eq!(cal.prior_sigmas.len(), cal.fit.params.len());
    let report = IdentificationReport::from_calibration(&cal);
    for (p, entry) in cal.fit.params.iter().zip(&report.parameters) {
        let free = matches!(p, ParamId::Base(_) | ParamId::Tcp { .. });
        assert_eq!(entry.prior_sigma_file_units.is_none(), free, "{}", entry.name);
        if let Some(r) = entry.posterior_over_prior {
            assert!(r > 0.0 && r <= 1.0 + 1e-9, "{}: posterior/prior {r}", entry.name);
        }
    }
    // the MAP fit predicts the held-out postures at the noise level (50 µm per axis)
    let after = validate(&cal.fit.model, &held_out).expect("validate").stats;
    assert!(after.rms < 0.08, "held-out RMS {} mm", after.rms);
}

/// `PriorSpec` gives each kind its width × the scale, compliances per their gravity torque,
/// the frames free; an override replaces one kind's width.
#[test]
fn prior_widths_follow_the_kind_and_the_gravity_torques() {
    let nominal = ur5e();
    let train = rows(&truth(&nominal, 4, [0.0, 0.0, 50.0]), 30, 0.05, 41);
    let params = ParamSet(vec![
        ParamId::ThetaOffset(2),
        ParamId::A(3),
        ParamId::Alpha(3),
        ParamId::Beta(2),
        ParamId::Compliance(2),
        ParamId::Compliance(6),
        ParamId::Base(vatcal_core::BaseParam::X),
        ParamId::Tcp { id: 1, axis: Axis::Z },
    ]);
    let spec = PriorSpec::new(PriorWidths::realistic(), 3.0);
    let s = spec.sigmas(&nominal, &train, &params);
    assert!((s[0] - 0.03).abs() < 1e-12 && (s[1] - 3.0).abs() < 1e-12);
    assert!((s[2] - 0.009).abs() < 1e-12 && (s[3] - 0.009).abs() < 1e-12);
    assert!(s[6].is_infinite() && s[7].is_infinite());
    // joint 2 (shoulder) carries the largest torque: its compliance allows 6 mrad there
    let tau2 = train.iter().map(|m| nominal.gravity_torques(&m.q)[1].abs()).fold(0.0, f64::max);
    assert!(tau2 > 1.0, "{tau2}");
    assert!((s[4] * tau2 - 0.006).abs() < 1e-9, "{}", s[4] * tau2);
    // the wrist's reference torque is floored at 10 % of the shoulder's
    assert!(s[5] * 0.1 * tau2 <= 0.006 + 1e-12, "{}", s[5]);
    let o: PriorOverride = "theta_offset=50mrad".parse().expect("override");
    let s2 = spec.with_override(o).sigmas(&nominal, &train, &params);
    assert!((s2[0] - 0.15).abs() < 1e-12 && s2[1] == s[1]);
    assert_eq!(PriorKind::of(ParamId::D(2), &nominal), PriorKind::Length);
}

/// A named set gets priors only when a scale is fixed; then its posterior/prior ratios are
/// reported and the fit is held where the data are weak.
#[test]
fn a_named_set_takes_priors_when_asked() {
    let nominal = ur5e();
    let train = rows(&truth(&nominal, 5, [10.0, 30.0, 70.0]), 30, 0.05, 51);
    let without = calibrate(
        &nominal,
        &train,
        "kinematic",
        &DataDesign::default(),
        &IdentifyOptions { max_condition_number: f64::INFINITY, ..IdentifyOptions::default() },
        &CvOptions::default(),
    )
    .expect("kinematic");
    assert!(without.prior_sigmas.is_empty() && without.selection.is_none());
    let cv = CvOptions { prior_scale: Some(1.0), ..CvOptions::default() };
    let with =
        calibrate(&nominal, &train, "kinematic", &DataDesign::default(), &IdentifyOptions::default(), &cv)
            .expect("kinematic with priors");
    assert_eq!(with.prior_sigmas.len(), with.fit.params.len());
    assert!(with.prior_sigmas.iter().any(|s| s.is_finite()));
}

/// The weak directions are the combinations the data inform less than the prior: every one has
/// λ < 1 and posterior/prior σ = 1/√(1 + λ); the wrist's compliance (gravity torques of a
/// tenth of a N·m) is one, with the advice to load that joint harder; a precise instrument
/// leaves fewer of them than a noisy one.
#[test]
fn weak_directions_are_found_from_the_design_with_what_would_excite_them() {
    let nominal = ur5e();
    let truth = truth(&nominal, 6, [30.0, 0.0, 60.0]);
    let weak_for = |sigma_mm: f64| {
        let train = rows(&truth, 40, sigma_mm, 61);
        let cv = CvOptions { prior_scale: Some(1.0), ..CvOptions::default() };
        let cal =
            calibrate(&nominal, &train, "default", &DataDesign::default(), &IdentifyOptions::default(), &cv)
                .expect("fit");
        // the fit's priors: the realistic widths at x1 (compliances per the start's torques)
        let sigmas = cal.prior_sigmas.clone();
        assert_eq!(sigmas.len(), cal.fit.params.len());
        let weak = weak_directions(
            &cal.fit.model,
            &train,
            &cal.fit.params,
            &sigmas,
            &KindWeights::default(),
            sigma_mm,
        )
        .expect("weak directions");
        (cal, weak)
    };
    let (cal, noisy) = weak_for(0.2);
    for d in &noisy {
        eprintln!("0.2 mm: {}", d.sentence());
        assert!(d.data_over_prior_information < 1.0);
        let r = 1.0 / (1.0 + d.data_over_prior_information).sqrt();
        assert!((d.posterior_over_prior_sigma - r).abs() < 1e-12);
        assert!(!d.parameters.is_empty() && !d.advice.is_empty());
    }
    // calibrate() reports them too (against its own priors, at its own σ̂)
    assert!(!cal.weak_directions.is_empty());
    let wrist = noisy.iter().find(|d| d.parameters.iter().any(|(n, x)| n == "c_6" && x.abs() > 0.9));
    let wrist = wrist.expect("the wrist compliance is a weak direction");
    assert!(wrist.advice.iter().any(|a| a.contains("load joint 6 harder")), "{:?}", wrist.advice);
    let (_, precise) = weak_for(0.002);
    for d in &precise {
        eprintln!("0.002 mm: {}", d.sentence());
    }
    assert!(precise.len() <= noisy.len(), "{} > {}", precise.len(), noisy.len());
}
