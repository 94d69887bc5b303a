//! Joint-space motion: limits with margins, singularity margins, the interpolation resolution
//! used for collision checks, and the motion-time model of the tour.
//!
//! # Motion time
//! A move from `a` to `b` is a synchronised joint move: every joint arrives at the same time,
//! limited by the slowest one, so
//!
//! `t(a, b) = max_j |b_j - a_j| / (v_j · fraction)`
//!
//! with `v_1` the guide speed (mm/s), `v_2..v_7` the Meca500 joint speeds \[deg/s\] and `fraction`
//! the planned fraction of the maximum speed, all from the cell's `[motion]` table
//! ([`vatcal_core::CellFile::motion_limits`]). Acceleration phases are ignored (the Meca500 and
//! the Zaber guide accelerate in a few tens of ms, small next to moves of seconds).
//!
//! # Any serial chain
//! [`MotionTimer::for_model`], [`JointBounds::new`], [`Resolution::intervals_for`] and
//! [`SingularityMargins::clear`] work on any chain of the model:
//! * speeds: every prismatic joint moves at the `[motion]` guide speed; the k-th revolute joint
//!   (k = 1..6) at the k-th of the six joint speeds, any further revolute joint at the slowest
//!   of them (the `[motion]` table has six arm speeds);
//! * bounds: the model's limits shrunk by the margins; a continuous (unlimited) revolute joint
//!   gets the window (-180°, 180°) of [`vatcal_kinematics::Model::joint_limits`], not shrunk
//!   (the IK wraps its solutions into it, and a path inside it never needs a whole turn);
//! * singularities: the three Meca500 criteria on the canonical cell; on any other chain the
//!   inverse condition number of the tool Jacobian (`[J_v; L J_w]`, L =
//!   [`SingularityMargins::length_scale_mm`]) must be at least
//!   [`SingularityMargins::min_inverse_condition`].

use nalgebra::DMatrix;
use vatcal_core::cell::MotionLimits;
use vatcal_core::{JointKind, JointVector, MAX_JOINTS, deg_to_rad};
use vatcal_kinematics::{Chain, Model};

use crate::error::PlanError;

/// Speeds of the joints in internal units (mm/s for prismatic, rad/s for revolute joints),
/// already multiplied by the speed fraction, plus the fixed times of the campaign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionTimer {
    /// effective speed of each joint (mm/s, rad/s); entries `joints..` are unused (1.0)
    pub speed: [f64; MAX_JOINTS],
    /// number of joints timed
    pub joints: usize,
    /// time per measurement (settle + auto-centre) (s)
    pub measurement_s: f64,
    /// time of one manual re-placement of the probe plate (s)
    pub probe_replacement_s: f64,
}

impl MotionTimer {
    /// From the cell's `[motion]` limits, for the canonical Meca500-on-guide cell (joint 1 the
    /// guide, joints 2..7 the arm).
    pub fn from_limits(limits: &MotionLimits) -> Result<Self, PlanError> {
        let mut kinds = [JointKind::Revolute; 7];
        kinds[0] = JointKind::Prismatic;
        Self::for_kinds(limits, &kinds)
    }

    /// From the cell's `[motion]` limits for the joints of `model` (see the module docs: any
    /// chain). Equals [`MotionTimer::from_limits`] on the canonical cell.
    pub fn for_model(limits: &MotionLimits, model: &Model) -> Result<Self, PlanError> {
        Self::for_kinds(limits, model.joint_kinds())
    }

    /// From the cell's `[motion]` limits for joints of the given kinds (see the module docs).
    pub fn for_kinds(limits: &MotionLimits, kinds: &[JointKind]) -> Result<Self, PlanError> {
        let f = limits.speed_fraction;
        if !(f > 0.0 && f <= 1.0) {
            return Err(PlanError::Option {
                option: "motion.speed_fraction".into(),
                reason: format!("must be in (0, 1], got {f}"),
            });
        }
        if kinds.is_empty() || kinds.len() > MAX_JOINTS {
            return Err(PlanError::Option {
                option: "motion".into(),
                reason: format!("a chain has 1..={MAX_JOINTS} joints, got {}", kinds.len()),
            });
        }
        let slowest = limits.joint_speed_deg_per_s.iter().copied().fold(f64::INFINITY, f64::min);
        let mut speed = [1.0; MAX_JOINTS];
        let mut revolute = 0;
        for (s, kind) in speed.iter_mut().zip(kinds) {
            *s = if kind.is_revolute() {
                let v = limits.joint_speed_deg_per_s.get(revolute).copied().unwrap_or(slowest);
                revolute += 1;
                deg_to_rad(v) * f
            } else {
                limits.guide_speed_mm_per_s * f
            };
        }
        if speed.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(PlanError::Option {
                option: "motion".into(),
                reason: format!("every speed must be positive, got {limits:?}"),
            });
        }
        Ok(Self {
            speed,
            joints: kinds.len(),
            measurement_s: limits.measurement_s,
            probe_replacement_s: limits.probe_replacement_s,
        })
    }

    /// Time (s) of the synchronised joint move from `a` to `b`.
    pub fn move_time_s(&self, a: &JointVector, b: &JointVector) -> f64 {
        let n = self.joints.min(a.len()).min(b.len());
        (0..n).map(|k| (b[k] - a[k]).abs() / self.speed[k]).fold(0.0, f64::max)
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
    /// Number of intervals needed to go from `a` to `b` at this resolution (>= 1), on the
    /// canonical cell (joint 1 the guide, the others revolute).
    pub fn intervals(&self, a: &JointVector, b: &JointVector) -> usize {
        let step_rad = deg_to_rad(self.max_joint_step_deg);
        let mut n = (b[0] - a[0]).abs() / self.max_guide_step_mm;
        for k in 1..a.len().min(b.len()) {
            n = n.max((b[k] - a[k]).abs() / step_rad);
        }
        (n.ceil() as usize).max(1)
    }

    /// Number of intervals needed to go from `a` to `b` at this resolution (>= 1) for joints of
    /// the given kinds (prismatic joints at `max_guide_step_mm`, revolute at
    /// `max_joint_step_deg`). Equals [`Resolution::intervals`] on the canonical cell.
    pub fn intervals_for(&self, a: &JointVector, b: &JointVector, kinds: &[JointKind]) -> usize {
        let step_rad = deg_to_rad(self.max_joint_step_deg);
        let mut n: f64 = 0.0;
        for (k, kind) in kinds.iter().enumerate().take(a.len().min(b.len())) {
            let step = if kind.is_revolute() { step_rad } else { self.max_guide_step_mm };
            n = n.max((b[k] - a[k]).abs() / step);
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
    for k in 0..a.len().min(b.len()) {
        q[k] = a[k] + t * (b[k] - a[k]);
    }
    q
}

/// Margin kept from the arm joint limits by every commanded move that is not a measurement
/// (retreat poses, path waypoints) (deg). Measurement poses keep the larger
/// `joint_margin_deg` of the candidate options, because auto-centring moves them slightly.
pub const MOVE_MARGIN_DEG: f64 = 0.5;

/// Joint limits shrunk by margins (internal units), one `(lo, hi)` per joint of the chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointBounds {
    /// bounds per cell joint (index = joint - 1); entries `len..` are unused
    pub bounds: [(f64, f64); MAX_JOINTS],
    /// number of joints
    pub len: usize,
    /// per joint: true when revolute (the arm margin and the rad slack apply)
    pub revolute: [bool; MAX_JOINTS],
}

impl JointBounds {
    /// The model's limits shrunk by `joint_margin_deg` on the revolute joints and
    /// `guide_margin_mm` on the prismatic joints (a continuous revolute joint keeps its
    /// (-180°, 180°) window unshrunk; see the module docs).
    pub fn new(model: &Model, joint_margin_deg: f64, guide_margin_mm: f64) -> Result<Self, PlanError> {
        let n = model.joint_count();
        let mut bounds = [(0.0, 0.0); MAX_JOINTS];
        let mut revolute = [false; MAX_JOINTS];
        bounds[..n].copy_from_slice(model.joint_limits());
        for (k, b) in bounds.iter_mut().enumerate().take(n) {
            revolute[k] = model.is_revolute(k + 1);
            let continuous = model.joint_limit(k + 1).is_none();
            let m = match (revolute[k], continuous) {
                (false, _) => guide_margin_mm,
                (true, false) => deg_to_rad(joint_margin_deg),
                (true, true) => 0.0,
            };
            *b = (b.0 + m, b.1 - m);
            if b.0 > b.1 || b.0.is_nan() || b.1.is_nan() {
                return Err(PlanError::Option {
                    option: if revolute[k] { "joint margin".into() } else { "guide margin".into() },
                    reason: format!("the margin leaves nothing of the range of joint {}", k + 1),
                });
            }
        }
        Ok(Self { bounds, len: n, revolute })
    }

    /// The bounds of the chain's joints (index = joint - 1).
    pub fn as_slice(&self) -> &[(f64, f64)] {
        &self.bounds[..self.len]
    }

    /// True when every joint is within its shrunk range.
    pub fn contains(&self, q: &JointVector) -> bool {
        q.len() == self.len
            && q.as_slice().iter().zip(self.as_slice()).all(|(v, (lo, hi))| *v >= *lo && *v <= *hi)
    }

    /// True when every joint is within its range widened by `slack` (mm / rad).
    pub fn contains_with_slack(&self, q: &JointVector, slack_mm: f64, slack_rad: f64) -> bool {
        q.len() == self.len
            && q.as_slice().iter().zip(self.as_slice()).enumerate().all(|(k, (v, (lo, hi)))| {
                let s = if self.revolute[k] { slack_rad } else { slack_mm };
                *v >= *lo - s && *v <= *hi + s
            })
    }
}

/// Margins from the three singularities of the Meca500 (canonical cell), and from singular
/// configurations of any other chain (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingularityMargins {
    /// wrist: `|sin theta_6| >= sin(margin)` (J5 away from 0)
    pub wrist_deg: f64,
    /// elbow: `|sin(theta_4 + delta)| >= sin(margin)` with `delta = atan2(d_5, a_4)` (arm neither
    /// stretched nor folded)
    pub elbow_deg: f64,
    /// shoulder: wrist centre at least this far from the J1 axis (mm)
    pub shoulder_mm: f64,
    /// any chain other than the canonical cell: smallest singular value / largest singular
    /// value of the scaled tool Jacobian `[J_v; L J_w]`
    pub min_inverse_condition: f64,
    /// the length `L` that weighs the angular rows (mm/rad)
    pub length_scale_mm: f64,
}

impl Default for SingularityMargins {
    fn default() -> Self {
        Self {
            wrist_deg: 10.0,
            elbow_deg: 10.0,
            shoulder_mm: 30.0,
            min_inverse_condition: 0.02,
            length_scale_mm: 100.0,
        }
    }
}

impl SingularityMargins {
    /// True when the chain is at least the margins away from every singularity (the Meca500
    /// criteria on the canonical cell, the Jacobian's inverse condition number on any other
    /// chain).
    pub fn clear(&self, model: &Model, chain: &Chain) -> bool {
        if !model.is_meca500_on_guide() {
            return self.inverse_condition(model, chain) >= self.min_inverse_condition;
        }
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

    /// Inverse condition number (smallest / largest singular value) of the scaled 6×N tool
    /// Jacobian `[z_i × (p - o_i); L z_i]` (revolute) / `[z_i; 0]` (prismatic) at `chain`;
    /// for fewer than six joints, of its N×N Gram matrix's square root (the N singular values).
    pub fn inverse_condition(&self, model: &Model, chain: &Chain) -> f64 {
        let n = model.joint_count();
        let p = chain.tool.p;
        let l = self.length_scale_mm;
        let mut j = DMatrix::<f64>::zeros(6, n);
        for i in 1..=n {
            let f = &chain.frames[i];
            let z = f.z_axis();
            let (lin, ang) = if model.is_revolute(i) {
                (z.cross(&(p - f.p)), z * l)
            } else {
                (z, nalgebra::Vector3::zeros())
            };
            for r in 0..3 {
                j[(r, i - 1)] = lin[r];
                j[(r + 3, i - 1)] = ang[r];
            }
        }
        let s = j.singular_values();
        let max = s.max();
        let min = s.min();
        if max > 0.0 { min / max } else { 0.0 }
    }
}
