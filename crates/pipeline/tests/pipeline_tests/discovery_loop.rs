//! The discovery stage's **measurement loop** on the in-process virtual cell (issue 21 item
//! 3): a gear error at the size rule's threshold is called *detected, negligible* by the
//! first discovery (3.3 µm < 3.5 µm); the stage proposes measurements for it, measures them on the same devices
//! (journaled), rediscovers on all data and reports before / after. Recomputing the stage from
//! the journals gives the same outcome.

use vatcal_campaign::{CampaignConfig, CellDevices};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::EffectParam;
use vatcal_core::{CellFile, ParamId, ParamSet};
use vatcal_hardware_traits::{TriCal, VirtualClock};
use vatcal_identification::{IdentifyOptions, identify};
use vatcal_kinematics::Model;
use vatcal_pipeline::discovery_loop::LOOP_JOURNAL;
use vatcal_pipeline::discovery_stage::{DiscoveryStageOptions, discovery_recompute, discovery_stage};
use vatcal_pipeline::{DeviceSet, NoProgress, RunOptions, RunSizes};
use vatcal_sim::truth::{
    ErrorBudget, ProbeNoise, perturbed_truth, probe_start_poses, synthetic_probe_measurements,
};
use vatcal_sim::{SimArm, SimConfig, SimGauge, SimGuide, SimOperator, VirtualCell};

struct Devices {
    arm: SimArm,
    guide: SimGuide,
    probe: TriCal<SimGauge>,
    operator: SimOperator,
    clock: VirtualClock,
}

impl DeviceSet for Devices {
    fn devices(&mut self) -> CellDevices<'_> {
        CellDevices {
            arm: &mut self.arm,
            guide: Some(&mut self.guide),
            probe: &mut self.probe,
            tracker: None,
            operator: &mut self.operator,
            clock: &self.clock,
            thermometer: None,
        }
    }
}

fn nominal() -> CellFile {
    CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture")
}

const SEED: u64 = 3;
/// at the size rule's threshold with the 30 + 60 measurements of the first discovery
const AMPLITUDE_DEG: f64 = 0.0018;

fn truth(model: &Model) -> Model {
    let mut truth = perturbed_truth(model, SEED, &ErrorBudget::realistic());
    truth.enable_effect(EffectSpec::JointCyclic { joint: 5, harmonic: 1 }).expect("effect");
    let id = ParamId::Effect(EffectParam::CyclicSin { joint: 5, harmonic: 1 });
    truth.set_param(id, AMPLITUDE_DEG.to_radians()).expect("value");
    truth
}

fn devices(cell: &VirtualCell) -> Devices {
    Devices {
        arm: cell.arm(),
        guide: cell.guide().expect("guide"),
        probe: cell.probe().expect("probe"),
        operator: cell.operator(),
        clock: cell.clock(),
    }
}

#[test]
fn the_loop_measures_what_decides_a_borderline_gear_error() {
    let cell_file = nominal();
    let model = Model::from_cell(&cell_file).expect("model");
    let truth = truth(&model);
    let cell = VirtualCell::new(model.clone(), truth.clone(), SimConfig::default(), SEED);
    let mut dev = devices(&cell);
    // the calibration: 60 probe poses of the truth, the 34 parameters identified
    let calibration =
        synthetic_probe_measurements(&truth, &probe_start_poses(&model, 60, 5), ProbeNoise::default(), 6);
    let fit = identify(&model, &calibration, &ParamSet::paper34(), &IdentifyOptions::default()).expect("fit");
    let opts = RunOptions {
        seed: SEED,
        nominal: cell_file,
        sizes: RunSizes { orientations: 60, guide_steps: 3, count: 40, random_poses: 30, slices: 20 },
        campaign: CampaignConfig {
            show_progress: false,
            skip_failed_measurements: true,
            sync_journal_each_step: false,
            ..CampaignConfig::default()
        },
    };
    let stage = DiscoveryStageOptions {
        count: 30,
        two_sided_repeats: 0,
        loop_count: 40,
        // this test is of the loop's decision, not of the budget (a 40-measurement targeted
        // batch is measured whatever it takes; the budget is tested in the demo's tests)
        budget_s: None,
        ..DiscoveryStageOptions::new(SEED).with_instrument_noise(0.002, 0.0067)
    };
    let dir = tempfile::tempdir().expect("tmp");
    let o = discovery_stage(
        &opts,
        &stage,
        &mut dev,
        &model,
        &fit.model,
        &fit.params,
        &calibration,
        None,
        dir.path(),
        opts.campaign.clone(),
        &mut NoProgress,
    )
    .expect("stage");
    let l = o.measurement_loop.as_ref().expect("a loop is configured");
    for line in l.lines() {
        eprintln!("{line}");
    }
    assert!(l.ran, "{}", l.reason);
    let label = EffectSpec::JointCyclic { joint: 5, harmonic: 1 }.label();
    let t = l.targets.iter().find(|t| t.label == label).expect("the gear error is targeted");
    // undecided either by the size rule or, since rival resolution, as the simpler-chosen rival of
    // the joint's scale error (the two are near-equivalent on the screening data)
    assert!(
        t.before.starts_with("detected, negligible") || t.before.starts_with("rival of"),
        "borderline before the loop: {}",
        t.before
    );
    assert!(!l.effects_before.contains(&label), "undecided before the loop: {:?}", l.effects_before);
    assert!(l.measured > 0 && l.measured <= l.proposed && l.proposed == 40);
    assert!(dir.path().join(LOOP_JOURNAL).exists());
    for p in &t.params {
        assert!(p.std_predicted < p.std_before, "{p:?}");
        // the measurements actually made deliver most of the predicted gain
        assert!(p.std_achieved < p.std_before, "{p:?}");
    }
    assert!(t.decision.starts_with("added"), "decided by the loop: {}", t.decision);
    assert!(l.effects_after.contains(&label));
    assert_eq!(o.total_measurements, calibration.len() + o.extra_measurements + l.measured);

    // recomputed from the journals (no devices): the same outcome
    let again = discovery_recompute(&opts, &stage, &model, &fit.model, &fit.params, &calibration, dir.path())
        .expect("recompute");
    assert_eq!(again.measurement_loop, o.measurement_loop);
    assert_eq!(again.discovery.params, o.discovery.params);
}
