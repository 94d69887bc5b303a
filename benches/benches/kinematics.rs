//! Forward kinematics and parameter Jacobian benchmarks (issue 2 targets on a 2-core machine:
//! FK of one TCP ≤ 250 ns, 3×34 Jacobian ≤ 1.5 µs).
//!
//! Both are measured on the canonical cell with nonzero compliances (so the gravity-torque
//! recursion is part of every FK call, as it is for a calibrated model).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use vatcal_core::{
    CellFile, EffectSpec, Frame, JointKind, JointVector, MeasurementContext, ParamId, ParamSet,
};
use vatcal_gravity_torque::{GravityModel, gravity_torques_n};
use vatcal_kinematics::Model;

fn calibrated_like_model() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml"))
        .expect("canonical cell fixture");
    let mut model = Model::from_cell(&cell).expect("model");
    for j in 2..=7u8 {
        model.set_param(vatcal_core::ParamId::Compliance(j), 3e-4).expect("compliance");
    }
    model.set_param(vatcal_core::ParamId::Beta(4), 1e-3).expect("beta");
    model
}

fn bench_kinematics(c: &mut Criterion) {
    let model = calibrated_like_model();
    let nominal = {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml"))
            .expect("canonical cell fixture");
        Model::from_cell(&cell).expect("model")
    };
    let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    let ctx = MeasurementContext::default();
    c.bench_function("kinematics/fk_tcp/with_compliance", |b| {
        b.iter(|| model.tcp_position(black_box(&q), 2).expect("fk"))
    });
    // a discovered-like model: catalog effects on top (their values are read inside every FK)
    let mut discovered = model.clone();
    for spec in [
        EffectSpec::JointCyclic { joint: 2, harmonic: 1 },
        EffectSpec::JointCyclic { joint: 3, harmonic: 1 },
        EffectSpec::JointScale { joint: 4 },
        EffectSpec::GuideAngular { order: 2 },
        EffectSpec::GuideStraightness { order: 3 },
        EffectSpec::GuideCarriageTilt,
    ] {
        discovered.enable_effect(spec).expect("effect");
    }
    let effect_params: Vec<ParamId> =
        discovered.all_params().0.into_iter().filter(|p| matches!(p, ParamId::Effect(_))).collect();
    let values: Vec<f64> = (0..effect_params.len()).map(|k| 1e-5 * (k as f64 + 1.0)).collect();
    discovered.set_params(&ParamSet(effect_params), &values).expect("effect values");
    c.bench_function("kinematics/fk_tcp/with_effects", |b| {
        b.iter(|| discovered.tcp_position(black_box(&q), 2).expect("fk"))
    });
    c.bench_function("kinematics/fk_tcp/nominal", |b| {
        b.iter(|| nominal.tcp_position(black_box(&q), 2).expect("fk"))
    });
    let params = ParamSet::paper34();
    let mut out = vec![0.0; 3 * params.len()];
    c.bench_function("kinematics/jacobian_3x34/paper34", |b| {
        b.iter(|| model.jacobian_into(black_box(&q), &ctx, 2, &params.0, &mut out).expect("jacobian"))
    });
    c.bench_function("kinematics/gravity_torques", |b| b.iter(|| model.gravity_torques(black_box(&q))));

    // the torque recursion alone (vatcal-gravity-torque), on the link transforms H_i^{i-1} of
    // the same pose (taken from the world frames, outside the timed loop)
    let frames = nominal.chain_full(&q, &ctx, false, None).frames;
    let links: [Frame; 7] = std::array::from_fn(|k| frames[k].inverse().compose(&frames[k + 1]));
    let kinds: [JointKind; 7] = nominal.joint_kinds().try_into().expect("7 joints");
    let (base, masses, g) = (nominal.base_frame().r, nominal.masses().clone(), nominal.gravity());
    c.bench_function("gravity_torque/recursion_7", |b| {
        b.iter(|| gravity_torques_n(black_box(&links), &kinds, &base, &masses, &g))
    });
    let constants = GravityModel::new(&masses, &base, &g);
    c.bench_function("gravity_torque/precomputed_7", |b| {
        b.iter(|| constants.torques_n(black_box(&links), &kinds))
    });
}

criterion_group!(benches, bench_kinematics);
criterion_main!(benches);
