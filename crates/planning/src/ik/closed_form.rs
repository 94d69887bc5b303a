//! The closed-form solution of a 6R arm with a spherical wrist ([`ArmGeometry`]): the
//! structure check, forward kinematics and the up to eight branches ([`ArmSolutions`]), and
//! the [`ClosedFormArm`] trait every closed form implements.

use nalgebra::Matrix3;
use vatcal_core::Frame;
use vatcal_core::frame::{rot_x, rot_z};
use vatcal_kinematics::Model;

use super::common::wrap_angle;
use super::structure::{
    STRUCTURE_LENGTH_TOL_MM, mdh_link, quarter_turn, sign_of_cos, six_revolute_arm, structure_error,
    zero_or_half_turn,
};
use crate::error::PlanError;

/// Elbow angle from the stretched / folded arm at which seeds are placed for a wrist centre
/// just beyond the nominal reach (rad).
pub const ELBOW_SEED_RAD: f64 = 0.05;
/// Relative reach slack of the seeds used for refinement (see
/// [`ArmGeometry::solve_with_reach_slack`]).
pub(super) const SEED_REACH_SLACK: f64 = 0.02;

/// The nominal geometry of a 6R arm with a spherical wrist and an ortho-parallel shoulder and
/// elbow, as used by the closed form (see the module docs).
///
/// *Arm joint* `j` (1..=6) is cell joint `first_joint + j - 1`; its MDH row holds `alpha_{j-1}`,
/// `a_{j-1}`, `theta_j`, `d_j` of the arm. The field names keep the Meca500 reading of the
/// canonical cell (where arm joint 1 is cell joint 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmGeometry {
    /// `d_1`: height of the shoulder (arm joint 2) above the base frame `B` (mm)
    pub shoulder_height_mm: f64,
    /// `a_2`: upper-arm length (arm joint 2 to arm joint 3 axis) (mm)
    pub upper_arm_mm: f64,
    /// `a_3`: elbow offset (mm)
    pub elbow_offset_mm: f64,
    /// `d_4`: forearm length to the wrist centre (mm)
    pub forearm_mm: f64,
    /// `d_6`: wrist centre to the tool-changer frame (mm)
    pub flange_mm: f64,
    /// `theta_offset_1..6` of the arm (rad)
    pub theta_offset_rad: [f64; 6],
    /// `a_1`: shoulder offset along the common normal of arm joints 1 and 2 (mm; e.g. 260 mm
    /// on a KUKA KR 16, 0 on the Meca500)
    pub shoulder_forward_mm: f64,
    /// `d_2 + cos(alpha_2) d_3`: sideways offset of the arm plane from arm joint 1 along the
    /// axis of arm joint 2 (mm; the PUMA 560's 149 mm, 0 on most arms)
    pub shoulder_lateral_mm: f64,
    /// The nominal structure angles `alpha_1..alpha_5` (rad): exactly `±pi/2` for
    /// `alpha_1, alpha_3, alpha_4, alpha_5` and `0` or `pi` for `alpha_2`.
    pub alpha_rad: [f64; 5],
    /// The cell joint (1-based) of arm joint 1 (the prismatic joints before it are the external
    /// axes; 2 on the canonical cell).
    pub first_joint: usize,
    /// `Rx(alpha_1..alpha_5)` and `Rx(-alpha_5)`, computed once (the solver's hot path would
    /// otherwise evaluate their sines and cosines on every call)
    pub(super) rx: [Matrix3<f64>; 6],
}

/// Up to eight closed-form solutions (the six arm joints, rad) for one tool pose.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ArmSolutions {
    pub(super) q: [[f64; 6]; 8],
    pub(super) beyond_reach: [bool; 8],
    pub(super) branch: [u8; 8],
    pub(super) len: usize,
}

impl ArmSolutions {
    /// The solutions found (0..=8), each the six arm joints (rad), wrapped to (-pi, pi].
    pub fn as_slice(&self) -> &[[f64; 6]] {
        &self.q[..self.len]
    }

    /// Number of solutions.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when there is no solution (pose out of reach).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// For each solution: true when it is a seed placed just beyond the nominal reach
    /// ([`ArmGeometry::solve_with_reach_slack`]), not an exact solution.
    pub fn beyond_reach(&self) -> &[bool] {
        &self.beyond_reach[..self.len]
    }

    /// For each solution its branch: bit 0 = shoulder (0: wrist centre on the +x side of the
    /// arm-joint-1 plane), bit 1 = elbow (0: `+acos`), bit 2 = wrist (0: the wrist Euler
    /// solution whose middle angle is `>= 0`; on the Meca500 `theta_6 >= 0`).
    pub fn branches(&self) -> &[u8] {
        &self.branch[..self.len]
    }

    /// The solution of branch `branch`, if present.
    pub fn of_branch(&self, branch: u8) -> Option<[f64; 6]> {
        self.branches().iter().position(|b| *b == branch).map(|k| self.q[k])
    }

    pub(crate) fn push(&mut self, q: [f64; 6], beyond_reach: bool, branch: u8) {
        let duplicate = self.as_slice().iter().any(|p| p.iter().zip(&q).all(|(a, b)| (a - b).abs() < 1e-12));
        if !duplicate && self.len < 8 {
            self.q[self.len] = q;
            self.beyond_reach[self.len] = beyond_reach;
            self.branch[self.len] = branch;
            self.len += 1;
        }
    }
}

impl ArmGeometry {
    /// Reads the nominal arm geometry from `model`, checking that its chain is a 6R arm with a
    /// spherical wrist and an ortho-parallel shoulder and elbow, optionally preceded by
    /// prismatic joints (external axes). In the arm's numbering (row `j` holds `alpha_{j-1}`,
    /// `a_{j-1}`, `d_j`):
    ///
    /// * wrist (checked first): `a_4 = d_5 = a_5 = 0` (the axes of arm joints 4, 5, 6 meet in
    ///   one point) and `alpha_4, alpha_5 = ±90 deg`;
    /// * shoulder and elbow: `alpha_1 = ±90 deg` (joint 2 perpendicular to joint 1),
    ///   `alpha_2 = 0` or `180 deg` (joints 2 and 3 parallel), `alpha_3 = ±90 deg`, an upper arm
    ///   `|a_2| >= 1 mm` and a wrist centre off the joint-3 axis (`|(a_3, d_4)| >= 1 mm`);
    ///   `a_1`, `d_1`, `d_2`, `d_3`, `a_3`, `d_4`, `d_6` and the theta offsets are free.
    ///
    /// Angles within 0.05 rad and zero lengths within 5 mm are accepted, so that a calibrated
    /// model qualifies: its small deviations (and beta, compliance, effects) are removed by the
    /// refinement.
    ///
    /// # Errors
    /// [`PlanError::UnsupportedArm`] naming the first joint row, field and value that do not
    /// fit (the wrist first: a UR5e-class arm is reported as not having a spherical wrist).
    pub fn from_model(model: &Model) -> Result<Self, PlanError> {
        let f = six_revolute_arm(model)?;
        // cell row of arm joint j
        let r = |j: usize| f + j - 1;
        let row = |j: usize| model.row(r(j));
        let wrist =
            format!("a spherical wrist: the axes of joints {}, {}, {} meet in one point", r(4), r(5), r(6));
        let zero = |j: usize, field: &str, v: f64, why: &str| {
            if v.abs() > STRUCTURE_LENGTH_TOL_MM {
                return Err(structure_error(
                    r(j),
                    field,
                    format!("{v:.3}"),
                    &format!("0 ± {STRUCTURE_LENGTH_TOL_MM} mm"),
                    why,
                ));
            }
            Ok(())
        };
        zero(5, "a_mm", row(5).a, &wrist)?;
        zero(5, "d_mm", row(5).d, &wrist)?;
        zero(6, "a_mm", row(6).a, &wrist)?;
        let alpha4 = quarter_turn(r(5), row(5).alpha, "perpendicular wrist axes")?;
        let alpha5 = quarter_turn(r(6), row(6).alpha, "perpendicular wrist axes")?;
        let alpha1 = quarter_turn(r(2), row(2).alpha, "the shoulder joint perpendicular to the base joint")?;
        let alpha2 = zero_or_half_turn(r(3), row(3).alpha, "the shoulder and elbow joints parallel")?;
        let alpha3 = quarter_turn(r(4), row(4).alpha, "the forearm joint perpendicular to the elbow joint")?;
        let upper_arm_mm = row(3).a;
        if upper_arm_mm.abs() < 1.0 {
            return Err(structure_error(
                r(3),
                "a_mm",
                format!("{upper_arm_mm:.3}"),
                "|a| >= 1 mm",
                "an upper arm",
            ));
        }
        if row(4).a.hypot(row(4).d) < 1.0 {
            return Err(structure_error(
                r(4),
                "(a_mm, d_mm)",
                format!("({:.3}, {:.3})", row(4).a, row(4).d),
                "a length >= 1 mm",
                "a wrist centre off the elbow axis",
            ));
        }
        let sigma = sign_of_cos(alpha2);
        let theta_offset_rad = std::array::from_fn(|j| row(j + 1).theta_offset);
        Ok(Self {
            shoulder_height_mm: row(1).d,
            upper_arm_mm,
            elbow_offset_mm: row(4).a,
            forearm_mm: row(4).d,
            flange_mm: row(6).d,
            theta_offset_rad,
            shoulder_forward_mm: row(2).a,
            shoulder_lateral_mm: row(2).d + sigma * row(3).d,
            alpha_rad: [alpha1, alpha2, alpha3, alpha4, alpha5],
            first_joint: f,
            rx: [rot_x(alpha1), rot_x(alpha2), rot_x(alpha3), rot_x(alpha4), rot_x(alpha5), rot_x(-alpha5)],
        })
    }

    /// `cos(alpha_2)`: +1 when `alpha_2 = 0`, -1 when `alpha_2 = pi`.
    fn sigma(&self) -> f64 {
        sign_of_cos(self.alpha_rad[1])
    }

    /// All closed-form solutions for the tool-changer frame pose `target` given in the robot
    /// base frame `B`. Each is the six arm joints (rad) (model offsets removed, wrapped).
    pub fn solve(&self, target: &Frame) -> ArmSolutions {
        self.solve_with_reach_slack(target, 0.0)
    }

    /// Like [`ArmGeometry::solve`], but a wrist centre up to `slack` (relative, in the elbow
    /// equation `|K / L| <= 1 + slack`) beyond the reach of this nominal-structure arm still
    /// gives seeds: both elbow branches at ±[`ELBOW_SEED_RAD`] from the stretched/folded arm.
    /// Likewise a wrist centre closer to arm joint 1 than the sideways shoulder offset gives
    /// the seeds of the arm plane through that axis. A calibrated arm may reach what its
    /// nominal structure cannot; the refinement decides.
    pub fn solve_with_reach_slack(&self, target: &Frame, slack: f64) -> ArmSolutions {
        use std::f64::consts::PI;
        let mut out = ArmSolutions::default();
        let z6 = target.z_axis();
        let w = target.p - z6 * self.flange_mm;
        let rho = w.x.hypot(w.y);
        let h = w.z - self.shoulder_height_mm;
        let theta1_base = if rho > 1e-12 { w.y.atan2(w.x) } else { 0.0 };
        let s1 = self.alpha_rad[0].signum();
        let s3 = self.alpha_rad[2].signum();
        let sigma = self.sigma();
        let lateral = self.shoulder_lateral_mm;
        let (a2, a3) = (self.upper_arm_mm, self.elbow_offset_mm);
        // the wrist centre in arm frame 3 is (a3, e, 0) after Rz(theta4)
        let e = -sigma * s3 * self.forearm_mm;
        let l = a3.hypot(e);
        let delta = e.atan2(a3);
        // in-plane distance of the wrist centre from arm joint 1 (the sideways offset removed)
        let (r_abs, shoulder_beyond) = if lateral == 0.0 {
            (rho, false)
        } else {
            let r2 = rho * rho - lateral * lateral;
            if r2 >= 0.0 {
                (r2.sqrt(), false)
            } else if slack > 0.0 {
                (0.0, true)
            } else {
                return out;
            }
        };
        for (shoulder_bit, shoulder) in [(0u8, 1.0), (1, -1.0)] {
            let r = shoulder * r_abs;
            let theta1 = if lateral == 0.0 {
                if shoulder > 0.0 { theta1_base } else { theta1_base + PI }
            } else {
                w.y.atan2(w.x) - (-s1 * lateral).atan2(r)
            };
            let x = r - self.shoulder_forward_mm;
            let k = (x * x + h * h - a2 * a2 - a3 * a3 - e * e) / (2.0 * a2);
            let ratio = k / l;
            if ratio.is_nan() || ratio.abs() > 1.0 + 1e-12 + slack {
                continue;
            }
            let beyond = shoulder_beyond || ratio.abs() > 1.0 + 1e-12;
            let gamma = if ratio.abs() <= 1.0 + 1e-12 {
                ratio.clamp(-1.0, 1.0).acos()
            } else {
                let edge = if ratio > 0.0 { 0.0 } else { PI };
                (edge - ELBOW_SEED_RAD).abs()
            };
            for (elbow_bit, elbow) in [(0u8, gamma), (2, -gamma)] {
                // psi = sigma theta3: the wrist centre in arm frame 2 is
                // v = (a2, 0) + Rot(psi) (a3, e), and (x, s1 h) = Rot(theta2) v
                let psi = elbow - delta;
                let (s, c) = psi.sin_cos();
                let v_r = a2 + a3 * c - e * s;
                let v_h = -a3 * s - e * c;
                let theta2 = v_h.atan2(v_r) + s1 * h.atan2(x);
                let branch = shoulder_bit | elbow_bit;
                self.push_wrist(&mut out, target, [theta1, theta2, sigma * psi], beyond, branch);
                if gamma == 0.0 {
                    break;
                }
            }
        }
        out
    }

    /// Forward kinematics of this nominal-structure arm: the tool-changer frame in the robot
    /// base frame for the six arm joints `q` (rad) (the exact inverse of
    /// [`ArmGeometry::solve`]). The sideways shoulder offset is put on arm row 3.
    pub fn forward(&self, q: &[f64; 6]) -> Frame {
        let t: [f64; 6] = std::array::from_fn(|k| q[k] + self.theta_offset_rad[k]);
        let rx = &self.rx;
        [
            mdh_link(&rot_x(0.0), 0.0, t[0], self.shoulder_height_mm),
            mdh_link(&rx[0], self.shoulder_forward_mm, t[1], 0.0),
            mdh_link(&rx[1], self.upper_arm_mm, t[2], self.sigma() * self.shoulder_lateral_mm),
            mdh_link(&rx[2], self.elbow_offset_mm, t[3], self.forearm_mm),
            mdh_link(&rx[3], 0.0, t[4], 0.0),
            mdh_link(&rx[4], 0.0, t[5], self.flange_mm),
        ]
        .iter()
        .fold(Frame::identity(), |acc, l| acc.compose(l))
    }

    /// Adds the (up to two) wrist solutions for given arm angles theta_1..3.
    ///
    /// With `R_3` the orientation of arm frame 3, `M = R_3^T R_6 Rx(-alpha_5)` (times
    /// `Rx(pi)` when `alpha_3 = alpha_4`) is `Ry(a) Rz(b) Ry(c)` (Y-Z-Y Euler angles) with
    /// `theta_4 = -sign(alpha_3) a`, `theta_5 = p b`, `theta_6 = -sign(alpha_5) p c`
    /// (`p = -1` when `alpha_3 = alpha_4`, else 1).
    fn push_wrist(&self, out: &mut ArmSolutions, target: &Frame, arm: [f64; 3], beyond: bool, branch: u8) {
        use std::f64::consts::PI;
        let [t1, t2, t3] = arm;
        let [_, alpha2, alpha3, alpha4, alpha5] = self.alpha_rad;
        let rx = &self.rx;
        let r3 = if alpha2 == 0.0 {
            rot_z(t1) * rx[0] * rot_z(t2 + t3)
        } else {
            rot_z(t1) * rx[0] * rot_z(t2) * rx[1] * rot_z(t3)
        };
        let mut m = r3.transpose() * target.r * rx[5];
        let flip = alpha3 == alpha4;
        if flip {
            // times Rx(pi) = diag(1, -1, -1), exactly
            for r in 0..3 {
                m[(r, 1)] = -m[(r, 1)];
                m[(r, 2)] = -m[(r, 2)];
            }
        }
        let p = if flip { -1.0 } else { 1.0 };
        let (k4, k6) = (-alpha3.signum(), -alpha5.signum() * p);
        let s6 = m[(0, 1)].hypot(m[(2, 1)]);
        let c6 = m[(1, 1)];
        let mut add = |a: f64, b: f64, c: f64, wrist_bit: u8| {
            let theta = [t1, t2, t3, k4 * a, p * b, k6 * c];
            let mut q = [0.0; 6];
            for k in 0..6 {
                q[k] = wrap_angle(theta[k] - self.theta_offset_rad[k]);
            }
            out.push(q, beyond, branch | wrist_bit);
        };
        if s6 > 1e-12 {
            let b = s6.atan2(c6);
            let a = m[(2, 1)].atan2(-m[(0, 1)]);
            let c = m[(1, 2)].atan2(m[(1, 0)]);
            add(a, b, c, 0);
            add(a + PI, -b, c + PI, 4);
        } else if c6 > 0.0 {
            // b = 0: M = Ry(a + c); choose a = 0
            add(0.0, 0.0, m[(0, 2)].atan2(m[(0, 0)]), 0);
        } else {
            // b = pi: M = Ry(a - c) Rz(pi); choose a = 0
            let mm = m * rot_z(PI).transpose();
            add(0.0, PI, -mm[(0, 2)].atan2(mm[(0, 0)]), 0);
        }
    }
}

/// A closed-form IK of the nominal structure of a 6R arm (optionally behind prismatic
/// external axes), the seed source of [`ToolPoseIk`](crate::ik::ToolPoseIk): [`ArmGeometry`]
/// (spherical wrist) and [`ParallelArm`](crate::ik::ParallelArm) (three parallel middle axes,
/// UR-type wrist).
pub trait ClosedFormArm: std::fmt::Debug + Clone + Sized {
    /// Reads the nominal geometry from a model, checking that its chain has the structure.
    ///
    /// # Errors
    /// [`PlanError::UnsupportedArm`] naming the first joint row, field and value that do not
    /// fit.
    fn from_model(model: &Model) -> Result<Self, PlanError>;

    /// The cell joint (1-based) of arm joint 1 (the prismatic joints before it are the
    /// external axes).
    fn first_joint(&self) -> usize;

    /// Every closed-form solution (six arm joints, rad, wrapped) for the tool-changer frame
    /// pose `target` in the robot base frame; a target up to `slack` (relative) beyond the
    /// nominal reach still gives seeds, marked [`ArmSolutions::beyond_reach`].
    fn solve_with_reach_slack(&self, target: &Frame, slack: f64) -> ArmSolutions;

    /// Forward kinematics of the nominal structure (tool-changer frame in the robot base frame).
    fn forward(&self, q: &[f64; 6]) -> Frame;

    /// The spherical-wrist geometry, when the arm has one (its wrist-singularity band search
    /// needs it, [`ToolPoseIk::add_wrist_band_solutions`](crate::ik::ToolPoseIk::add_wrist_band_solutions)).
    fn spherical_wrist(&self) -> Option<&ArmGeometry>;

    /// What the closed form covers, for messages (e.g. "6R arm with a spherical wrist, up to 8
    /// branches").
    fn description(&self) -> &'static str;
}

impl ClosedFormArm for ArmGeometry {
    fn from_model(model: &Model) -> Result<Self, PlanError> {
        ArmGeometry::from_model(model)
    }

    fn first_joint(&self) -> usize {
        self.first_joint
    }

    fn solve_with_reach_slack(&self, target: &Frame, slack: f64) -> ArmSolutions {
        ArmGeometry::solve_with_reach_slack(self, target, slack)
    }

    fn forward(&self, q: &[f64; 6]) -> Frame {
        ArmGeometry::forward(self, q)
    }

    fn spherical_wrist(&self) -> Option<&ArmGeometry> {
        Some(self)
    }

    fn description(&self) -> &'static str {
        "6R arm with a spherical wrist, up to 8 branches"
    }
}
