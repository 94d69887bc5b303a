//! Campaign-like simulated data: what a real discovery campaign on the cell records.
//!
//! * poses: `n/2` poses chosen by Detmax (paper34 information, 2 restarts) from 300 candidate
//!   probe poses (`probe_start_poses`, the way the observability tests build candidates), each
//!   measured twice, approached from opposite directions (`dir` = d and −d, d a random sign per
//!   joint): `n` probe measurements;
//! * context: `time_s` (45 s per measurement) and `temperature_c` (a slow warm-up plus a swing,
//!   so temperature and time are not collinear) on every measurement;
//! * centring truncation: auto-centering stops anywhere inside the 5 µm tolerance, so the ball
//!   sits at `position + offset` with the offset uniform in a 5 µm ball; the gauges read the
//!   offset with 0.7 µm noise per axis and it is recorded (`probe_offset_mm`); 1.5 µm per axis
//!   of unmodelled noise (repeatability, gauge error) is not recorded;
//! * the truth: [`base_truth`] (today `perturbed_truth(…, realistic)` plus ~1 µm CMM errors of
//!   every TCP and calibration-position coordinate) plus the hidden effects;
//! * validation: 200 tracker poses over the workspace, 5 µm noise per axis.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::params::Axis;
use vatcal_core::{Measurement, MeasurementContext, ParamId, ParamSet, Target};
use vatcal_kinematics::Model;
use vatcal_observability::detmax::{Candidates, DetmaxOptions, detmax};
use vatcal_sim::truth::{
    ErrorBudget, perturbed_truth, probe_start_poses, reach, synthetic_tracker_measurements,
};

use super::{Hidden, Scenario, nominal};

/// σ of the CMM errors of the TCP and calibration-position coordinates in the truth [mm].
pub const CMM_SIGMA_MM: f64 = 0.001;
/// centring tolerance: the ball ends anywhere inside this radius of the probe origin [mm]
pub const CENTRING_TOLERANCE_MM: f64 = 0.005;
/// gauge noise of the recorded final offset, per axis [mm]
pub const GAUGE_SIGMA_MM: f64 = 0.0007;
/// unrecorded noise of a probe measurement, per axis [mm]
pub const UNMODELLED_SIGMA_MM: f64 = 0.0015;
/// seconds between measurements
pub const SECONDS_PER_MEASUREMENT: f64 = 45.0;

/// Standard normal draw (Box–Muller).
pub fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// The hidden base truth every scenario starts from. Switching to another base truth (e.g. the
/// paper-like one of `vatcal_sim`) is this one function.
pub fn base_truth(nominal: &Model, seed: u64) -> Model {
    let mut truth = perturbed_truth(nominal, seed, &ErrorBudget::realistic());
    add_cmm_errors(&mut truth, seed, CMM_SIGMA_MM);
    truth
}

/// Adds Gaussian errors of `sigma_mm` to every TCP and calibration-position coordinate.
pub fn add_cmm_errors(truth: &mut Model, seed: u64, sigma_mm: f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xc33_0001);
    let mut ids = Vec::new();
    for id in truth.tcp_ids() {
        ids.extend(Axis::ALL.map(|axis| ParamId::Tcp { id, axis }));
    }
    for id in truth.position_ids() {
        ids.extend(Axis::ALL.map(|axis| ParamId::Position { id, axis }));
    }
    for id in ids {
        let v = truth.param(id).expect("coordinate") + sigma_mm * gaussian(&mut rng);
        truth.set_param(id, v).expect("coordinate");
    }
}

/// `count` poses chosen by Detmax (paper34, nominal model) from 300 random candidate poses.
pub fn detmax_poses(nominal: &Model, count: usize, seed: u64) -> Vec<Measurement> {
    let candidates = probe_start_poses(nominal, 300, seed.wrapping_add(101));
    let c = Candidates::from_measurements(nominal, &candidates, &ParamSet::paper34()).expect("candidates");
    let options = DetmaxOptions { restarts: 2, seed, ..DetmaxOptions::new(count) };
    let selection = detmax(&c, &options).expect("detmax");
    selection.selected.iter().map(|i| candidates[*i]).collect()
}

/// [`reach`] on a model whose effects depend on the context: fixed point on the shift.
fn reach_ctx(
    model: &Model,
    start: &Measurement,
    ctx: &MeasurementContext,
    target: &Vector3<f64>,
) -> Option<Measurement> {
    let mut shifted = *target;
    let mut q = start.q;
    for _ in 0..10 {
        q = reach(model, &q, start.tcp, &shifted, 1e-10).ok()?;
        let with = model.tcp_position_ctx(&q, ctx, start.tcp).ok()?;
        let err = target - with;
        if err.norm() < 1e-10 {
            break;
        }
        shifted += err;
    }
    Some(Measurement { q, context: *ctx, ..*start })
}

/// Temperature [°C] at time `t` of a campaign lasting `total_s`: 1 K warm-up plus a ±1 K swing.
pub fn temperature_at(t: f64, total_s: f64) -> f64 {
    let u = t / total_s.max(1.0);
    20.0 + 1.0 * u + 1.0 * (2.0 * std::f64::consts::PI * 1.7 * u).sin()
}

/// The true cell of a scenario: [`base_truth`] with `hidden` switched on. Values of TCP and
/// calibration-position coordinates (`tcp-offset`, `position-offset`) are offsets added to the
/// base truth's coordinates; every other value is the effect parameter itself.
pub fn truth_with(seed: u64, hidden: &[Hidden]) -> Model {
    let mut truth = base_truth(&nominal(), seed);
    for h in hidden {
        truth.enable_effect(h.spec).expect("effect");
        for (id, v) in &h.values {
            let base = match id {
                ParamId::Tcp { .. } | ParamId::Position { .. } => truth.param(*id).expect("coordinate"),
                _ => 0.0,
            };
            truth.set_param(*id, base + *v).expect("effect value");
        }
    }
    truth
}

/// How the campaign is run: every pose measured from both sides (the default), or the demo's
/// discovery campaign (each pose once, a few two-sided repeats); the cell's temperature and how
/// the thermometer records it.
#[derive(Debug, Clone, Copy)]
pub struct Style {
    /// `None`: every pose twice, from `d` then `−d`; `Some(k)`: each pose once (random `d`) and
    /// `k` of them, evenly spread, again right after from `−d`
    pub two_sided_repeats: Option<usize>,
    /// true cell temperature [°C] at time `t` of a campaign lasting `total_s`
    pub temperature: fn(f64, f64) -> f64,
    /// thermometer noise σ [K] and resolution [K] of the recorded `temperature_c` (0, 0: the
    /// true temperature is recorded)
    pub thermometer: (f64, f64),
}

impl Default for Style {
    fn default() -> Self {
        Self { two_sided_repeats: None, temperature: temperature_at, thermometer: (0.0, 0.0) }
    }
}

/// A campaign-like data set of `n` probe measurements (module docs).
pub fn campaign(seed: u64, hidden: &[Hidden], n: usize) -> Scenario {
    campaign_with(seed, hidden, n, Style::default())
}

/// [`campaign`] run the way `style` says.
pub fn campaign_with(seed: u64, hidden: &[Hidden], n: usize, style: Style) -> Scenario {
    let nominal = nominal();
    let truth = truth_with(seed, hidden);
    let (pose_count, repeats) = match style.two_sided_repeats {
        None => (n.div_ceil(2), None),
        Some(k) => (n - k.min(n / 2), Some(k.min(n / 2))),
    };
    let poses = detmax_poses(&nominal, pose_count, seed);
    let repeated = |i: usize| match repeats {
        None => true,
        Some(k) => k > 0 && (0..k).any(|r| r * pose_count / k == i),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(202));
    let total_s = SECONDS_PER_MEASUREMENT * n as f64;
    let mut probe = Vec::with_capacity(n);
    for (i, pose) in poses.iter().enumerate() {
        let d: [i8; 6] = std::array::from_fn(|_| if rng.random::<bool>() { 1 } else { -1 });
        let sides: &[[i8; 6]] = if repeated(i) { &[d, d.map(|x| -x)] } else { &[d] };
        for dir in sides.iter().copied() {
            if probe.len() >= n {
                break;
            }
            let t = SECONDS_PER_MEASUREMENT * probe.len() as f64;
            let true_c = (style.temperature)(t, total_s);
            let ctx = MeasurementContext {
                dir: Some(vatcal_core::measurement::dirs_from_meca500_arm(dir)),
                time_s: Some(t),
                temperature_c: Some(true_c),
            };
            let Target::Probe { position } = pose.target else { continue };
            let Some(origin) = truth.position(position) else { continue };
            // where centring stopped: uniform inside the tolerance ball
            let offset = loop {
                let v = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                if v.norm() <= 1.0 {
                    break v * CENTRING_TOLERANCE_MM;
                }
            };
            let unrecorded = Vector3::from_fn(|_, _| UNMODELLED_SIGMA_MM * gaussian(&mut rng));
            let read = offset + Vector3::from_fn(|_, _| GAUGE_SIGMA_MM * gaussian(&mut rng));
            let (sigma_k, resolution_k) = style.thermometer;
            let recorded_c = if sigma_k > 0.0 || resolution_k > 0.0 {
                let v = true_c + sigma_k * gaussian(&mut rng);
                if resolution_k > 0.0 { (v / resolution_k).round() * resolution_k } else { v }
            } else {
                true_c
            };
            if let Some(m) = reach_ctx(&truth, pose, &ctx, &(origin + offset + unrecorded)) {
                let context = MeasurementContext { temperature_c: Some(recorded_c), ..m.context };
                probe.push(Measurement { context, ..m }.with_probe_offset(read));
            }
        }
    }
    let validation =
        synthetic_tracker_measurements(&truth, 200, super::TRACKER_SIGMA_MM, seed.wrapping_add(303));
    Scenario { truth, probe, validation }
}
