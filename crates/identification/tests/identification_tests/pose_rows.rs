//! Pose rows (issue 31 item 1): a motion-capture log gives the position and the orientation of
//! the tool body; each row is a tracker measurement plus an orientation measurement. The UR5e
//! fixture's perturbed truth has a tool frame tilted by a few mrad (the `tool-frame` effect) on
//! top of its geometry errors; with pose rows the fit reaches the noise floor on held-out
//! tracker points and predicts the tool's orientation on held-out postures (the tool rotation
//! is recovered), which position rows alone cannot.

use nalgebra::{UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};

use crate::common::{geometry_truth, ur5e};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::{EffectParam, ToolFrameDof};
use vatcal_core::{CellFile, Measurement, ParamId, ParamSet};
use vatcal_identification::{
    FittedScatter, IdentifyOptions, KindSigmas, KindWeights, fit_with_fitted_scatter, identify, validate,
};
use vatcal_kinematics::Model;
use vatcal_observability::sets::{DataDesign, GenericSet, generic_set};
use vatcal_sim::truth::synthetic_tracker_measurements;

const SIGMA_MM: f64 = 0.01;
const SIGMA_RAD: f64 = 1e-3;

fn tool(d: ToolFrameDof) -> ParamId {
    ParamId::Effect(EffectParam::ToolFrame(d))
}

/// The truth: perturbed geometry and a tool frame tilted by (3, -2) mrad.
fn truth(nominal: &Model) -> Model {
    let mut t = geometry_truth(nominal, 11);
    t.enable_effect(EffectSpec::ToolFrame).expect("tool frame");
    t.set_param(tool(ToolFrameDof::Rx), 3e-3).expect("rx");
    t.set_param(tool(ToolFrameDof::Ry), -2e-3).expect("ry");
    t
}

/// Pose rows of the truth: the tracker rows of TCP 1 and, for each, the tool orientation with
/// a rotation noise of `sigma_rad` per axis (world side).
fn pose_rows(truth: &Model, n: usize, sigma_mm: f64, sigma_rad: f64, seed: u64) -> Vec<Measurement> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 1000);
    // Box-Muller
    let mut gauss = move || {
        let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
        sigma_rad * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    let mut out = Vec::new();
    for m in synthetic_tracker_measurements(truth, n, sigma_mm, seed).into_iter().filter(|m| m.tcp == 1) {
        let r = truth.tool_rotation_ctx(&m.q, &m.context).expect("rotation");
        let noise = Vector3::new(gauss(), gauss(), gauss());
        let measured = UnitQuaternion::from_scaled_axis(noise) * UnitQuaternion::from_matrix(&r);
        out.push(m);
        out.push(Measurement::orientation(m.tcp, m.q, measured));
    }
    out
}

/// Kinematic set of the data plus the tool-frame tilts and the last joint's offset (the rotation of
/// the tool about the flange axis).
fn params(start: &Model, rows: &[Measurement]) -> ParamSet {
    let mut set = generic_set(start, rows, GenericSet::Kinematic, &DataDesign::default()).expect("set");
    let last = start.joint_kinds().len() as u8;
    for p in [ParamId::ThetaOffset(last), tool(ToolFrameDof::Rx), tool(ToolFrameDof::Ry)] {
        if !set.0.contains(&p) {
            set.0.push(p);
        }
    }
    set
}

/// Mean angle \[rad\] between the model's and the truth's tool orientation on noise-free
/// orientation rows of the truth.
fn orientation_error(model: &Model, held_out: &[Measurement]) -> f64 {
    let rows: Vec<Measurement> = held_out.iter().filter(|m| m.target.is_orientation()).copied().collect();
    validate(model, &rows).expect("validate").stats.mean
}

#[test]
fn pose_rows_reach_the_noise_floor_and_recover_the_tool_rotation() {
    let nominal = ur5e();
    let truth = truth(&nominal);
    let mut start = nominal.clone();
    start.enable_effect(EffectSpec::ToolFrame).expect("tool frame");
    let train = pose_rows(&truth, 240, SIGMA_MM, SIGMA_RAD, 5);
    let held_out = pose_rows(&truth, 600, 0.0, 0.0, 6);
    let positions = |rows: &[Measurement]| -> Vec<Measurement> {
        rows.iter().filter(|m| !m.target.is_orientation()).copied().collect()
    };
    let set = params(&start, &train);
    let weights = KindWeights { orientation: (SIGMA_MM / SIGMA_RAD).powi(2), ..KindWeights::default() };
    let options = IdentifyOptions { weights, ..IdentifyOptions::default() };
    let fit = identify(&start, &train, &set, &options).expect("fit");
    let held_pos = validate(&fit.model, &positions(&held_out)).expect("validate").stats;
    let rot = orientation_error(&fit.model, &held_out);
    let rot_nominal = orientation_error(&start, &held_out);
    eprintln!(
        "{} rows, {} params: held-out position mean {:.5} mm (max {:.5}), orientation {:.3} mrad (nominal {:.3})",
        train.len(),
        set.len(),
        held_pos.mean,
        held_pos.max,
        1e3 * rot,
        1e3 * rot_nominal
    );
    // the fitted scatter of each kind is its noise
    let sigmas = KindSigmas::estimate(&train, &fit.residuals, set.len());
    let sigma_rad = KindSigmas::orientation_rad(&train, &fit.residuals, set.len()).expect("orientation rows");
    eprintln!("fitted sigma: tracker {:?} mm, orientation {sigma_rad:.2e} rad", sigmas.tracker_mm);
    assert!((sigma_rad / SIGMA_RAD - 1.0).abs() < 0.15, "orientation sigma {sigma_rad}");
    let tracker_sigma = sigmas.tracker_mm.expect("tracker rows");
    assert!((tracker_sigma / SIGMA_MM - 1.0).abs() < 0.15, "tracker sigma {tracker_sigma}");
    let w = sigmas.weights_with_orientation(Some(sigma_rad));
    assert!((w.orientation / 100.0 - 1.0).abs() < 0.35, "orientation weight {}", w.orientation);
    // noise floor on held-out tracker points: better than one row's noise (~17 µm 3D)
    assert!(held_pos.mean < 0.015 && held_pos.max < 0.05, "{} / {}", held_pos.mean, held_pos.max);
    // the tool rotation is recovered: orientation predicted to a quarter of one row's 3-D
    // noise (1 mrad per axis: 1.6 mrad mean); the start is 4.7 mrad off
    assert!(rot_nominal > 3e-3, "the truth's tool is tilted: {rot_nominal}");
    assert!(rot < 4e-4, "held-out orientation error {rot} rad");
    // the iteration log keeps mm and rad apart: position statistics over the tracker rows
    // only (noise ~17 µm 3-D), the orientation rows' RMS in mrad (~1.7 mrad 3-D)
    let last = fit.iterations.last().expect("log");
    assert!(last.rms_mm < 0.03, "position RMS {} mm", last.rms_mm);
    let o = last.orientation_rms_mrad.expect("orientation rows logged");
    assert!((1.0..3.0).contains(&o), "orientation RMS {o} mrad");
    assert!(fit.iterations[0].orientation_rms_mrad.expect("start") > o);
}

/// Position rows alone do not fix the tool's rotation: the same data without the orientation
/// rows predict positions as well but the orientation only as well as the start.
#[test]
fn position_rows_alone_leave_the_tool_rotation_open() {
    let nominal = ur5e();
    let truth = truth(&nominal);
    let train: Vec<Measurement> =
        pose_rows(&truth, 240, SIGMA_MM, 0.0, 5).into_iter().filter(|m| !m.target.is_orientation()).collect();
    let held_out = pose_rows(&truth, 300, 0.0, 0.0, 6);
    let set = generic_set(&nominal, &train, GenericSet::Kinematic, &DataDesign::default()).expect("set");
    let fit = identify(&nominal, &train, &set, &IdentifyOptions::default()).expect("fit");
    let rot = orientation_error(&fit.model, &held_out);
    eprintln!("position rows only: held-out orientation {:.3} mrad", 1e3 * rot);
    assert!(rot > 1e-3, "{rot}");
}

/// The 7R KUKA iiwa 14 (fixtures/real/mukca, from its URDF).
fn iiwa14() -> Model {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/real/mukca/cells/iiwa14.toml");
    Model::from_cell(&CellFile::load(path).expect("fixture")).expect("model")
}

/// The position rows of `rows`.
fn positions(rows: &[Measurement]) -> Vec<Measurement> {
    rows.iter().filter(|m| !m.target.is_orientation()).copied().collect()
}

/// Fits `train` from `start` weighing the orientation rows by their fitted scatter (the
/// library path of `vatcal identify`); returns the held-out position mean and max \[mm\], the
/// held-out orientation error \[rad\] and the scatter.
fn fit_and_score(
    start: &Model,
    train: &[Measurement],
    held_out: &[Measurement],
) -> (f64, f64, f64, FittedScatter) {
    let set = params(start, train);
    let (fit, scatter) = fit_with_fitted_scatter(
        &IdentifyOptions::default(),
        |o| identify(start, train, &set, o),
        |fit, w| FittedScatter::of(train, fit, w),
    )
    .expect("fit");
    let held = validate(&fit.model, &positions(held_out)).expect("validate").stats;
    (held.mean, held.max, orientation_error(&fit.model, held_out), scatter)
}

/// Pose rows alone, and pose rows of half the postures mixed with tracker rows of others, on a
/// 7-joint arm (iiwa 14) and on the UR5e (geometry errors and a (3, -2) mrad tool tilt each):
/// both reach the noise floor on held-out tracker points and predict the tool's orientation
/// (the tool rotation is recovered), weighed by their fitted scatter.
#[test]
fn pose_rows_alone_and_mixed_reach_the_noise_floor_on_a_7_joint_arm_and_the_ur5e() {
    assert_eq!(iiwa14().joint_kinds().len(), 7);
    for (arm, nominal, draws) in [("iiwa14", iiwa14(), 120), ("UR5e", ur5e(), 240)] {
        let truth = truth(&nominal);
        let mut start = nominal.clone();
        start.enable_effect(EffectSpec::ToolFrame).expect("tool frame");
        let held_out = pose_rows(&truth, 2 * draws, 0.0, 0.0, 26);
        let rot_nominal = orientation_error(&start, &held_out);
        let alone = pose_rows(&truth, draws, SIGMA_MM, SIGMA_RAD, 25);
        let mut mixed = pose_rows(&truth, draws / 2, SIGMA_MM, SIGMA_RAD, 25);
        mixed.extend(synthetic_tracker_measurements(&truth, 2 * draws / 3, SIGMA_MM, 27));
        for (name, train) in [("pose rows alone", &alone), ("pose + tracker rows", &mixed)] {
            let (mean, max, rot, s) = fit_and_score(&start, train, &held_out);
            eprintln!(
                "{arm}, {name} ({} rows): held-out position mean {mean:.5} mm (max {max:.5}), orientation {:.3} mrad (nominal {:.3}); {}",
                train.len(),
                1e3 * rot,
                1e3 * rot_nominal,
                s.one_line()
            );
            let sigma_rad = s.orientation_rad.expect("orientation rows");
            assert!(
                (sigma_rad / SIGMA_RAD - 1.0).abs() < 0.2,
                "{arm}, {name}: orientation sigma {sigma_rad}"
            );
            assert!(mean < 0.015 && max < 0.05, "{arm}, {name}: {mean} / {max}");
            assert!(rot_nominal > 3e-3, "the truth's tool is tilted: {rot_nominal}");
            assert!(rot < 4e-4, "{arm}, {name}: held-out orientation error {rot} rad");
        }
    }
}

/// Orientation noise five times what the default weight assumes (10 µm, 5 mrad): the fitted
/// scatter weighs the orientation rows down to about (0.01 / 0.005)² = 4 mm²/rad² in a few
/// fits, and the held-out positions are no worse than with the default weight.
#[test]
fn a_noisier_orientation_is_weighed_down_by_its_fitted_scatter() {
    let nominal = iiwa14();
    let truth = truth(&nominal);
    let mut start = nominal.clone();
    start.enable_effect(EffectSpec::ToolFrame).expect("tool frame");
    let held_out = pose_rows(&truth, 400, 0.0, 0.0, 36);
    let train = pose_rows(&truth, 120, SIGMA_MM, 5.0 * SIGMA_RAD, 35);
    let (mean, _, _, s) = fit_and_score(&start, &train, &held_out);
    let set = params(&start, &train);
    let fixed = identify(&start, &train, &set, &IdentifyOptions::default()).expect("fit");
    let fixed_mean = validate(&fixed.model, &positions(&held_out)).expect("validate").stats.mean;
    eprintln!("{}; held-out {mean:.5} mm (default weight {fixed_mean:.5} mm)", s.one_line());
    assert!(s.fits >= 2 && s.settled, "{s:?}");
    assert!((s.orientation_weight / 4.0 - 1.0).abs() < 0.35, "{s:?}");
    assert!(mean <= 1.02 * fixed_mean, "{mean} vs {fixed_mean}");
}
