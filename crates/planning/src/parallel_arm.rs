//! Closed-form inverse kinematics of a 6R arm whose three middle axes are parallel (the
//! Universal Robots family and its kin): the analytic 8-solution IK, derived for the nominal
//! modified-DH rows of any chain that has this structure.
//!
//! # Which chains ([`ParallelArm::from_model`])
//! Any number of prismatic joints (external axes) followed by six revolute joints, *arm joints*
//! 1..6, whose MDH rows (`alpha_{j-1}, a_{j-1}, beta_{j-1}, theta_j, d_j` in row `j` of the
//! arm) have, within 0.05 rad / 5 mm:
//! * `alpha_1 = ±90 deg`: arm joint 2 perpendicular to arm joint 1;
//! * `alpha_2, alpha_3 = 0` or `180 deg`: arm joints 2, 3 and 4 parallel;
//! * `alpha_4, alpha_5 = ±90 deg`: arm joint 5 perpendicular to 4, and 6 perpendicular to 5;
//! * `a_5 = 0`: the axis of arm joint 6 meets the axis of arm joint 5;
//! * `|a_2|, |a_3| >= 1 mm`: an upper arm and a forearm (a planar two-link arm);
//! * `beta_1..beta_5 = 0` (the Hayati angles of the rows after the first).
//!
//! `d_1`, the shoulder offset `a_1`, `d_2..d_6`, `a_4` and the theta offsets are free. The
//! wrist need not be spherical: its axes are offset by `d_5` and `d_6` as on a UR arm. Nothing
//! here knows a robot by name: any chain whose rows fit gets the closed form.
//!
//! # Closed form ([`ParallelArm::solve`])
//! In the robot base frame `B` (see [`crate::ik`]), with the MDH angles `theta_j = q_j +
//! theta_offset_j`, `s_j = sign(alpha_j)` for the quarter turns and `c_j = cos(alpha_j) = ±1` for
//! the parallel rows:
//!
//! 1. the origin of arm frame 5 is `o_5 = p_6 - d_6 z_6` (`a_5 = 0`). Every link between arm
//!    frame 1 and arm frame 5 moves it in the plane normal to the parallel axes except the `d`
//!    offsets along them, so its component along the axis of arm joint 2,
//!    `z_2 = s_1 (sin theta_1, -cos theta_1, 0)`, is the constant lateral offset
//!    `D = d_2 + c_2 d_3 + c_2 c_3 d_4`: `rho sin(theta_1 - phi) = s_1 D` with `(rho, phi)` the
//!    polar coordinates of `(o_5x, o_5y)`, two shoulder branches
//!    `theta_1 = phi + asin(s_1 D / rho)` and `phi + pi - asin(s_1 D / rho)`;
//! 2. the axis of arm joint 4 is `z_4 = c_2 c_3 z_2` and `z_6 . z_4 = -s_4 s_5 cos theta_5`:
//!    two wrist branches `theta_5 = ±acos(-c_2 c_3 s_4 s_5 z_6 . z_2)`;
//! 3. `z_4` in the tool frame, `u = R_6^T z_4 = s_4 (sin theta_5 cos theta_6, -sin theta_5
//!    sin theta_6, -s_5 cos theta_5)`, gives `theta_6 = atan2(-s_4 u_y, s_4 u_x)` (signs of
//!    `sin theta_5` divided out; `theta_6 = 0` at the wrist singularity `sin theta_5 = 0`);
//! 4. arm frame 4 is `T_4 = T_6 (L_5 L_6)^-1` (the last two links, known now), and in the frame
//!    of arm joint 2 before its rotation, `P = (Rz(theta_1) Tz(d_1) Rx(alpha_1) Tx(a_1))^-1 T_4
//!    = Rz(theta_2) .. Rz(theta_4) Tz(d_4)` is a planar three-link arm: its origin's `(x, y)` is
//!    `a_2 e(theta_2) + a_3 e(theta_2 + psi)` with `psi = c_2 theta_3`, and its x axis points at
//!    the angle `phi_4 = theta_2 + psi + c_2 c_3 theta_4`. Two elbow branches
//!    `psi = ±acos((x^2 + y^2 - a_2^2 - a_3^2) / (2 a_2 a_3))`, then
//!    `theta_2 = atan2(y, x) - atan2(a_3 sin psi, a_2 + a_3 cos psi)`, `theta_3 = c_2 psi`,
//!    `theta_4 = c_2 c_3 (phi_4 - theta_2 - psi)`.
//!
//! Two shoulder × two wrist × two elbow branches give up to 8 solutions, `q_j = theta_j -
//! theta_offset_j` wrapped into (-pi, pi]. Branch bits as [`ArmSolutions::branches`]: bit 0 the
//! shoulder, bit 1 the elbow (0: `+acos`), bit 2 the wrist (0: `theta_5 = +acos`).
//!
//! On a model that is not exactly this nominal structure (a calibrated model: non-zero
//! `beta`, alphas a little off, compliance, effects), the solutions are seeds of the
//! refinement on the model ([`crate::ik::ToolPoseIk`]).

use nalgebra::{Matrix3, Vector3};
use vatcal_core::Frame;
use vatcal_core::frame::rot_x;
use vatcal_kinematics::Model;

use crate::error::PlanError;
use crate::ik::{
    ArmGeometry, ArmSolutions, ClosedFormArm, ELBOW_SEED_RAD, STRUCTURE_ANGLE_TOL_RAD,
    STRUCTURE_LENGTH_TOL_MM, mdh_link, quarter_turn, sign_of_cos, structure_error, wrap_angle,
    zero_or_half_turn,
};

/// The nominal geometry of a 6R arm with three parallel middle axes and a UR-type wrist, as
/// used by its closed form (see the module docs).
///
/// *Arm joint* `j` (1..=6) is cell joint `first_joint + j - 1`; its MDH row holds
/// `alpha_{j-1}`, `a_{j-1}`, `theta_j`, `d_j` of the arm.
///
/// # Examples
/// The UR5e's rows from its published standard-DH table (`fixtures/ur5e.toml`): every
/// solution reproduces the pose, and the generating joints are among the eight.
/// ```
/// use vatcal_core::{CellFile, JointVector};
/// use vatcal_kinematics::Model;
/// use vatcal_planning::ik::ParallelArm;
///
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml");
/// let model = Model::from_cell(&CellFile::load(path)?)?;
/// let arm = ParallelArm::from_model(&model)?;
/// let q = [0.3, -1.2, 1.0, -0.7, 1.1, 0.4];
/// let target = arm.forward(&q);
/// let solutions = arm.solve(&target);
/// assert_eq!(solutions.len(), 8);
/// for s in solutions.as_slice() {
///     let f = arm.forward(s);
///     assert!((f.p - target.p).norm() < 1e-9);
/// }
/// assert!(solutions.as_slice().iter().any(|s| s.iter().zip(&q).all(|(a, b)| (a - b).abs() < 1e-9)));
/// // and the model's own forward kinematics agrees (the nominal model is this structure)
/// let chain = model.chain(&JointVector::from_slice(&q)?);
/// assert!((chain.tool.p - target.p).norm() < 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParallelArm {
    /// `d_1`: height of arm frame 1 above the base frame `B` (mm)
    pub shoulder_height_mm: f64,
    /// `a_1`: offset along the common normal of arm joints 1 and 2 (mm)
    pub shoulder_forward_mm: f64,
    /// `a_2`: upper arm (mm, signed)
    pub upper_arm_mm: f64,
    /// `a_3`: forearm (mm, signed)
    pub forearm_mm: f64,
    /// `a_4`: offset of arm joint 5 from arm joint 4 along the common normal (mm)
    pub wrist_forward_mm: f64,
    /// `d_2, d_3, d_4`: offsets along the parallel axes (mm)
    pub parallel_d_mm: [f64; 3],
    /// `d_5`: offset of arm frame 5 along the axis of arm joint 5 (mm)
    pub wrist2_mm: f64,
    /// `d_6`: arm frame 5's origin to the tool-changer frame along the axis of arm joint 6 (mm)
    pub flange_mm: f64,
    /// `theta_offset_1..6` of the arm (rad)
    pub theta_offset_rad: [f64; 6],
    /// The nominal structure angles `alpha_1..alpha_5` (rad): exactly `±pi/2` for `alpha_1`,
    /// `alpha_4`, `alpha_5` and `0` or `pi` for `alpha_2`, `alpha_3`.
    pub alpha_rad: [f64; 5],
    /// The cell joint (1-based) of arm joint 1.
    pub first_joint: usize,
    /// `Rx(alpha_1..alpha_5)`, computed once
    rx: [Matrix3<f64>; 5],
}

impl ParallelArm {
    /// Reads the nominal geometry from `model`, checking the structure of the module docs
    /// (angles within 0.05 rad, zero lengths and `beta` within 5 mm / 0.05 rad, so that a
    /// calibrated model qualifies and is refined from the closed-form seeds).
    ///
    /// # Errors
    /// [`PlanError::UnsupportedArm`] naming the first joint row, field and value that do not
    /// fit (e.g. for a Meca500-like arm: `alpha_deg = -90.000` of the row of arm joint 4, which
    /// must be parallel to arm joint 3).
    pub fn from_model(model: &Model) -> Result<Self, PlanError> {
        let f = crate::ik::six_revolute_arm(model)?;
        let r = |j: usize| f + j - 1;
        let row = |j: usize| model.row(r(j));
        let parallel_why = format!("the axes of joints {}, {}, {} parallel", r(2), r(3), r(4));
        let alpha1 = quarter_turn(r(2), row(2).alpha, "the shoulder joint perpendicular to the base joint")?;
        let alpha2 = zero_or_half_turn(r(3), row(3).alpha, &parallel_why)?;
        let alpha3 = zero_or_half_turn(r(4), row(4).alpha, &parallel_why)?;
        let alpha4 = quarter_turn(r(5), row(5).alpha, "the wrist joints perpendicular")?;
        let alpha5 = quarter_turn(r(6), row(6).alpha, "the wrist joints perpendicular")?;
        if row(6).a.abs() > STRUCTURE_LENGTH_TOL_MM {
            return Err(structure_error(
                r(6),
                "a_mm",
                format!("{:.3}", row(6).a),
                &format!("0 ± {STRUCTURE_LENGTH_TOL_MM} mm"),
                &format!("the axes of joints {} and {} meet", r(5), r(6)),
            ));
        }
        for (j, what) in [(3, "an upper arm"), (4, "a forearm")] {
            if row(j).a.abs() < 1.0 {
                return Err(structure_error(r(j), "a_mm", format!("{:.3}", row(j).a), "|a| >= 1 mm", what));
            }
        }
        for j in 2..=6 {
            if row(j).beta.abs() > STRUCTURE_ANGLE_TOL_RAD {
                return Err(structure_error(
                    r(j),
                    "beta_deg",
                    format!("{:.3}", row(j).beta.to_degrees()),
                    &format!("0 ± {:.1} deg", STRUCTURE_ANGLE_TOL_RAD.to_degrees()),
                    "the nominal structure",
                ));
            }
        }
        let alpha_rad = [alpha1, alpha2, alpha3, alpha4, alpha5];
        Ok(Self {
            shoulder_height_mm: row(1).d,
            shoulder_forward_mm: row(2).a,
            upper_arm_mm: row(3).a,
            forearm_mm: row(4).a,
            wrist_forward_mm: row(5).a,
            parallel_d_mm: [row(2).d, row(3).d, row(4).d],
            wrist2_mm: row(5).d,
            flange_mm: row(6).d,
            theta_offset_rad: std::array::from_fn(|j| row(j + 1).theta_offset),
            alpha_rad,
            first_joint: f,
            rx: alpha_rad.map(rot_x),
        })
    }

    /// The lateral offset `D = d_2 + c_2 d_3 + c_2 c_3 d_4` (mm): the distance of arm frame 5's
    /// origin from arm joint 1 along the parallel axes.
    pub fn lateral_offset_mm(&self) -> f64 {
        let (c2, c3) = (sign_of_cos(self.alpha_rad[1]), sign_of_cos(self.alpha_rad[2]));
        let [d2, d3, d4] = self.parallel_d_mm;
        d2 + c2 * d3 + c2 * c3 * d4
    }

    /// All closed-form solutions for the tool-changer frame pose `target` given in the robot
    /// base frame `B`, each the six arm joints (rad; model offsets removed, wrapped).
    pub fn solve(&self, target: &Frame) -> ArmSolutions {
        self.solve_with_reach_slack(target, 0.0)
    }

    /// Like [`ParallelArm::solve`], but a target up to `slack` (relative) beyond the reach of
    /// this nominal-structure arm still gives seeds: an elbow equation with `|cos psi| <= 1 +
    /// slack` gives both elbow branches at ±[`ELBOW_SEED_RAD`] from the stretched / folded arm,
    /// and arm frame 5 up to `slack` closer to arm joint 1 than the lateral offset gives the
    /// seeds of the arm plane tangent to that cylinder. Such seeds are marked
    /// [`ArmSolutions::beyond_reach`]; a calibrated arm may reach what its nominal structure
    /// cannot, and the refinement decides.
    pub fn solve_with_reach_slack(&self, target: &Frame, slack: f64) -> ArmSolutions {
        use std::f64::consts::PI;
        let mut out = ArmSolutions::default();
        let [alpha1, alpha2, alpha3, alpha4, alpha5] = self.alpha_rad;
        let (s1, s4, s5) = (alpha1.signum(), alpha4.signum(), alpha5.signum());
        let (c2, c3) = (sign_of_cos(alpha2), sign_of_cos(alpha3));
        let (a2, a3) = (self.upper_arm_mm, self.forearm_mm);
        let z6 = target.z_axis();
        let o5 = target.p - z6 * self.flange_mm;
        let rho = o5.x.hypot(o5.y);
        let phi = if rho > 1e-12 { o5.y.atan2(o5.x) } else { 0.0 };
        let lateral = self.lateral_offset_mm();
        // step 1: theta_1 from rho sin(theta_1 - phi) = s1 D
        let (shoulder_angle, shoulder_beyond) = if lateral == 0.0 {
            (0.0, false)
        } else if rho > 0.0 && lateral.abs() <= rho {
            ((s1 * lateral / rho).clamp(-1.0, 1.0).asin(), false)
        } else if slack > 0.0 && lateral.abs() <= rho * (1.0 + slack) {
            ((s1 * lateral).signum() * std::f64::consts::FRAC_PI_2, true)
        } else {
            return out;
        };
        let rx = &self.rx;
        let base_to_2 = |theta1: f64| {
            mdh_link(&Matrix3::identity(), 0.0, theta1, self.shoulder_height_mm)
                .compose(&Frame { r: rx[0], p: Vector3::new(self.shoulder_forward_mm, 0.0, 0.0) })
        };
        for (shoulder_bit, theta1) in [(0u8, phi + shoulder_angle), (1, phi + PI - shoulder_angle)] {
            let (st1, ct1) = theta1.sin_cos();
            let z2 = Vector3::new(s1 * st1, -s1 * ct1, 0.0);
            let z4 = z2 * (c2 * c3);
            // step 2: cos theta_5 = -s4 s5 (z6 . z4)
            let cos5 = (-s4 * s5 * z6.dot(&z4)).clamp(-1.0, 1.0);
            let t5 = cos5.acos();
            // step 3: z4 in the tool frame
            let u = target.r.transpose() * z4;
            let frame_2_inv = base_to_2(theta1).inverse();
            for (wrist_bit, theta5) in [(0u8, t5), (4, -t5)] {
                let sin5 = theta5.sin();
                let theta6 = if u.x.hypot(u.y) > 1e-12 && sin5 != 0.0 {
                    let k = s4 * sin5.signum();
                    (-k * u.y).atan2(k * u.x)
                } else {
                    0.0
                };
                // step 4: the planar three-link arm
                let l5 = mdh_link(&rx[3], self.wrist_forward_mm, theta5, self.wrist2_mm);
                let l6 = mdh_link(&rx[4], 0.0, theta6, self.flange_mm);
                let t4 = target.compose(&l5.compose(&l6).inverse());
                let p = frame_2_inv.compose(&t4);
                let (x, y) = (p.p.x, p.p.y);
                let phi4 = p.r[(1, 0)].atan2(p.r[(0, 0)]);
                let ratio = (x * x + y * y - a2 * a2 - a3 * a3) / (2.0 * a2 * a3);
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
                for (elbow_bit, psi) in [(0u8, gamma), (2, -gamma)] {
                    let (s, c) = psi.sin_cos();
                    let theta2 = y.atan2(x) - (a3 * s).atan2(a2 + a3 * c);
                    let theta4 = c2 * c3 * (phi4 - theta2 - psi);
                    let theta = [theta1, theta2, c2 * psi, theta4, theta5, theta6];
                    let q: [f64; 6] =
                        std::array::from_fn(|j| wrap_angle(theta[j] - self.theta_offset_rad[j]));
                    out.push(q, beyond, shoulder_bit | elbow_bit | wrist_bit);
                    if gamma == 0.0 {
                        break;
                    }
                }
                if t5 == 0.0 {
                    break;
                }
            }
            if lateral == 0.0 && rho <= 1e-12 {
                // on the axis of arm joint 1: theta_1 is free, one pass
                break;
            }
        }
        out
    }

    /// Forward kinematics of this nominal-structure arm: the tool-changer frame in the robot
    /// base frame for the six arm joints `q` (rad), the exact inverse of
    /// [`ParallelArm::solve`].
    pub fn forward(&self, q: &[f64; 6]) -> Frame {
        let t: [f64; 6] = std::array::from_fn(|k| q[k] + self.theta_offset_rad[k]);
        let rx = &self.rx;
        let [d2, d3, d4] = self.parallel_d_mm;
        [
            mdh_link(&Matrix3::identity(), 0.0, t[0], self.shoulder_height_mm),
            mdh_link(&rx[0], self.shoulder_forward_mm, t[1], d2),
            mdh_link(&rx[1], self.upper_arm_mm, t[2], d3),
            mdh_link(&rx[2], self.forearm_mm, t[3], d4),
            mdh_link(&rx[3], self.wrist_forward_mm, t[4], self.wrist2_mm),
            mdh_link(&rx[4], 0.0, t[5], self.flange_mm),
        ]
        .iter()
        .fold(Frame::identity(), |acc, l| acc.compose(l))
    }
}

impl ClosedFormArm for ParallelArm {
    fn from_model(model: &Model) -> Result<Self, PlanError> {
        ParallelArm::from_model(model)
    }

    fn first_joint(&self) -> usize {
        self.first_joint
    }

    fn solve_with_reach_slack(&self, target: &Frame, slack: f64) -> ArmSolutions {
        ParallelArm::solve_with_reach_slack(self, target, slack)
    }

    fn forward(&self, q: &[f64; 6]) -> Frame {
        ParallelArm::forward(self, q)
    }

    fn spherical_wrist(&self) -> Option<&ArmGeometry> {
        None
    }

    fn description(&self) -> &'static str {
        "6R arm with three parallel middle axes, UR-type wrist, up to 8 branches"
    }
}
