//! The canonical 7-joint Meca500-on-guide cell gives the same numbers as before the chain
//! became generic (issue 12): FK of the three TCPs at three joint vectors on the nominal model,
//! with compliances and beta, and with every guide/joint/tool/thermal effect switched on, plus
//! gravity torques and one Jacobian column. The reference values were printed by the code of
//! commit a48edf8 (JointVector = [f64; 7]) with this same model construction.

#![allow(clippy::excessive_precision)] // reference values printed with 17 significant digits

use vatcal_core::effects::{EffectSpec, ThermalDriver};
use vatcal_core::measurement::dirs_from_meca500_arm;
use vatcal_core::params::{Axis, EffectParam};
use vatcal_core::{CellFile, JointVector, MeasurementContext, ParamId, ParamSet};
use vatcal_kinematics::Model;

const REFERENCE: &[(&str, usize, u32, [f64; 3])] = &[
    ("nominal", 0, 1, [-3.14108925535776322e1, -2.91149715519133451e2, 1.59485828841499455e2]),
    ("nominal", 0, 2, [-4.48542065236365133e1, -2.94859912651360162e2, 7.97516480421557219e1]),
    ("nominal", 0, 3, [-3.93190846095662039e0, -2.25557312642402991e2, 7.08538789808868046e1]),
    ("nominal", 1, 1, [-2.42791517716458571e1, 8.57769823840148007e1, 3.63899509069242470e2]),
    ("nominal", 1, 2, [-9.84839476444709021e1, 1.17243592892756865e2, 3.56447762055052294e2]),
    ("nominal", 1, 3, [-1.06201849192955734e2, 7.91171510900574333e1, 2.85430415074520340e2]),
    ("nominal", 2, 1, [4.07977012006260082e1, -1.05601528342420750e2, 3.75192304131802075e2]),
    ("nominal", 2, 2, [1.11395976926788734e2, -7.59964737156982011e1, 3.48896828360455459e2]),
    ("nominal", 2, 3, [8.02672062708971339e1, -1.36238301312764776e0, 3.53069032029186815e2]),
    ("compliant", 0, 1, [-3.16039659198795917e1, -2.91097027460736854e2, 1.59050466607661576e2]),
    ("compliant", 0, 2, [-4.49655461629748672e1, -2.94664745498506306e2, 7.92960472792613587e1]),
    ("compliant", 0, 3, [-3.95857950980922269e0, -2.25392450497520372e2, 7.05534520008249331e1]),
    ("compliant", 1, 1, [-2.36222684592912096e1, 8.60731363765886499e1, 3.63358646375435285e2]),
    ("compliant", 1, 2, [-9.78475471759025055e1, 1.17521970128075324e2, 3.56036986992978200e2]),
    ("compliant", 1, 3, [-1.05743961105057721e2, 7.92626131301777832e1, 2.85110804308676961e2]),
    ("compliant", 2, 1, [4.08485916693060460e1, -1.05472333039246621e2, 3.74907558365035868e2]),
    ("compliant", 2, 2, [1.11386527034030252e2, -7.57664755624373925e1, 3.48563877015431558e2]),
    ("compliant", 2, 3, [8.02115127430026291e1, -1.16263319529934606e0, 3.52927399561888876e2]),
    ("effects", 0, 1, [-3.21125524888187073e1, -2.91252735561955660e2, 1.59036270101956006e2]),
    ("effects", 0, 2, [-4.56150488332149280e1, -2.94668794743621618e2, 7.92989452588380175e1]),
    ("effects", 0, 3, [-4.43941523297933216e0, -2.25492465002099095e2, 7.05893102428747454e1]),
    ("effects", 1, 1, [-2.35784705435658672e1, 8.62762401152688341e1, 3.63107995115481003e2]),
    ("effects", 1, 2, [-9.77814330997282610e1, 1.17731901027967041e2, 3.55592039724839424e2]),
    ("effects", 1, 3, [-1.05583936591940670e2, 7.92908829243445155e1, 2.84753743532659712e2]),
    ("effects", 2, 1, [4.13535857202562980e1, -1.05127157067765111e2, 3.75202371472717573e2]),
    ("effects", 2, 2, [1.11782116624828646e2, -7.51832145965159668e1, 3.48835532737248684e2]),
    ("effects", 2, 3, [8.04205190413669442e1, -6.69498676809833881e-1, 3.53397492606684295e2]),
];

const TAU_2_TO_7: [f64; 6] = [
    -7.81463339195954121e-1,
    -2.32451619650806807e0,
    -9.22504096062710888e-1,
    -3.24297813311970551e-1,
    -4.10574590662067251e-1,
    -6.08379364379112858e-2,
];
const JAC_COL0: [f64; 3] = [-2.63536986992978257e2, -1.61369863788944251e-14, 2.02152452824097452e2];
const JAC_SUM_ABS: f64 = 5.84576486884554379e3;

fn models() -> [(&'static str, Model); 3] {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture");
    let nominal = Model::from_cell(&cell).expect("model");
    let mut compliant = nominal.clone();
    for j in 2..=7u8 {
        compliant.set_param(ParamId::Compliance(j), 3e-4 * f64::from(j)).expect("c");
    }
    compliant.set_param(ParamId::Beta(4), 1e-3).expect("beta");
    let mut effects = compliant.clone();
    for spec in [
        EffectSpec::GuideAngular { order: 2 },
        EffectSpec::GuideStraightness { order: 3 },
        EffectSpec::GuideScale,
        EffectSpec::GuideCarriageTilt,
        EffectSpec::JointCyclic { joint: 3, harmonic: 2 },
        EffectSpec::JointBacklash { joint: 5 },
        EffectSpec::JointScale { joint: 6 },
        EffectSpec::ToolFrame,
        EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature },
    ] {
        effects.enable_effect(spec).expect("effect");
    }
    let ids: Vec<ParamId> =
        effects.all_params().0.into_iter().filter(|p| matches!(p, ParamId::Effect(_))).collect();
    for (k, id) in ids.into_iter().enumerate() {
        let k = (k + 1) as f64;
        let v = match id {
            ParamId::Effect(EffectParam::GuideStraightness { .. }) => 0.01 * k,
            ParamId::Effect(EffectParam::ThermalPerKelvin) => 2e-5,
            ParamId::Effect(EffectParam::CarriageTilt { axis: Axis::X }) => 1e-4,
            ParamId::Effect(EffectParam::CarriageTilt { .. }) => -2e-4,
            _ => 1e-4 * k,
        };
        effects.set_param(id, v).expect("set");
    }
    [("nominal", nominal), ("compliant", compliant), ("effects", effects)]
}

fn joint_vectors() -> [JointVector; 3] {
    [
        JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]),
        JointVector::from_mm_deg(12.5, [-100.0, 60.0, -120.0, 150.0, -100.0, 170.0]),
        JointVector::from_mm_deg(290.0, [170.0, -65.0, 65.0, -160.0, 110.0, -175.0]),
    ]
}

#[test]
fn canonical_cell_predictions_are_unchanged() {
    let models = models();
    let qs = joint_vectors();
    let ctx = MeasurementContext {
        dir: Some(dirs_from_meca500_arm([1, -1, 1, -1, 1, -1])),
        time_s: None,
        temperature_c: Some(27.5),
    };
    assert_eq!(REFERENCE.len(), 27);
    for (name, iq, tcp, want) in REFERENCE {
        let model = &models.iter().find(|(n, _)| n == name).expect("model").1;
        let got = model.tcp_position_ctx(&qs[*iq], &ctx, *tcp).expect("fk");
        for a in 0..3 {
            assert!((got[a] - want[a]).abs() < 1e-9, "{name} q{iq} tcp{tcp}: {got} vs {want:?}");
        }
    }
}

#[test]
fn canonical_cell_torques_and_jacobian_are_unchanged() {
    let compliant = &models()[1].1;
    let q = joint_vectors()[1];
    let tau = compliant.gravity_torques(&q);
    assert_eq!(tau[0], 0.0, "the guide carries no torque");
    for k in 0..6 {
        assert!(
            (tau[k + 1] - TAU_2_TO_7[k]).abs() < 1e-12,
            "tau_{}: {} vs {}",
            k + 2,
            tau[k + 1],
            TAU_2_TO_7[k]
        );
    }
    let j = compliant.jacobian(&q, 2, &ParamSet::paper34().0).expect("jacobian");
    for a in 0..3 {
        assert!((j[(a, 0)] - JAC_COL0[a]).abs() < 1e-9);
    }
    let sum: f64 = j.iter().map(|v| v.abs()).sum();
    assert!((sum - JAC_SUM_ABS).abs() < 1e-8, "{sum} vs {JAC_SUM_ABS}");
}
