//! Two-sided repeats of a probe campaign (the discovery campaign's backlash excitation): a
//! planned pose measured again right after, approached from the opposite side on every
//! revolute joint.

use vatcal_core::JointVector;
use vatcal_kinematics::Model;

/// Adds up to `count` **two-sided repeats** to a campaign plan: measure steps spread evenly
/// over the plan are each followed by a move that takes every revolute joint `overshoot_rad`
/// past the measurement pose on the side it arrived from and back, and a second measurement
/// of the same ball at the same position. The first measurement of the pose is centred with
/// each joint's last motion in the planned direction `s` (auto-centering keeps the approach
/// side), the repeat with `−s` on every revolute joint, so the pair differs by twice the
/// backlash of every joint (`dir2..dir7` are recorded with each). A pose whose overshoot
/// waypoint would leave the joint limits of `model` is not repeated. Returns the number of
/// repeats added.
///
/// The ball stays on the probe: the overshoot moves it by about `overshoot_rad` times the
/// lever arms (≈ 0.3–0.7 mm for 1 mrad), well inside the gauges' range, like the approach
/// overshoot of auto-centering.
pub fn add_two_sided_repeats(
    plan: &mut vatcal_campaign::CampaignPlan,
    model: &Model,
    count: usize,
    overshoot_rad: f64,
) -> usize {
    use vatcal_campaign::CampaignStep;
    if count == 0 || overshoot_rad <= 0.0 {
        return 0;
    }
    // the planned approach side of every measurement: the sign of the last motion of each
    // revolute joint through the plan's waypoints (0: not moved yet)
    let revolute: Vec<usize> = (0..model.joint_count()).filter(|k| model.is_revolute(k + 1)).collect();
    let mut measures = Vec::new();
    let mut dir = vec![0i8; revolute.len()];
    let mut current: Option<JointVector> = None;
    for (k, step) in plan.steps.iter().enumerate() {
        match step {
            CampaignStep::Move { path } => {
                for w in path {
                    if let Some(c) = current {
                        for (d, j) in dir.iter_mut().zip(&revolute) {
                            let (a, b) = (c[*j], w[*j]);
                            if b != a {
                                *d = if b > a { 1 } else { -1 };
                            }
                        }
                    }
                    current = Some(*w);
                }
            }
            CampaignStep::Measure { position, tcp } => {
                if let Some(q) = current {
                    measures.push((k, *position, *tcp, q, dir.clone()));
                }
            }
            _ => {}
        }
    }
    if measures.is_empty() {
        return 0;
    }
    let wanted = count.min(measures.len());
    let mut chosen = Vec::new();
    let mut next = 0usize;
    for i in 0..wanted {
        // evenly spread, moving on when a pose is too close to a limit
        let from = (i * measures.len() / wanted).max(next);
        let Some(found) = (from..measures.len()).find(|&m| {
            let (_, _, _, q, s) = &measures[m];
            let mut w = *q;
            for (j, sj) in revolute.iter().zip(s) {
                w[*j] += overshoot_rad * if *sj < 0 { -1.0 } else { 1.0 };
            }
            model.limit_violation(&w).is_none()
        }) else {
            break;
        };
        chosen.push(found);
        next = found + 1;
    }
    // insert from the back so the step indices stay valid
    for &m in chosen.iter().rev() {
        let (k, position, tcp, q, s) = &measures[m];
        let (k, position, tcp, q) = (*k, *position, *tcp, *q);
        let mut past = q;
        for (j, sj) in revolute.iter().zip(s) {
            past[*j] += overshoot_rad * if *sj < 0 { -1.0 } else { 1.0 };
        }
        plan.steps.insert(k + 1, CampaignStep::Move { path: vec![past, q] });
        plan.steps.insert(k + 2, CampaignStep::Measure { position, tcp });
    }
    chosen.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_campaign::CampaignConfig;
    use vatcal_campaign::{Campaign, CampaignPlan, CampaignPlanOptions, CampaignStep, CellDevices};
    use vatcal_core::Measurement;
    use vatcal_core::effects::EffectSpec;
    use vatcal_core::params::{EffectParam, ParamId};
    use vatcal_core::{CellFile, Target};
    use vatcal_hardware_traits::Thermometer;

    fn nominal() -> Model {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("fixture");
        Model::from_cell(&cell).expect("model")
    }

    /// Two-sided repeats on the virtual cell with backlash on every joint: each repeat is the
    /// same pose, recorded with every revolute joint's direction reversed, and the backlash
    /// shows in the recorded joints (the nominal FK of the pair differs by far more than the
    /// repeatability); the plan's other steps are unchanged.
    #[test]
    fn two_sided_repeats_reverse_every_joint_and_excite_backlash() {
        let model = nominal();
        let limits = model.joint_limits();
        let poses: Vec<Measurement> = vatcal_sim::truth::probe_start_poses(&model, 60, 11)
            .into_iter()
            .filter(|m| {
                (1..7).all(|k| m.q[k] > limits[k].0 + 0.15 && m.q[k] < limits[k].1 - 0.15)
                    && vatcal_sim::translation_joint_gain(&model, &m.q).is_some_and(|g| g < 0.03)
            })
            .take(8)
            .collect();
        assert_eq!(poses.len(), 8);
        let clear = JointVector::from_mm_deg(150.0, [0.0, -30.0, 30.0, 0.0, 0.0, 0.0]);
        let mut plan = CampaignPlan::from_poses(
            &poses,
            &CampaignPlanOptions { clear_pose: Some(clear), zero_probe: false },
        );
        let original = plan.clone();
        assert_eq!(add_two_sided_repeats(&mut plan, &model, 3, 1e-3), 3);
        assert_eq!(plan.measurement_count(), original.measurement_count() + 3);
        // removing each inserted (overshoot move, measure) pair gives the original plan back
        let mut kept = Vec::new();
        let mut k = 0;
        while k < plan.steps.len() {
            kept.push(&plan.steps[k]);
            if let (CampaignStep::Measure { .. }, Some(CampaignStep::Move { path }), Some(again)) =
                (&plan.steps[k], plan.steps.get(k + 1), plan.steps.get(k + 2))
                && path.len() == 2
                && again == &plan.steps[k]
                && matches!(&plan.steps[k - 1], CampaignStep::Move { path: p } if p.last() == Some(&path[1]))
            {
                let step = (1..7).map(|j| (path[0][j] - path[1][j]).abs()).fold(0.0, f64::max);
                assert!((step - 1e-3).abs() < 1e-12, "overshoot {step} rad");
                k += 3;
                continue;
            }
            k += 1;
        }
        assert_eq!(kept, original.steps.iter().collect::<Vec<_>>(), "only pairs were inserted");

        let mut truth =
            vatcal_sim::truth::perturbed_truth(&model, 4, &vatcal_sim::truth::ErrorBudget::realistic());
        let b = 0.01f64.to_radians();
        for joint in 2..=7u8 {
            truth.enable_effect(EffectSpec::JointBacklash { joint }).expect("backlash");
            truth.set_param(ParamId::Effect(EffectParam::Backlash { joint }), b).expect("value");
        }
        let cell = vatcal_sim::VirtualCell::new(model.clone(), truth, vatcal_sim::SimConfig::default(), 4);
        let (mut arm, mut guide, mut operator) =
            (cell.arm(), cell.guide().expect("the canonical cell has a guide"), cell.operator());
        let mut probe = cell.probe().expect("probe");
        let clock = cell.clock();
        assert!(cell.thermometer().is_none());
        let mut no_thermometer: Option<vatcal_sim::SimThermometer> = None;
        let devices = CellDevices {
            arm: &mut arm,
            guide: Some(&mut guide),
            probe: &mut probe,
            tracker: None,
            operator: &mut operator,
            clock: &clock,
            thermometer: no_thermometer.as_mut().map(|t| t as &mut dyn Thermometer),
        };
        let dir = tempfile::tempdir().expect("tmp");
        let config = CampaignConfig { show_progress: false, ..CampaignConfig::default() };
        let report =
            Campaign::new(devices, &model, config).run(&plan, dir.path().join("j")).expect("campaign");
        assert_eq!(report.measurements.len(), plan.measurement_count());
        let mut pairs = 0;
        for w in report.measurements.windows(2) {
            let (a, r) = (&w[0], &w[1]);
            if a.tcp != r.tcp || a.target != r.target || !matches!(a.target, Target::Probe { .. }) {
                continue;
            }
            pairs += 1;
            let (da, dr) = (a.context.dir.expect("dir"), r.context.dir.expect("dir"));
            for j in 1..7 {
                assert!(da[j] != 0 && dr[j] == -da[j], "joint {}: {da:?} then {dr:?}", j + 1);
            }
            let shift = (model.tcp_position(&a.q, a.tcp).expect("fk")
                - model.tcp_position(&r.q, r.tcp).expect("fk"))
            .norm();
            assert!(shift > 0.03, "backlash of 0.01 deg per joint moves the centred pose by {shift} mm");
        }
        assert_eq!(pairs, 3);
    }
}
