//! Random validation poses (paper §5: 573 joint positions over the whole accessible
//! workspace, one SMR measured at each).

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};
use vatcal_core::JointVector;
use vatcal_kinematics::Model;
use vatcal_planning::collision::{CollisionChecker, ProbeState};
use vatcal_planning::motion::JointBounds;

use super::ValidationError;

/// Options of [`random_validation_poses`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RandomPoseOptions {
    /// number of poses (paper: 573)
    pub count: usize,
    /// distance kept from every arm joint limit \[deg\]
    pub joint_margin_deg: f64,
    /// distance kept from the guide's stroke ends \[mm\]
    pub guide_margin_mm: f64,
    /// draws allowed per accepted pose before giving up
    pub max_draws_per_pose: usize,
    /// when given, each revolute joint is drawn within at most this range centred on the
    /// middle of its limits \[deg\] (e.g. 360: one turn of a ±360° UR joint, whose two turns
    /// reach the same poses and make the legs between random poses too long for the path
    /// planner); `None` (the default): the whole range
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub revolute_range_deg: Option<f64>,
}

impl Default for RandomPoseOptions {
    /// 573 poses, 5° from the arm joint limits, 5 mm from the stroke ends, 200 draws per pose,
    /// the whole range of every joint.
    fn default() -> Self {
        Self {
            count: 573,
            joint_margin_deg: 5.0,
            guide_margin_mm: 5.0,
            max_draws_per_pose: 200,
            revolute_range_deg: None,
        }
    }
}

/// One random validation pose: the joints and the SMR (TCP id) the tracker measures there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ValidationPose {
    /// joints (q1 mm, q2..q7 rad)
    pub q: JointVector,
    /// measured SMR / TCP id
    pub tcp: u32,
}

/// `opts.count` joint vectors drawn uniformly inside the joint limits shrunk by the margins,
/// kept only when collision-free with the probe removed (the checker's model and margin); each
/// with one of the model's TCPs drawn uniformly (the paper measured "one or another of the
/// three SMRs" at each pose). Seeded, deterministic. The tracker's line of sight is not
/// modelled.
///
/// # Errors
/// Invalid margins; no TCP; too many rejected draws.
pub fn random_validation_poses(
    model: &Model,
    checker: &CollisionChecker<'_>,
    opts: &RandomPoseOptions,
    seed: u64,
) -> Result<Vec<ValidationPose>, ValidationError> {
    let mut bounds = JointBounds::new(model, opts.joint_margin_deg, opts.guide_margin_mm)?;
    if let Some(range) = opts.revolute_range_deg {
        let half = range.to_radians() / 2.0;
        for (k, (lo, hi)) in bounds.bounds.iter_mut().enumerate().take(model.joint_count()) {
            if model.is_revolute(k + 1) && *hi - *lo > 2.0 * half {
                let mid = 0.5 * (*lo + *hi);
                (*lo, *hi) = (mid - half, mid + half);
            }
        }
    }
    let tcps = model.tcp_ids();
    if tcps.is_empty() {
        return Err(ValidationError::Option { option: "model".into(), reason: "has no TCP".into() });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(opts.count);
    let budget = opts.count.saturating_mul(opts.max_draws_per_pose.max(1));
    let mut draws = 0usize;
    while out.len() < opts.count {
        if draws >= budget {
            return Err(ValidationError::NotEnoughPoses { found: out.len(), wanted: opts.count, draws });
        }
        draws += 1;
        let mut q = JointVector::zeros(model.joint_count());
        for (v, (lo, hi)) in q.as_mut_slice().iter_mut().zip(&bounds.bounds) {
            *v = if hi > lo { rng.random_range(*lo..*hi) } else { *lo };
        }
        let tcp = tcps[rng.random_range(0..tcps.len())];
        if checker.is_free(&q, ProbeState::Absent) {
            out.push(ValidationPose { q, tcp });
        }
    }
    Ok(out)
}
