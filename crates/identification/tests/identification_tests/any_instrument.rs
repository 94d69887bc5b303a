//! Calibration of a chain other than the canonical cell from an external instrument whose frame
//! and measured point are unknown, and from fixed points at unknown places (issue 20).
//!
//! The UR5e fixture's truth has perturbed geometry; the instrument's frame is rotated
//! arbitrarily and two metres away; the measured point is 80 mm from the nominal TCP. Judged by
//! predicted positions on postures the fit never saw.

use nalgebra::{Rotation3, Vector3};

use crate::common::{geometry_truth, ur5e, ur5e_cell};
use vatcal_core::{Measurement, PointDistance};
use vatcal_identification::{
    CvOptions, IdentifyOptions, InitOptions, calibrate, identify, initialise, posture_folds, validate,
};
use vatcal_kinematics::Model;
use vatcal_observability::sets::{DataDesign, GenericSet};
use vatcal_sim::truth::{
    ProbeNoise, probe_start_poses, synthetic_probe_measurements, synthetic_tracker_measurements,
    synthetic_tracker_measurements_in_frame,
};

/// Tracker rows of TCP 1 in an instrument frame `y = R x + t`.
fn tracker_rows(
    truth: &Model,
    n: usize,
    sigma_mm: f64,
    seed: u64,
    r: &Rotation3<f64>,
    t: &Vector3<f64>,
) -> Vec<Measurement> {
    synthetic_tracker_measurements_in_frame(truth, n, sigma_mm, seed, 1, r, t)
}

/// The "done" case, as a library call: `default` (cross-validated) from the nominal
/// model reaches the noise floor on 300 held-out postures.
#[test]
fn tracker_frame_anywhere_and_unknown_marker_calibrate_to_the_noise_floor() {
    let nominal = ur5e();
    let truth = geometry_truth(&nominal, 11);
    let r = Rotation3::from_euler_angles(0.9, -0.6, 2.2);
    let t = Vector3::new(1300.0, -1500.0, 500.0);
    assert!(t.norm() > 2000.0);
    let noise = 0.01;
    let train = tracker_rows(&truth, 80, noise, 5, &r, &t);
    let held_out = tracker_rows(&truth, 300, 0.0, 6, &r, &t);
    let cal = calibrate(
        &nominal,
        &train,
        "default",
        &DataDesign::default(),
        &IdentifyOptions::default(),
        &CvOptions::default(),
    )
    .expect("calibration");
    let sel = cal.selection.as_ref().expect("cross-validated default");
    for c in &sel.candidates {
        eprintln!(
            "{:<22} {:>3} params  CV {:>9.4} mm  train {:>9.4} mm  {:?}",
            c.set.name(),
            c.params.len(),
            c.cv_rms_mm,
            c.train_rms_mm,
            c.rejected
        );
    }
    eprintln!("{}", sel.reason);
    assert!(cal.fit.params.iter().any(|p| matches!(p, vatcal_core::ParamId::Tcp { id: 1, .. })));
    let before = validate(&nominal, &held_out).expect("validate").stats;
    let after = validate(&cal.fit.model, &held_out).expect("validate").stats;
    eprintln!("held-out mean {:.3} mm -> {:.5} mm (max {:.5})", before.mean, after.mean, after.max);
    assert!(before.mean > 1000.0, "the instrument frame is far away: {}", before.mean);
    // 10 µm per axis: a 3D noise of ~17 µm per row; the prediction of the fitted model is
    // better than one row's noise
    assert!(after.mean < 0.02 && after.max < 0.06, "{} / {}", after.mean, after.max);
    // the chosen set is not the registration alone: the truth's geometry differs from nominal
    assert_ne!(sel.chosen().set, GenericSet::Registration);
}

/// The registration initialisation converges for any rotation of the instrument frame and a
/// translation of metres (multi-seed): afterwards the full fit converges from it.
#[test]
fn registration_initialisation_converges_for_random_rotations() {
    use rand::{RngExt, SeedableRng};
    let nominal = ur5e();
    let truth = geometry_truth(&nominal, 3);
    let mut rng = rand::rngs::StdRng::seed_from_u64(42);
    for case in 0..12 {
        // uniform random rotation from a random unit quaternion
        let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ));
        let r = q.to_rotation_matrix();
        let t = Vector3::new(
            rng.random_range(-3000.0..3000.0),
            rng.random_range(-3000.0..3000.0),
            rng.random_range(-3000.0..3000.0),
        );
        let rows = tracker_rows(&truth, 40, 0.01, 100 + case, &r, &t);
        let init = initialise(&nominal, &rows, &InitOptions { tcps: vec![1], ..InitOptions::default() })
            .expect("init");
        // what remains is the truth's geometry error (~1 mm), not the frame (metres)
        assert!(init.rms_after_mm < 5.0, "case {case}: {} -> {} mm", init.rms_before_mm, init.rms_after_mm);
        let params = vatcal_observability::sets::generic_set(
            &init.model,
            &rows,
            GenericSet::Kinematic,
            &DataDesign::default(),
        )
        .expect("set");
        let fit = identify(&init.model, &rows, &params, &IdentifyOptions::default()).expect("fit");
        assert!(fit.residual_stats.rms < 0.03, "case {case}: rms {}", fit.residual_stats.rms);
    }
}

/// The UR5e with two sockets 50 mm apart (unknown to the nominal model: placeholder
/// coordinates) and its perturbed truth; the socket ids.
fn two_socket_cell() -> (Model, Model, Vec<u32>) {
    let mut cell = ur5e_cell();
    cell.calibration_positions.truncate(2);
    let ids: Vec<u32> = cell.calibration_positions.iter().map(|p| p.id).collect();
    // the true sockets: 50 mm apart, somewhere in front of the robot
    let sockets = [Vector3::new(420.0, -130.0, 80.0), Vector3::new(420.0 + 30.0, -130.0 + 40.0, 80.0)];
    for (p, s) in cell.calibration_positions.iter_mut().zip(&sockets) {
        (p.x_mm, p.y_mm, p.z_mm) = (s.x, s.y, s.z);
    }
    let true_nominal = Model::from_cell(&cell).expect("model");
    let truth = geometry_truth(&true_nominal, 21);
    // the user's nominal model knows neither socket (placeholder coordinates)
    for (k, p) in cell.calibration_positions.iter_mut().enumerate() {
        (p.x_mm, p.y_mm, p.z_mm) = (100.0 * k as f64, 0.0, 0.0);
    }
    let nominal = Model::from_cell(&cell).expect("model");
    (nominal, truth, ids)
}

/// Socket rows of `truth` (the measured point is TCP 1) with probe noise `sigma_mm`.
fn socket_rows(truth: &Model, count: usize, seed: u64, sigma_mm: f64) -> Vec<Measurement> {
    // start poses reach the socket with the TCP they drew; the synthetic step re-reaches with
    // the measured point (TCP 1)
    let starts: Vec<Measurement> =
        probe_start_poses(truth, count, seed).into_iter().map(|m| Measurement { tcp: 1, ..m }).collect();
    synthetic_probe_measurements(truth, &starts, ProbeNoise { sigma_mm }, seed + 1)
}

/// Two sockets 50 mm apart at unknown places, the measured ball centre unknown: with the known
/// distance as a measurement, `default` predicts held-out postures at the sockets to noise level
/// and keeps the distance; the base pose is absorbed by the points (not identified).
#[test]
fn two_unknown_sockets_with_a_known_distance_identify_to_the_noise_floor() {
    let (nominal, truth, ids) = two_socket_cell();
    let train = socket_rows(&truth, 300, 7, 0.01);
    let held_out = socket_rows(&truth, 200, 8, 0.01);
    assert!(train.len() > 250 && held_out.len() > 150, "{} / {}", train.len(), held_out.len());
    let design = DataDesign {
        free_positions: ids.clone(),
        distances: vec![PointDistance { a: ids[0], b: ids[1], distance_mm: 50.0, sigma_mm: 0.005 }],
        ..DataDesign::default()
    };
    let cal =
        calibrate(&nominal, &train, "default", &design, &IdentifyOptions::default(), &CvOptions::default())
            .expect("calibration");
    let sel = cal.selection.as_ref().expect("cross-validated default");
    for c in &sel.candidates {
        eprintln!(
            "{:<22} {:>3} params  CV {:>9.4} mm  {:?}",
            c.set.name(),
            c.params.len(),
            c.cv_rms_mm,
            c.rejected
        );
    }
    eprintln!("{}", sel.reason);
    assert!(
        !cal.fit.params.iter().any(|p| matches!(p, vatcal_core::ParamId::Base(_))),
        "the unknown points absorb the base pose: {:?}",
        cal.fit.params.names()
    );
    let m = &cal.fit.model;
    let d = (m.position(ids[0]).expect("p") - m.position(ids[1]).expect("p")).norm();
    let after = validate(m, &held_out).expect("validate").stats;
    let before = validate(&nominal, &held_out).expect("validate").stats;
    eprintln!("held-out {:.3} -> {:.5} mm, distance {d:.5} mm", before.mean, after.mean);
    assert!((d - 50.0).abs() < 0.01, "distance {d}");
    assert!(after.mean < 0.03, "held-out mean {} mm", after.mean);
    // regularised toward nominal: the same prediction quality
    let cv = CvOptions { prior_scale: Some(1.0), ..CvOptions::default() };
    let reg = calibrate(&nominal, &train, "default", &design, &IdentifyOptions::default(), &cv)
        .expect("regularised");
    let after_reg = validate(&reg.fit.model, &held_out).expect("validate").stats;
    eprintln!(
        "regularised: {} chosen, held-out {:.5} mm",
        reg.selection.as_ref().expect("cv").chosen().set,
        after_reg.mean
    );
    assert!(after_reg.mean < 0.03, "regularised held-out mean {} mm", after_reg.mean);
}

/// The known distance is weighed against the data's own σ̂, not the a-priori
/// `measurement_sigma_mm`: on noisy socket data (0.2 mm, like the MUKCa rows) the fit is the same
/// whatever a-priori σ is given, and the distance is held to its own σ; with the re-weighting
/// off, the a-priori σ changes the fit (the test can tell).
#[test]
fn a_known_distance_is_weighed_by_the_fits_own_sigma() {
    let (nominal, truth, ids) = two_socket_cell();
    let train = socket_rows(&truth, 120, 17, 0.2);
    let probe = socket_rows(&truth, 60, 18, 0.0);
    let design = DataDesign {
        free_positions: ids.clone(),
        distances: vec![PointDistance { a: ids[0], b: ids[1], distance_mm: 50.0, sigma_mm: 0.01 }],
        ..DataDesign::default()
    };
    let fit_with = |sigma_mm: f64, from_fit: bool| {
        let options = IdentifyOptions {
            measurement_sigma_mm: sigma_mm,
            distance_sigma_from_fit: from_fit,
            max_condition_number: f64::INFINITY,
            ..IdentifyOptions::default()
        };
        let cal = calibrate(&nominal, &train, "kinematic", &design, &options, &CvOptions::default())
            .expect("calibration");
        let m = cal.fit.model;
        let d = (m.position(ids[0]).expect("p") - m.position(ids[1]).expect("p")).norm();
        (m, d)
    };
    let largest_difference = |a: &Model, b: &Model| {
        probe
            .iter()
            .map(|r| (a.tcp_position(&r.q, 1).expect("a") - b.tcp_position(&r.q, 1).expect("b")).norm())
            .fold(0.0f64, f64::max)
    };
    let (small, d_small) = fit_with(0.003, true);
    let (large, d_large) = fit_with(0.3, true);
    let reweighted = largest_difference(&small, &large);
    let (fixed_small, d_fixed_small) = fit_with(0.003, false);
    let (fixed_large, d_fixed_large) = fit_with(0.3, false);
    let fixed = largest_difference(&fixed_small, &fixed_large);
    eprintln!(
        "sigma from the fit: distances {d_small:.5} / {d_large:.5} mm, predictions differ by {reweighted:.2e} mm; \
         a-priori sigma: distances {d_fixed_small:.5} / {d_fixed_large:.5} mm, predictions differ by {fixed:.2e} mm"
    );
    assert!((d_small - 50.0).abs() < 0.01 && (d_large - 50.0).abs() < 0.01, "{d_small} / {d_large}");
    assert!(reweighted < 1e-3, "the a-priori sigma changed the fit by {reweighted} mm");
    assert!(fixed > 10.0 * reweighted.max(1e-6), "without re-weighting the fits should differ: {fixed} mm");
}

/// Folds keep repeated readings of one posture together and depend only on the seed.
#[test]
fn posture_folds_are_deterministic_and_keep_postures_together() {
    let nominal = ur5e();
    let mut rows = synthetic_tracker_measurements(&nominal, 30, 0.0, 1);
    let repeats: Vec<Measurement> = rows.iter().take(10).copied().collect();
    rows.extend(repeats);
    let (a, k) = posture_folds(&rows, 5, 9);
    let (b, _) = posture_folds(&rows, 5, 9);
    let (c, _) = posture_folds(&rows, 5, 10);
    assert_eq!(k, 5);
    assert_eq!(a, b);
    assert_ne!(a, c);
    for i in 0..10 {
        assert_eq!(a[i], a[30 + i], "a repeated posture stays in its fold");
    }
}
