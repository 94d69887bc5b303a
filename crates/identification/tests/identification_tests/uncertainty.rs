//! Per-kind σ and the propagation of CMM coordinate errors, checked against simulation.

use nalgebra::Vector3;
use vatcal_core::params::Axis;
use vatcal_core::{CellFile, Measurement, ParamId, ParamSet};
use vatcal_identification::{CmmUncertainty, IdentifyOptions, KindSigmas, KindWeights, identify};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ProbeNoise, probe_start_poses, synthetic_probe_measurements, synthetic_tracker_measurements,
};

fn nominal() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture");
    Model::from_cell(&cell).expect("model")
}

/// A 10 µm CMM error of one ball: the fit absorbs part of it, the rest shows in the predictions
/// exactly as `A (c_file − c_true)` predicts (noiseless data, so the only error is the CMM one).
#[test]
fn cmm_error_of_a_tcp_propagates_as_predicted() {
    let model = nominal();
    let coord = ParamId::Tcp { id: 1, axis: Axis::X };
    let mut truth = model.clone();
    let delta = 0.010;
    truth.set_param(coord, model.param(coord).expect("tcp") + delta).expect("set");
    let starts = probe_start_poses(&model, 90, 3);
    let ms = synthetic_probe_measurements(&truth, &starts, ProbeNoise { sigma_mm: 0.0 }, 4);
    let fit = identify(&model, &ms, &ParamSet::paper34(), &IdentifyOptions::default()).expect("fit");
    let cmm = CmmUncertainty::new(&fit, &ms, &KindWeights::default(), 0.002).expect("cmm");
    let k = cmm.coordinates.index_of(coord).expect("coordinate is propagated");
    let poses = synthetic_tracker_measurements(&truth, 40, 0.0, 5);
    let mut worst: f64 = 0.0;
    let mut size: f64 = 0.0;
    for m in &poses {
        let actual =
            fit.model.tcp_position(&m.q, m.tcp).expect("fk") - truth.tcp_position(&m.q, m.tcp).expect("fk");
        let a = cmm.sensitivity(&fit, &m.q, m.tcp).expect("A");
        let predicted = Vector3::new(a[(0, k)], a[(1, k)], a[(2, k)]) * (-delta);
        worst = worst.max((actual - predicted).norm());
        size = size.max(actual.norm());
    }
    eprintln!("largest prediction error {size:.5} mm, largest mismatch of A·dc {worst:.2e} mm");
    assert!(size > 1e-3, "the CMM error must matter: {size}");
    assert!(worst < 0.02 * size, "{worst} vs {size}");
    // the total σ includes the systematic part
    let m = &poses[0];
    let stat = fit.predicted_position_sigma(&m.q, m.tcp).expect("sigma");
    let total = cmm.total_sigma(&fit, &m.q, m.tcp).expect("total");
    assert!(total.norm() > stat.norm());
    let zero = CmmUncertainty::new(&fit, &ms, &KindWeights::default(), 0.0).expect("cmm");
    assert!(zero.covariance(&fit, &m.q, m.tcp).expect("cov").norm() == 0.0);
}

#[test]
fn kind_sigmas_are_estimated_per_group_and_turned_into_weights() {
    let model = nominal();
    let mut ms: Vec<Measurement> = probe_start_poses(&model, 60, 7);
    ms.extend(synthetic_tracker_measurements(&model, 60, 0.0, 8));
    // residuals 2 µm (probe) and 8 µm (tracker) per axis
    let r: Vec<Vector3<f64>> = ms
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let s = if m.position().is_some() { 0.002 } else { 0.008 };
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            Vector3::new(s, -s, s) * sign
        })
        .collect();
    let ks = KindSigmas::estimate(&ms, &r, 0);
    assert!((ks.probe_mm.expect("probe") - 0.002).abs() < 1e-12);
    assert!((ks.tracker_mm.expect("tracker") - 0.008).abs() < 1e-12);
    let w = ks.weights();
    assert!((w.probe - 1.0).abs() < 1e-12 && (w.tracker - 1.0 / 16.0).abs() < 1e-12);
    // one kind only: default weights
    let probe_only = KindSigmas::estimate(&ms[..60], &r[..60], 34);
    assert!(probe_only.tracker_mm.is_none() && probe_only.weights() == KindWeights::default());
}
