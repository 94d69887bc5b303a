//! Postures and synthetic measurements on a truth: reaching a world point (position IK),
//! random joints, start poses, and synthetic probe and tracker measurements.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::{JointVector, Measurement, MeasurementContext, ParamId, Target};
use vatcal_hardware_traits::JointLayout;
use vatcal_kinematics::Model;

use super::gauss;

/// Why [`reach`] failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReachError {
    /// The iteration did not converge.
    #[error("position IK did not converge: {residual_mm} mm left after {iterations} iterations")]
    NoConvergence {
        /// remaining distance \[mm\]
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

/// Numerical position IK: moves the arm joints (every joint but the guide of the model's
/// [`JointLayout`]: the six Meca500 joints on the canonical cell, all joints of a chain
/// without a guide; the guide stays at its value in `q_start`) until TCP `tcp` of `model` is
/// at `target_mm` (world), to `tolerance_mm`. Damped least squares on the model's own
/// Jacobian (columns of the joints' offsets: `theta` of revolute, `d` of prismatic joints)
/// with the minimum-norm step, so the arm stays close to `q_start` (the redundancy is resolved
/// toward the start). Torques are re-evaluated at every iterate. Any chain, no closed form.
///
/// # Errors
/// [`ReachError`]: no convergence in 100 iterations, a solution outside the joint limits, or a
/// TCP the model does not have.
pub fn reach(
    model: &Model,
    q_start: &JointVector,
    tcp: u32,
    target_mm: &Vector3<f64>,
    tolerance_mm: f64,
) -> Result<JointVector, ReachError> {
    let layout = JointLayout::of(model.joint_kinds());
    macro_rules! dispatch {
        ($($n:literal)*) => {
            match layout.arm_joint_count() {
                $($n => reach_n::<$n>(model, &layout, q_start, tcp, target_mm, tolerance_mm),)*
                n => Err(ReachError::Model(format!("an arm of {n} joints"))),
            }
        };
    }
    dispatch!(1 2 3 4 5 6 7 8 9 10 11 12)
}

/// [`reach`] for an arm of `N` joints.
fn reach_n<const N: usize>(
    model: &Model,
    layout: &JointLayout,
    q_start: &JointVector,
    tcp: u32,
    target_mm: &Vector3<f64>,
    tolerance_mm: f64,
) -> Result<JointVector, ReachError> {
    let params: Vec<ParamId> = layout
        .arm_cell_joints()
        .map(|j| if model.is_revolute(j) { ParamId::ThetaOffset(j as u8) } else { ParamId::D(j as u8) })
        .collect();
    let mut q = *q_start;
    let mut buf = vec![0.0; 3 * N];
    let ctx = MeasurementContext::default();
    let max_iter = 100;
    for it in 0..max_iter {
        let p = model
            .jacobian_into(&q, &ctx, tcp, &params, &mut buf)
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
        let j = SMatrix::<f64, 3, N>::from_column_slice(&buf);
        // damping only far from the target (stabilises big first steps)
        let lambda2 = if n > 1.0 { 1e-2 * n } else { 0.0 };
        let jjt = j * j.transpose() + Matrix3::identity() * lambda2;
        let Some(inv) = jjt.try_inverse() else {
            return Err(ReachError::NoConvergence { residual_mm: n, iterations: it });
        };
        let mut dq: SVector<f64, N> = j.transpose() * (inv * e);
        // cap the step at 0.2 rad per joint
        let m = dq.amax();
        if m > 0.2 {
            dq *= 0.2 / m;
        }
        for k in 0..N {
            q[layout.cell_joint(k) - 1] += dq[k];
        }
    }
    Err(ReachError::NoConvergence { residual_mm: f64::NAN, iterations: max_iter })
}

/// Joint values drawn uniformly inside the limits shrunk by `margin` (fraction of each range).
pub fn random_joints(model: &Model, rng: &mut ChaCha8Rng, margin: f64) -> JointVector {
    let mut q = JointVector::zeros(model.joint_count());
    for (k, (lo, hi)) in model.joint_limits().iter().enumerate() {
        let pad = (hi - lo) * margin;
        q[k] = if hi - lo > 2.0 * pad { rng.random_range(lo + pad..hi - pad) } else { *lo };
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
    /// standard deviation per axis \[mm\]
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

/// [`synthetic_tracker_measurements`] of one marker (TCP `tcp`) as an instrument whose frame is
/// elsewhere sees it: the draws of that function (same postures and noise for the same seed),
/// the truth's position of TCP `tcp` plus the noise, mapped by `y = R x + t`
/// (`rotation`, `translation_mm`). What a motion-capture system or a tracker at an unknown place
/// records; every row is labelled TCP `tcp`.
pub fn synthetic_tracker_measurements_in_frame(
    truth: &Model,
    count: usize,
    sigma_mm: f64,
    seed: u64,
    tcp: u32,
    rotation: &nalgebra::Rotation3<f64>,
    translation_mm: &Vector3<f64>,
) -> Vec<Measurement> {
    synthetic_tracker_measurements(truth, count, sigma_mm, seed)
        .into_iter()
        .filter_map(|m| {
            let Target::Tracker { xyz_mm } = m.target else { return None };
            let noise = xyz_mm - truth.tcp_position(&m.q, m.tcp).ok()?;
            let p = truth.tcp_position(&m.q, tcp).ok()? + noise;
            Some(Measurement::tracker(tcp, m.q, rotation * p + translation_mm))
        })
        .collect()
}
