//! Discovery benchmarks: the whole `discover` loop on 180 simulated probe measurements
//! (paper noise, 2 µm per axis) from the paper's 34 parameters.
//!
//! * `discovery/null/180` — nothing hidden: one round (fit, 5-fold CV, location, scoring of
//!   ~60 candidates, refits of the screened ones — none here);
//! * `discovery/cyclic-j4/180` — a 0.02° first-harmonic error of joint 4 hidden: two rounds,
//!   with up to 4 refits (each with 5-fold CV) in the first.
//!
//! Data are generated once, seeded, outside the timed loop.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::EffectParam;
use vatcal_core::{CellFile, Measurement, ParamId, ParamSet};
use vatcal_discovery::{DiscoverOptions, discover};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
};

fn canonical() -> Model {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml"))
        .expect("canonical cell fixture");
    Model::from_cell(&cell).expect("model")
}

fn data(nominal: &Model, hidden_cyclic: bool) -> Vec<Measurement> {
    let mut truth = perturbed_truth(nominal, 3, &ErrorBudget::realistic());
    if hidden_cyclic {
        let (joint, harmonic) = (4, 1);
        truth.enable_effect(EffectSpec::JointCyclic { joint, harmonic }).expect("effect");
        truth
            .set_param(ParamId::Effect(EffectParam::CyclicSin { joint, harmonic }), 0.02f64.to_radians())
            .expect("value");
    }
    let starts = probe_start_poses(nominal, 180, 103);
    synthetic_probe_measurements(&truth, &starts, ProbeNoise::default(), 203)
}

fn bench_discovery(c: &mut Criterion) {
    let nominal = canonical();
    let options = DiscoverOptions::default();
    let mut group = c.benchmark_group("discovery");
    group.sample_size(10).measurement_time(Duration::from_secs(20));
    for (name, hidden) in [("null", false), ("cyclic-j4", true)] {
        let m = data(&nominal, hidden);
        let d = discover(&nominal, &m, &ParamSet::paper34(), None, &options).expect("discover");
        eprintln!(
            "discovery bench {name}: {} rounds, added {:?}",
            d.rounds.len(),
            d.added_effects.iter().map(|a| a.label.clone()).collect::<Vec<_>>()
        );
        group.bench_function(format!("{name}/{}", m.len()), |b| {
            b.iter(|| {
                discover(black_box(&nominal), black_box(&m), &ParamSet::paper34(), None, &options)
                    .expect("discover")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_discovery);
criterion_main!(benches);
