//! The hidden true cell and synthetic measurements.
//!
//! * [`perturbed_truth`] — nominal model + random errors of realistic size ([`ErrorBudget`]);
//! * [`reach`] — numerical position IK: move the arm joints (guide fixed) until a TCP sits on a
//!   world point, on any model (this is what auto-centering achieves physically);
//! * [`probe_start_poses`] — random joint vectors whose nominal TCP reaches a calibration
//!   position (a stand-in for planned candidates in tests);
//! * [`synthetic_probe_measurements`] / [`synthetic_tracker_measurements`] — data as the real
//!   cell would record it.

use nalgebra::{Matrix3, Matrix3x6, Vector3, Vector6};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use vatcal_core::params::BaseParam;
use vatcal_core::{JointVector, Measurement, MeasurementContext, ParamId, Target};
use vatcal_kinematics::Model;

/// Standard deviations of the random errors of the true cell (internal units).
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorBudget {
    /// MDH lengths a, d [mm]
    pub length_mm: f64,
    /// MDH angles alpha, beta_3, theta offsets [rad]
    pub angle_rad: f64,
    /// base translation [mm]
    pub base_translation_mm: f64,
    /// base rotation [rad]
    pub base_angle_rad: f64,
    /// joint compliances are drawn uniformly in this range [rad/(N·m)] (positive: joints yield)
    pub compliance_range: (f64, f64),
    /// also perturb the redundant parameters (a_1, d_2, d_3, alpha_0, a_0, theta_offset_1,
    /// d_1): harmless, they are absorbed by equivalent parameters
    pub perturb_redundant: bool,
    /// errors of the TCP coordinates (CMM) [mm]; 0 = perfect CMM
    pub tcp_mm: f64,
    /// errors of the calibration positions (CMM) [mm]
    pub position_mm: f64,
}

impl ErrorBudget {
    /// Errors of an off-the-shelf Meca500 on a guide as assembled: gives a nominal mean
    /// position error of about 1.2–1.3 mm over the workspace, like the paper's cell.
    pub fn realistic() -> Self {
        Self {
            length_mm: 0.14,
            angle_rad: 0.07f64.to_radians(),
            base_translation_mm: 0.35,
            base_angle_rad: 0.06f64.to_radians(),
            compliance_range: (1.0e-4, 4.0e-4),
            perturb_redundant: false,
            tcp_mm: 0.0,
            position_mm: 0.0,
        }
    }

    /// No errors at all (truth = nominal).
    pub fn none() -> Self {
        Self {
            length_mm: 0.0,
            angle_rad: 0.0,
            base_translation_mm: 0.0,
            base_angle_rad: 0.0,
            compliance_range: (0.0, 0.0),
            perturb_redundant: false,
            tcp_mm: 0.0,
            position_mm: 0.0,
        }
    }
}

fn gauss(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
    if sigma <= 0.0 {
        return 0.0;
    }
    Normal::new(0.0, sigma).map_or(0.0, |n| n.sample(rng))
}

/// A "true" cell: `nominal` with random errors drawn from `budget` (seeded, deterministic).
/// Errors are added to the paper's 28 geometric parameters, compliances are drawn uniformly in
/// `budget.compliance_range`, and (optionally) to redundant parameters, TCPs and positions.
/// Effects switched on in `nominal` are kept with their values.
pub fn perturbed_truth(nominal: &Model, seed: u64, budget: &ErrorBudget) -> Model {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut truth = nominal.clone();
    let add = |truth: &mut Model, rng: &mut ChaCha8Rng, id: ParamId, sigma: f64| {
        if let Ok(v) = truth.param(id) {
            let _ = truth.set_param(id, v + gauss(rng, sigma));
        }
    };
    for i in 2..=7u8 {
        add(&mut truth, &mut rng, ParamId::Alpha(i), budget.angle_rad);
        add(&mut truth, &mut rng, ParamId::ThetaOffset(i), budget.angle_rad);
    }
    for i in 3..=7u8 {
        add(&mut truth, &mut rng, ParamId::A(i), budget.length_mm);
    }
    for i in 4..=7u8 {
        add(&mut truth, &mut rng, ParamId::D(i), budget.length_mm);
    }
    add(&mut truth, &mut rng, ParamId::Beta(4), budget.angle_rad);
    for b in [BaseParam::X, BaseParam::Y, BaseParam::Z] {
        add(&mut truth, &mut rng, ParamId::Base(b), budget.base_translation_mm);
    }
    for b in [BaseParam::Alpha, BaseParam::Beta, BaseParam::Gamma] {
        add(&mut truth, &mut rng, ParamId::Base(b), budget.base_angle_rad);
    }
    let (lo, hi) = budget.compliance_range;
    for j in 2..=7u8 {
        let c = if hi > lo { rng.random_range(lo..hi) } else { lo };
        let _ = truth.set_param(ParamId::Compliance(j), c);
    }
    if budget.perturb_redundant {
        add(&mut truth, &mut rng, ParamId::Alpha(1), budget.angle_rad);
        add(&mut truth, &mut rng, ParamId::A(1), budget.length_mm);
        add(&mut truth, &mut rng, ParamId::A(2), budget.length_mm);
        add(&mut truth, &mut rng, ParamId::ThetaOffset(1), budget.angle_rad);
        add(&mut truth, &mut rng, ParamId::D(1), budget.length_mm);
        add(&mut truth, &mut rng, ParamId::D(2), budget.length_mm);
        add(&mut truth, &mut rng, ParamId::D(3), budget.length_mm);
    }
    for id in nominal.tcp_ids() {
        for axis in vatcal_core::Axis::ALL {
            add(&mut truth, &mut rng, ParamId::Tcp { id, axis }, budget.tcp_mm);
        }
    }
    for id in nominal.position_ids() {
        for axis in vatcal_core::Axis::ALL {
            add(&mut truth, &mut rng, ParamId::Position { id, axis }, budget.position_mm);
        }
    }
    truth
}

/// Why [`reach`] failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReachError {
    /// The iteration did not converge.
    #[error("position IK did not converge: {residual_mm} mm left after {iterations} iterations")]
    NoConvergence {
        /// remaining distance [mm]
        residual_mm: f64,
        /// iterations used
        iterations: usize,
    },
    /// The solution leaves the joint limits.
    #[error("position IK left the limits of joint {joint}")]
    OutsideLimits {
        /// cell joint
        joint: usize,
    },
    /// The model rejected the TCP id.
    #[error("{0}")]
    Model(String),
}

const JOINT_PARAMS: [ParamId; 6] = [
    ParamId::ThetaOffset(2),
    ParamId::ThetaOffset(3),
    ParamId::ThetaOffset(4),
    ParamId::ThetaOffset(5),
    ParamId::ThetaOffset(6),
    ParamId::ThetaOffset(7),
];

/// Numerical position IK: moves the six arm joints (the guide stays at `q_start.q1`) until
/// TCP `tcp` of `model` is at `target_mm` (world), to `tolerance_mm`. Damped least squares with
/// the minimum-norm step, so the arm stays close to `q_start` (the redundancy is resolved
/// toward the start). Torques are re-evaluated at every iterate.
pub fn reach(
    model: &Model,
    q_start: &JointVector,
    tcp: u32,
    target_mm: &Vector3<f64>,
    tolerance_mm: f64,
) -> Result<JointVector, ReachError> {
    let mut q = *q_start;
    let mut buf = [0.0; 18];
    let ctx = MeasurementContext::default();
    let max_iter = 100;
    for it in 0..max_iter {
        let p = model
            .jacobian_into(&q, &ctx, tcp, &JOINT_PARAMS, &mut buf)
            .map_err(|e| ReachError::Model(e.to_string()))?;
        let e = target_mm - p;
        let n = e.norm();
        if n <= tolerance_mm {
            if let Some((joint, ..)) = model.limit_violation(&q) {
                return Err(ReachError::OutsideLimits { joint });
            }
            return Ok(q);
        }
        if !n.is_finite() || it + 1 == max_iter {
            return Err(ReachError::NoConvergence { residual_mm: n, iterations: it });
        }
        let j = Matrix3x6::from_column_slice(&buf);
        // damping only far from the target (stabilises big first steps)
        let lambda2 = if n > 1.0 { 1e-2 * n } else { 0.0 };
        let jjt = j * j.transpose() + Matrix3::identity() * lambda2;
        let Some(inv) = jjt.try_inverse() else {
            return Err(ReachError::NoConvergence { residual_mm: n, iterations: it });
        };
        let mut dq: Vector6<f64> = j.transpose() * (inv * e);
        // cap the step at 0.2 rad per joint
        let m = dq.amax();
        if m > 0.2 {
            dq *= 0.2 / m;
        }
        for k in 0..6 {
            q.0[k + 1] += dq[k];
        }
    }
    Err(ReachError::NoConvergence { residual_mm: f64::NAN, iterations: max_iter })
}

/// Joint values drawn uniformly inside the limits shrunk by `margin` (fraction of each range).
pub fn random_joints(model: &Model, rng: &mut ChaCha8Rng, margin: f64) -> JointVector {
    let mut q = JointVector::default();
    for (k, (lo, hi)) in model.joint_limits().iter().enumerate() {
        let pad = (hi - lo) * margin;
        q.0[k] = if hi - lo > 2.0 * pad { rng.random_range(lo + pad..hi - pad) } else { *lo };
    }
    q
}

/// `count` probe "start poses": for each, a random calibration position and TCP, random joints,
/// then [`reach`] on `model` to put the TCP exactly on the position. Rejected draws (no
/// convergence, limits) are retried. No collision check: for realistic, collision-free poses use
/// the planning crate's candidates.
pub fn probe_start_poses(model: &Model, count: usize, seed: u64) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let tcps = model.tcp_ids();
    let positions = model.position_ids();
    let mut out = Vec::with_capacity(count);
    let mut attempts = 0usize;
    while out.len() < count && attempts < 200 * count.max(1) {
        attempts += 1;
        let position = positions[out.len() % positions.len()];
        let tcp = tcps[rng.random_range(0..tcps.len())];
        let q0 = random_joints(model, &mut rng, 0.05);
        let Some(target) = model.position(position) else { continue };
        if let Ok(q) = reach(model, &q0, tcp, &target, 1e-10) {
            out.push(Measurement::probe(position, tcp, q));
        }
    }
    out
}

/// Noise of a probe measurement: the true TCP ends within this Gaussian scatter of the probe
/// origin (auto-centering threshold 5 µm composite, robot repeatability 5 µm, guide 2.5 µm,
/// gauge 1.2 µm). Default σ = 2 µm per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeNoise {
    /// standard deviation per axis [mm]
    pub sigma_mm: f64,
}

impl Default for ProbeNoise {
    fn default() -> Self {
        Self { sigma_mm: 0.002 }
    }
}

/// Probe measurements on the true cell: for every start pose (TCP, calibration position, joints
/// near the solution), the truth's TCP is driven onto the position plus noise, and the joints
/// are recorded. The context of each start pose (time, dir, temperature) is kept.
/// Start poses the truth cannot reach are skipped (reported through the returned length).
pub fn synthetic_probe_measurements(
    truth: &Model,
    start_poses: &[Measurement],
    noise: ProbeNoise,
    seed: u64,
) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(start_poses.len());
    for s in start_poses {
        let offset = Vector3::new(
            gauss(&mut rng, noise.sigma_mm),
            gauss(&mut rng, noise.sigma_mm),
            gauss(&mut rng, noise.sigma_mm),
        );
        let Target::Probe { position } = s.target else { continue };
        let Some(target) = truth.position(position) else { continue };
        if let Ok(q) = reach_ctx(truth, &s.q, &s.context, s.tcp, &(target + offset)) {
            out.push(Measurement { q, target: Target::Probe { position }, ..*s });
        }
    }
    out
}

/// [`reach`] with a per-sample context (effects such as backlash or drift depend on it).
fn reach_ctx(
    model: &Model,
    q: &JointVector,
    ctx: &MeasurementContext,
    tcp: u32,
    target: &Vector3<f64>,
) -> Result<JointVector, ReachError> {
    if *ctx == MeasurementContext::default() {
        return reach(model, q, tcp, target, 1e-10);
    }
    // fixed-point on the context-dependent offset: reach the target shifted by the difference
    // between the model with and without context
    let mut shifted = *target;
    let mut sol = *q;
    for _ in 0..10 {
        sol = reach(model, &sol, tcp, &shifted, 1e-10)?;
        let with = model.tcp_position_ctx(&sol, ctx, tcp).map_err(|e| ReachError::Model(e.to_string()))?;
        let err = target - with;
        if err.norm() < 1e-10 {
            return Ok(sol);
        }
        shifted += err;
    }
    Ok(sol)
}

/// Tracker measurements: `count` random joint vectors inside the limits (10 % margin), random
/// TCP, world position from the truth plus isotropic Gaussian noise `sigma_mm` per axis (a laser
/// tracker with SMRs in nests: ≈ 0.02 mm).
pub fn synthetic_tracker_measurements(
    truth: &Model,
    count: usize,
    sigma_mm: f64,
    seed: u64,
) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let tcps = truth.tcp_ids();
    let mut out = Vec::with_capacity(count);
    while out.len() < count {
        let q = random_joints(truth, &mut rng, 0.1);
        let tcp = tcps[rng.random_range(0..tcps.len())];
        let Ok(p) = truth.tcp_position(&q, tcp) else { break };
        let noise =
            Vector3::new(gauss(&mut rng, sigma_mm), gauss(&mut rng, sigma_mm), gauss(&mut rng, sigma_mm));
        out.push(Measurement::tracker(tcp, q, p + noise));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::CellFile;

    fn nominal() -> Model {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("fixture");
        Model::from_cell(&cell).expect("model")
    }

    #[test]
    fn reach_puts_the_tcp_on_the_target() {
        let m = nominal();
        let poses = probe_start_poses(&m, 12, 3);
        assert_eq!(poses.len(), 12);
        for p in &poses {
            let r = m.residual(p).expect("residual");
            assert!(r.norm() < 1e-9, "{}", r.norm());
        }
    }

    #[test]
    fn truth_is_deterministic_and_realistically_wrong() {
        let m = nominal();
        let t1 = perturbed_truth(&m, 7, &ErrorBudget::realistic());
        let t2 = perturbed_truth(&m, 7, &ErrorBudget::realistic());
        let v1 = synthetic_tracker_measurements(&t1, 300, 0.0, 1);
        let v2 = synthetic_tracker_measurements(&t2, 300, 0.0, 1);
        assert_eq!(v1, v2);
        let mut means = Vec::new();
        for seed in 0..8 {
            let t = perturbed_truth(&m, seed, &ErrorBudget::realistic());
            let v = synthetic_tracker_measurements(&t, 300, 0.0, 1);
            means.push(v.iter().map(|x| m.residual(x).expect("r").norm()).sum::<f64>() / v.len() as f64);
        }
        let avg = means.iter().sum::<f64>() / means.len() as f64;
        eprintln!("nominal mean errors {means:?}");
        assert!((0.9..1.7).contains(&avg), "nominal mean error {avg} mm (target ~1.27 like the paper)");
    }

    #[test]
    fn probe_measurements_sit_on_the_true_position_within_noise() {
        let m = nominal();
        let truth = perturbed_truth(&m, 11, &ErrorBudget::realistic());
        let starts = probe_start_poses(&m, 20, 5);
        let meas = synthetic_probe_measurements(&truth, &starts, ProbeNoise { sigma_mm: 0.0 }, 1);
        assert!(meas.len() >= 18);
        for x in &meas {
            assert!(truth.residual(x).expect("r").norm() < 1e-9);
            assert!(m.residual(x).expect("r").norm() > 1e-3, "nominal must disagree");
        }
    }
}
