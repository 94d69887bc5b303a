//! Joint-space motion: limits with margins, singularity margins, the interpolation resolution
//! used for collision checks, and the motion-time model of the tour.
//!
//! # Motion time
//! A move from `a` to `b` is a synchronised joint move: every joint arrives at the same time,
//! limited by the slowest one, so
//!
//! `t(a, b) = max_j |b_j - a_j| / (v_j · fraction)`
//!
//! with `v_1` the guide speed (mm/s), `v_2..v_7` the Meca500 joint speeds [deg/s] and `fraction`
//! the planned fraction of the maximum speed, all from the cell's `[motion]` table
//! ([`vatcal_core::CellFile::motion_limits`]). Acceleration phases are ignored (the Meca500 and
//! the Zaber guide accelerate in a few tens of ms, small next to moves of seconds).

use vatcal_core::cell::MotionLimits;
use vatcal_core::{JointVector, deg_to_rad};
use vatcal_kinematics::{Chain, Model};

use crate::error::PlanError;

/// Speeds of the seven joints in internal units (mm/s for the guide, rad/s for the arm),
/// already multiplied by the speed fraction, plus the fixed times of the campaign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionTimer {
    /// effective speed of each joint (mm/s, rad/s)
    pub speed: [f64; 7],
    /// time per measurement (settle + auto-centre) (s)
    pub measurement_s: f64,
    /// time of one manual re-placement of the probe plate (s)
    pub probe_replacement_s: f64,
}

impl MotionTimer {
    /// From the cell's `[motion]` limits.
    pub fn from_limits(limits: &MotionLimits) -> Result<Self, PlanError> {
        let f = limits.speed_fraction;
        if !(f > 0.0 && f <= 1.0) {
            return Err(PlanError::Option {
                option: "motion.speed_fraction".into(),
                reason: format!("must be in (0, 1], got {f}"),
            });
        }
        let mut speed = [0.0; 7];
        speed[0] = limits.guide_speed_mm_per_s * f;
        for (k, v) in limits.joint_speed_deg_per_s.iter().enumerate() {
            speed[k + 1] = deg_to_rad(*v) * f;
        }
        if speed.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(PlanError::Option {
                option: "motion".into(),
                reason: format!("every speed must be positive, got {limits:?}"),
            });
        }
        Ok(Self {
            speed,
            measurement_s: limits.measurement_s,
            probe_replacement_s: limits.probe_replacement_s,
        })
    }

    /// Time (s) of the synchronised joint move from `a` to `b`.
    pub fn move_time_s(&self, a: &JointVector, b: &JointVector) -> f64 {
        (0..7).map(|k| (b[k] - a[k]).abs() / self.speed[k]).fold(0.0, f64::max)
    }

    /// Time (s) along a polyline of joint vectors.
    pub fn path_time_s(&self, path: &[JointVector]) -> f64 {
        path.windows(2).map(|w| self.move_time_s(&w[0], &w[1])).sum()
    }
}

/// Resolution at which a straight joint-space segment is checked for collisions: consecutive
/// checked configurations differ by at most `max_joint_step_deg` on every arm joint and
/// `max_guide_step_mm` on the guide (both ends included).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Resolution {
    /// largest arm-joint change between two checks (deg)
    pub max_joint_step_deg: f64,
    /// largest guide change between two checks (mm)
    pub max_guide_step_mm: f64,
}

impl Default for Resolution {
    fn default() -> Self {
        Self { max_joint_step_deg: 1.0, max_guide_step_mm: 1.0 }
    }
}

impl Resolution {
    /// Number of intervals needed to go from `a` to `b` at this resolution (>= 1).
    pub fn intervals(&self, a: &JointVector, b: &JointVector) -> usize {
        let step_rad = deg_to_rad(self.max_joint_step_deg);
        let mut n = (b[0] - a[0]).abs() / self.max_guide_step_mm;
        for k in 1..7 {
            n = n.max((b[k] - a[k]).abs() / step_rad);
        }
        (n.ceil() as usize).max(1)
    }

    /// Checks that both steps are positive and finite.
    pub fn validate(&self) -> Result<(), PlanError> {
        for (name, v) in
            [("max_joint_step_deg", self.max_joint_step_deg), ("max_guide_step_mm", self.max_guide_step_mm)]
        {
            if !(v.is_finite() && v > 0.0) {
                return Err(PlanError::Option {
                    option: format!("resolution.{name}"),
                    reason: format!("must be > 0, got {v}"),
                });
            }
        }
        Ok(())
    }
}

/// Linear interpolation `a + t (b - a)`.
pub fn interpolate(a: &JointVector, b: &JointVector, t: f64) -> JointVector {
    let mut q = *a;
    for k in 0..7 {
        q[k] = a[k] + t * (b[k] - a[k]);
    }
    q
}

/// Margin kept from the arm joint limits by every commanded move that is not a measurement
/// (retreat poses, path waypoints) (deg). Measurement poses keep the larger
/// `joint_margin_deg` of the candidate options, because auto-centring moves them slightly.
pub const MOVE_MARGIN_DEG: f64 = 0.5;

/// Joint limits shrunk by margins (internal units): `[(lo, hi); 7]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointBounds {
    /// bounds per cell joint (index = joint - 1)
    pub bounds: [(f64, f64); 7],
}

impl JointBounds {
    /// The model's limits shrunk by `joint_margin_deg` on the arm joints and `guide_margin_mm`
    /// on the guide.
    pub fn new(model: &Model, joint_margin_deg: f64, guide_margin_mm: f64) -> Result<Self, PlanError> {
        model.require_meca500_on_guide("joint bounds for planning")?;
        let mut bounds = [(0.0, 0.0); 7];
        bounds.copy_from_slice(model.joint_limits());
        for (k, b) in bounds.iter_mut().enumerate() {
            let m = if k == 0 { guide_margin_mm } else { deg_to_rad(joint_margin_deg) };
            *b = (b.0 + m, b.1 - m);
            if b.0 > b.1 || b.0.is_nan() || b.1.is_nan() {
                return Err(PlanError::Option {
                    option: if k == 0 { "guide margin".into() } else { "joint margin".into() },
                    reason: format!("the margin leaves nothing of the range of joint {}", k + 1),
                });
            }
        }
        Ok(Self { bounds })
    }

    /// True when every joint is within its shrunk range.
    pub fn contains(&self, q: &JointVector) -> bool {
        q.as_slice().iter().zip(&self.bounds).all(|(v, (lo, hi))| *v >= *lo && *v <= *hi)
    }

    /// True when every joint is within its range widened by `slack` (mm / rad).
    pub fn contains_with_slack(&self, q: &JointVector, slack_mm: f64, slack_rad: f64) -> bool {
        q.as_slice().iter().zip(&self.bounds).enumerate().all(|(k, (v, (lo, hi)))| {
            let s = if k == 0 { slack_mm } else { slack_rad };
            *v >= *lo - s && *v <= *hi + s
        })
    }
}

/// Margins from the three singularities of the Meca500.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingularityMargins {
    /// wrist: `|sin theta_6| >= sin(margin)` (J5 away from 0)
    pub wrist_deg: f64,
    /// elbow: `|sin(theta_4 + delta)| >= sin(margin)` with `delta = atan2(d_5, a_4)` (arm neither
    /// stretched nor folded)
    pub elbow_deg: f64,
    /// shoulder: wrist centre at least this far from the J1 axis (mm)
    pub shoulder_mm: f64,
}

impl Default for SingularityMargins {
    fn default() -> Self {
        Self { wrist_deg: 10.0, elbow_deg: 10.0, shoulder_mm: 30.0 }
    }
}

impl SingularityMargins {
    /// True when the chain is at least the margins away from every singularity.
    pub fn clear(&self, model: &Model, chain: &Chain) -> bool {
        let wrist = chain.theta[5].sin().abs() >= deg_to_rad(self.wrist_deg).sin();
        let r5 = model.row(5);
        let delta = r5.d.atan2(r5.a);
        let elbow = (chain.theta[3] + delta).sin().abs() >= deg_to_rad(self.elbow_deg).sin();
        let axis_point = chain.frames[2].p;
        let axis = chain.frames[2].z_axis();
        let w = chain.frames[6].p - axis_point;
        let shoulder = (w - axis * w.dot(&axis)).norm() >= self.shoulder_mm;
        wrist && elbow && shoulder
    }
}
