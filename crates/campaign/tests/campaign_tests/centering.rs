//! Auto-centering on the virtual cell: converges in a few iterations to within the paper's
//! 5 µm, and refuses unsafe situations with typed errors.

use crate::common;

use std::time::Duration;

use common::{SimDevices, nominal, paper_cell, poses};
use nalgebra::Vector3;
use vatcal_campaign::{CenteringConfig, CenteringError, auto_center};
use vatcal_core::JointVector;
use vatcal_hardware_traits::{
    JointLayout, LinearAxis, MotionOptions, Operator, OperatorInstruction, Probe3d, RobotArm,
};
use vatcal_sim::truth::reach;
use vatcal_sim::{SimFaults, VirtualCell};

/// Homes the cell, places the plate at `position`, moves to `q`.
fn at_pose(cell: &VirtualCell, d: &mut SimDevices, position: u32, q: &JointVector) {
    d.arm.activate_and_home(Duration::from_secs(60)).expect("home");
    d.guide.home(Duration::from_secs(60)).expect("home guide");
    d.operator.perform(&OperatorInstruction::PlaceProbe { position }).expect("plate");
    d.guide.move_absolute_and_wait(q.guide_mm(), &MotionOptions::default()).expect("guide");
    d.arm
        .move_joints_and_wait(&JointLayout::MECA500_ON_GUIDE.arm(q), &MotionOptions::default())
        .expect("arm");
    assert_eq!(cell.plate_position(), Some(position));
}

/// Auto-centres with the approach directions the arm arrived with (what the campaign tracks;
/// here read from the cell's oracle).
fn center(
    cell: &VirtualCell,
    d: &mut SimDevices,
    position: u32,
    config: &CenteringConfig,
) -> Result<vatcal_campaign::CenteringOutcome, CenteringError> {
    let approach = cell.motion_directions();
    auto_center(&mut d.arm, Some(&mut d.guide), &mut d.probe, &nominal(), position, &approach, config)
}

#[test]
fn converges_within_5_um_in_a_few_iterations_at_every_position() {
    let mut iterations = Vec::new();
    for (k, pose) in poses(9, 41).iter().enumerate() {
        let cell = paper_cell(100 + k as u64);
        let mut d = SimDevices::of(&cell);
        let position = pose.position().expect("probe pose");
        at_pose(&cell, &mut d, position, &pose.q);
        let initial = cell.true_ball_offset_mm(pose.tcp).expect("offset").norm();
        let guide_before = cell.physical_joints().guide_mm();
        let o = center(&cell, &mut d, position, &CenteringConfig::default()).expect("converges");
        assert!(o.final_reading.composite_mm() < 0.005);
        assert!(o.iterations <= 5, "pose {k}: {} iterations ({:?})", o.iterations, o.composite_history_mm);
        // the physical ball is on the true probe origin: 5 µm threshold + ball-radius bias
        // (≤ √3·2.5 µm) + gauge error
        let err = cell.true_ball_offset_mm(pose.tcp).expect("offset").norm();
        assert!(err < 0.012, "pose {k}: true residual {err} mm (started at {initial} mm)");
        assert!(initial > 0.1, "the nominal pose must be off (calibration needed): {initial}");
        assert_eq!(cell.physical_joints().guide_mm(), guide_before, "guide stationary");
        assert_eq!(o.joint_trace.len(), o.iterations + 1);
        // history decreases at each corrective move (until the noise floor)
        assert!(o.composite_history_mm.windows(2).all(|w| w[1] < w[0] + 0.010));
        eprintln!("pose {k}: initial {initial:.4} mm, history {:?}", o.composite_history_mm);
        iterations.push(o.iterations);
    }
    eprintln!("auto-centering iterations: {iterations:?}");
}

#[test]
fn a_diverging_arm_is_stopped_when_the_error_grows() {
    let pose = &poses(3, 42)[0];
    for gain in [2.5, -1.0] {
        let cell = paper_cell(7);
        let mut d = SimDevices::of(&cell);
        at_pose(&cell, &mut d, pose.position().expect("p"), &pose.q);
        cell.set_faults(SimFaults { linear_move_gain: gain, ..SimFaults::default() });
        let e = center(&cell, &mut d, pose.position().expect("p"), &CenteringConfig::default())
            .expect_err("diverges");
        match e {
            CenteringError::ErrorGrew { previous_mm, current_mm, iteration } => {
                assert!(current_mm > previous_mm);
                assert_eq!(iteration, 1, "stopped after the first bad move (gain {gain})");
            }
            other => panic!("gain {gain}: expected ErrorGrew, got {other}"),
        }
        assert_eq!(cell.linear_moves().len(), 1, "no further move after the growth");
    }
}

#[test]
fn readings_near_or_beyond_the_range_are_refused_before_moving() {
    let pose = &poses(3, 43)[0];
    let position = pose.position().expect("p");
    let cell = paper_cell(8);
    let mut d = SimDevices::of(&cell);
    let truth = cell.truth();
    // put the ball 5.9 mm along gauge 2: inside ±6 mm but within the 0.25 mm margin
    let along = d.probe.placement(position).expect("placement").to_world(&Vector3::new(0.0, 5.9, 0.0));
    let q = reach(&truth, &pose.q, pose.tcp, &(truth.position(position).expect("p") + along), 1e-10)
        .expect("reach");
    at_pose(&cell, &mut d, position, &q);
    let e = center(&cell, &mut d, position, &CenteringConfig::default()).expect_err("margin");
    assert!(matches!(e, CenteringError::OutOfRange { ref readings_mm, .. } if readings_mm.len() == 3), "{e}");
    assert!(cell.linear_moves().is_empty(), "nothing moved");
    // beyond the range: the probe refuses, same typed error
    let along = d.probe.placement(position).expect("placement").to_world(&Vector3::new(0.0, 0.0, 7.0));
    let q = reach(&truth, &pose.q, pose.tcp, &(truth.position(position).expect("p") + along), 1e-10)
        .expect("reach");
    d.arm
        .move_joints_and_wait(&JointLayout::MECA500_ON_GUIDE.arm(&q), &MotionOptions::default())
        .expect("arm");
    let e = center(&cell, &mut d, position, &CenteringConfig::default()).expect_err("range");
    assert!(matches!(e, CenteringError::OutOfRange { ref readings_mm, .. } if readings_mm.is_empty()), "{e}");
    assert!(e.to_string().contains("outside"), "{e}");
    // a position the probe has no placement for
    assert!(matches!(
        center(&cell, &mut d, 9, &CenteringConfig::default()),
        Err(CenteringError::NoPlacement { position: 9 })
    ));
}

#[test]
fn iteration_cap_and_step_cap() {
    let pose = &poses(3, 44)[1];
    let position = pose.position().expect("p");
    let cell = paper_cell(9);
    let mut d = SimDevices::of(&cell);
    at_pose(&cell, &mut d, position, &pose.q);
    let capped = CenteringConfig { max_iterations: 1, ..CenteringConfig::default() };
    let e = center(&cell, &mut d, position, &capped).expect_err("cap");
    assert!(
        matches!(e, CenteringError::IterationCap { iterations: 1, composite_mm } if composite_mm > 0.005),
        "{e}"
    );

    // small steps: every commanded correction is at most 0.2 mm, and it still converges
    let cell = paper_cell(9);
    let mut d = SimDevices::of(&cell);
    at_pose(&cell, &mut d, position, &pose.q);
    let initial = cell.true_ball_offset_mm(pose.tcp).expect("offset").norm();
    let short = CenteringConfig { max_step_mm: 0.2, max_iterations: 40, ..CenteringConfig::default() };
    let o = center(&cell, &mut d, position, &short).expect("converges with short steps");
    assert!(o.steps_world_mm.iter().all(|s| s.norm() <= 0.2 + 1e-12));
    assert!(cell.linear_moves().iter().all(|s| s.norm() <= 0.2 + 1e-9));
    assert!(o.iterations as f64 >= (initial / 0.2).floor(), "{} iterations for {initial} mm", o.iterations);
}

/// The paper's cell (realistic geometric truth, paper noise) with a backlash of half lost
/// motion `half_rad` on every arm joint (none when 0).
fn backlash_cell(seed: u64, half_rad: f64) -> VirtualCell {
    use vatcal_core::EffectSpec;
    use vatcal_core::params::{EffectParam, ParamId};
    let model = nominal();
    let mut truth =
        vatcal_sim::truth::perturbed_truth(&model, seed, &vatcal_sim::truth::ErrorBudget::realistic());
    if half_rad > 0.0 {
        for joint in 2..=7 {
            truth.enable_effect(EffectSpec::JointBacklash { joint }).expect("effect");
            truth.set_param(ParamId::Effect(EffectParam::Backlash { joint }), half_rad).expect("value");
        }
    }
    VirtualCell::new(model.clone(), truth, vatcal_sim::SimConfig::paper_for(&model), seed)
}

/// One centering per pose on a fresh cell: `Ok((corrections, arm motions, true residual mm))`
/// or the refusal; every converged run must end with each joint on its approach side.
fn sweep(half_rad: f64, overshoot_rad: f64, n: usize) -> Vec<Result<(usize, usize, f64), String>> {
    let config = CenteringConfig { approach_overshoot_rad: overshoot_rad, ..CenteringConfig::default() };
    poses(n, 45)
        .iter()
        .enumerate()
        .map(|(k, pose)| {
            let cell = backlash_cell(300 + k as u64, half_rad);
            let mut d = SimDevices::of(&cell);
            let position = pose.position().expect("probe pose");
            at_pose(&cell, &mut d, position, &pose.q);
            let approach = cell.motion_directions();
            let o = center(&cell, &mut d, position, &config).map_err(|e| e.to_string())?;
            assert_eq!(o.approach_dir, cell.motion_directions(), "the outcome's directions are the cell's");
            if overshoot_rad > 0.0 {
                assert_eq!(o.approach_dir, approach, "pose {k}: every joint ends on its approach side");
            }
            assert_eq!(o.joint_trace.len(), o.iterations + 1);
            let residual = cell.true_ball_offset_mm(pose.tcp).expect("offset").norm();
            Ok((o.iterations, o.arm_motions, residual))
        })
        .collect()
}

fn summary(label: &str, runs: &[Result<(usize, usize, f64), String>]) -> (usize, usize, usize) {
    let ok: Vec<_> = runs.iter().filter_map(|r| r.as_ref().ok()).collect();
    let corrections: usize = ok.iter().map(|r| r.0).sum();
    let motions: usize = ok.iter().map(|r| r.1).sum();
    eprintln!(
        "{label}: {} of {} centred, corrections {:?}, arm motions {:?}, true residual max {:.1} µm; refused: {:?}",
        ok.len(),
        runs.len(),
        ok.iter().map(|r| r.0).collect::<Vec<_>>(),
        ok.iter().map(|r| r.1).collect::<Vec<_>>(),
        ok.iter().map(|r| r.2).fold(0.0, f64::max) * 1e3,
        runs.iter().filter_map(|r| r.as_ref().err()).collect::<Vec<_>>()
    );
    (ok.len(), corrections, motions)
}

/// Large backlash alone (0.3 arcmin half lost motion on every joint, ≈ 30–100 µm at the ball
/// when a joint reverses): re-approaching every reversed joint from its planned side makes the
/// loop converge as without backlash; the plain linear correction limit-cycles above 5 µm.
#[test]
fn large_backlash_converges_when_every_joint_keeps_its_approach_side() {
    let half = 0.3 * std::f64::consts::PI / 180.0 / 60.0;
    let n = 12;
    let robust = sweep(half, CenteringConfig::default().approach_overshoot_rad, n);
    let (centred, corrections, _) = summary("backlash 0.3', overshoot", &robust);
    assert_eq!(centred, n, "every pose centred");
    for r in robust.iter().flatten() {
        assert!(r.0 <= 6, "{} corrections", r.0);
        assert!(r.2 < 0.012, "true residual {:.1} µm", r.2 * 1e3);
    }
    assert!(corrections as f64 / n as f64 <= 4.0);
    let plain = sweep(half, 0.0, n);
    let (plain_centred, ..) = summary("backlash 0.3', linear moves only", &plain);
    assert!(plain_centred < n / 2, "the plain loop should fail with this backlash ({plain_centred} of {n})");
}

/// Without backlash the approach-side moves cost arm motions but no corrections: every pose
/// still converges within the same number of corrections (± the noise of the extra moves).
#[test]
fn without_backlash_the_corrections_are_unchanged() {
    let n = 12;
    let robust = sweep(0.0, CenteringConfig::default().approach_overshoot_rad, n);
    let plain = sweep(0.0, 0.0, n);
    let (a, corrections, motions) = summary("no backlash, overshoot", &robust);
    let (b, plain_corrections, plain_motions) = summary("no backlash, linear moves only", &plain);
    assert_eq!((a, b), (n, n), "every pose centred both ways");
    assert_eq!(plain_motions, plain_corrections, "one arm motion per correction without overshoot");
    assert!(motions <= 3 * corrections);
    assert!(corrections <= plain_corrections + 1, "{corrections} vs {plain_corrections} corrections");
    for (r, p) in robust.iter().flatten().zip(plain.iter().flatten()) {
        assert!(r.2 < 0.012 && p.2 < 0.012, "true residuals {:.1} / {:.1} µm", r.2 * 1e3, p.2 * 1e3);
    }
}
