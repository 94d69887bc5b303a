//! Inverse kinematics of a cell: closed form for the nominal geometry of a 6R arm with a
//! spherical wrist (the Meca500, KUKA KR, ABB IRB, Fanuc, Stäubli type) or with three parallel
//! middle axes and a UR-type wrist ([`ParallelArm`], the Universal Robots family), numerical
//! refinement on the full [`Model`]; [`ModelIk`] picks a closed form wherever the chain
//! qualifies and the multi-start numerical IK ([`crate::numeric_ik`]) otherwise. Both closed
//! forms are seed sources of [`ToolPoseIk`] ([`ClosedFormArm`]); the rest of these docs
//! describe the spherical-wrist one, `crate::parallel_arm` the other.
//!
//! # Which chains ([`ArmGeometry::from_model`])
//! Any number of prismatic joints (external axes, e.g. the canonical guide) followed by six
//! revolute joints, *arm joints* 1..6, whose MDH rows (`alpha_{j-1}, a_{j-1}, theta_j, d_j` in
//! row `j` of the arm) have, within 0.05 rad / 5 mm:
//! * a spherical wrist: `a_4 = d_5 = a_5 = 0` (axes 4, 5, 6 meet in the wrist centre),
//!   `alpha_4, alpha_5 = ±90 deg`;
//! * an ortho-parallel shoulder and elbow: `alpha_1 = ±90 deg`, `alpha_2 = 0` or `180 deg`,
//!   `alpha_3 = ±90 deg`, `|a_2| >= 1 mm`.
//!
//! `a_1` (shoulder forward offset), `d_1`, the sideways shoulder offset `D = d_2 + cos(alpha_2)
//! d_3`, `a_3`, `d_4`, `d_6` and the theta offsets are free. A chain that does not qualify gets
//! [`PlanError::UnsupportedArm`] naming the row, field and value (the wrist is checked first,
//! so a UR5e-class arm is reported as not having a spherical wrist). [`ToolPoseIk`] and
//! [`ModelIk`] hold at most one prismatic joint (the guide, joint 1) at given positions.
//!
//! # Frames
//! The *robot base frame* `B` is the parent of the first arm frame: the frame after the
//! prismatic joints followed by the fixed part `Rx(alpha_0) Tx(a_0) Ry(beta_0)` of the first arm
//! row (on the canonical cell: the carriage frame 1 and the sideways mounting
//! `alpha_1 = -90 deg` of cell row 2). It depends on the prismatic joints only
//! ([`robot_base_frame`]).
//!
//! # Closed form ([`ArmGeometry::solve`])
//! In the MDH angles `theta_j = q_j + theta_offset_j` of the arm, with `s_j = sign(alpha_j)`,
//! `sigma = cos(alpha_2)`:
//!
//! 1. wrist centre `w = p_6 - d_6 z_6` (origin of arm frames 4 and 5), `h = w_z - d_1`,
//!    `rho = |(w_x, w_y)|`;
//! 2. shoulder: the in-plane distance `r = ±sqrt(rho^2 - D^2)` (two branches) and
//!    `theta_1 = atan2(w_y, w_x) - atan2(-s_1 D, r)` (`= atan2(w_y, w_x)` or `+ pi` when
//!    `D = 0`); `x = r - a_1`;
//! 3. elbow: with `e = -sigma s_3 d_4`, `L = |(a_3, e)|`, `delta = atan2(e, a_3)`:
//!    `cos(psi + delta) = (x^2 + h^2 - a_2^2 - a_3^2 - e^2) / (2 a_2 L)`, two branches
//!    `psi = ±acos(..) - delta`, `theta_3 = sigma psi`;
//! 4. `theta_2 = atan2(v_h, v_r) + s_1 atan2(h, x)` with `v = (a_2 + a_3 cos psi - e sin psi,
//!    -a_3 sin psi - e cos psi)`;
//! 5. wrist: `M = R_3^T R_6 Rx(-alpha_5)` (times `Rx(pi)` when `alpha_3 = alpha_4`)
//!    `= Ry(a) Rz(b) Ry(c)` (Y-Z-Y Euler angles, two branches `b = ±acos(M_11)`), and
//!    `theta_4 = -s_3 a`, `theta_5 = p b`, `theta_6 = -s_5 p c` (`p = -1` when
//!    `alpha_3 = alpha_4`, else 1).
//!
//! Two shoulder × two elbow × two wrist branches give up to 8 solutions; `q_j = theta_j -
//! theta_offset_j`, wrapped into (-pi, pi]. On the canonical cell (`alpha = (-90, 0, -90, 90,
//! -90) deg`, `a_1 = D = 0`) this is, operation for operation, the Meca500 closed form the
//! planner has always used. The closed form uses the model's own lengths and theta offsets; the
//! small angular errors of a calibrated model (alpha, beta, compliance, effects) are removed by
//! [`refine_tool_pose`].
//!
//! # Seeds on a calibrated model ([`ToolPoseIk::seeds`])
//! Each closed-form branch is corrected on its own branch before the refinement
//! (`T* E(q)⁻¹` with `E` the nominal-structure error at the seed, [`SEED_CORRECTIONS`] times),
//! and a wrist centre up to 2 % beyond the nominal reach still gives seeds
//! ([`ArmGeometry::solve_with_reach_slack`]). Within a few degrees of the wrist singularity a
//! calibrated wrist (axes no longer exactly intersecting) can have more than eight solutions,
//! notably when the wrist centre is also near the axis of arm joint 1: each refined solution
//! within [`WRIST_SCAN_BAND_DEG`] of the wrist singularity has its soft direction
//! (`theta_4` and `theta_6` turned against each other) searched over a whole turn, and every
//! further solution found is added ([`ToolPoseIk::add_wrist_band_solutions`]).
//!
//! # Refinement ([`refine_tool_pose`])
//! Levenberg–Marquardt on the 6-DOF tool-frame error `[p* - p; log(R* R^T)]` with the guide
//! (the prismatic joints in front of the arm) held fixed.
//! The Jacobian columns are `z_i × (p - o_i)` (position; identical to the
//! `ParamId::ThetaOffset(i)` columns of `Model::jacobian`) and `z_i` (orientation), with the joint
//! axes from [`vatcal_kinematics::Chain::frames`]. Gravity torques are held fixed in the
//! Jacobian, so with compliance the iteration is quasi-Newton (still converging to machine
//! precision because `c_i d(tau_i)/dq` is tiny). The iteration is the chain-agnostic one of
//! [`crate::numeric_ik::solve_local`], run on the arm with the guide fixed (as [`ArmAtGuide`]).

use nalgebra::{Matrix3, Matrix6, Matrix6xX, Vector3};
use vatcal_core::frame::{rot_x, rot_y, rot_z};
use vatcal_core::{Frame, JointVector, deg_to_rad};
use vatcal_kinematics::Model;

use crate::error::PlanError;
use crate::numeric_ik::{IkTarget, JointSpec, MultiStartOptions, NumericIk, ToolKinematics, solve_local};
pub use crate::parallel_arm::ParallelArm;

/// Elbow angle from the stretched / folded arm at which seeds are placed for a wrist centre
/// just beyond the nominal reach (rad).
pub const ELBOW_SEED_RAD: f64 = 0.05;
/// Relative reach slack of the seeds used for refinement (see
/// [`ArmGeometry::solve_with_reach_slack`]).
const SEED_REACH_SLACK: f64 = 0.02;
/// Tolerance on the structural angles (alpha) for the closed form to be used as a seed (rad).
pub(crate) const STRUCTURE_ANGLE_TOL_RAD: f64 = 0.05;
/// Tolerance on the structural lengths that must be zero (mm).
pub(crate) const STRUCTURE_LENGTH_TOL_MM: f64 = 5.0;

/// Wraps an angle into (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut w = a % two_pi;
    if w <= -std::f64::consts::PI {
        w += two_pi;
    } else if w > std::f64::consts::PI {
        w -= two_pi;
    }
    w
}

/// Rotation vector (axis × angle) of a rotation matrix, accurate for small angles
/// (unlike `acos`-based formulas, whose error near 0 is ~1e-8 rad).
pub fn rotation_vector(r: &Matrix3<f64>) -> Vector3<f64> {
    let v = 0.5 * Vector3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)]);
    let s = v.norm();
    let c = 0.5 * (r.trace() - 1.0);
    let angle = s.atan2(c);
    if s > 1e-6 {
        return v * (angle / s);
    }
    if c > 0.0 {
        // tiny angle: sin(angle) = angle to second order
        return v;
    }
    // angle close to pi: axis from the symmetric part (R + I) / 2 = a a^T (approximately)
    let b = 0.5 * (r + Matrix3::identity());
    let k = (0..3).max_by(|&i, &j| b[(i, i)].total_cmp(&b[(j, j)])).unwrap_or(0);
    let mut axis: Vector3<f64> = b.column(k).into_owned();
    let n = axis.norm();
    if n > 0.0 {
        axis /= n;
    }
    if axis.dot(&v) < 0.0 {
        axis = -axis;
    }
    axis * angle
}

/// Angle (rad) of the rotation taking `a` to `b` (both rotation matrices).
pub fn rotation_angle_between(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    rotation_vector(&(b * a.transpose())).norm()
}

/// Number of prismatic joints before the first revolute joint of `model` (the external axes
/// in front of the arm; 1 on the canonical cell, 0 for an arm on a table).
pub fn leading_prismatic_joints(model: &Model) -> usize {
    model.joint_kinds().iter().take_while(|k| !k.is_revolute()).count()
}

/// The cell row of the first arm joint of a chain that is six revolute joints after its
/// prismatic external axes (if any) — what every closed-form IK needs.
///
/// # Errors
/// [`PlanError::UnsupportedArm`] describing the chain otherwise.
pub fn six_revolute_arm(model: &Model) -> Result<usize, PlanError> {
    let n = model.joint_count();
    let k = leading_prismatic_joints(model);
    if n != k + 6 || !model.joint_kinds()[k..].iter().all(|j| j.is_revolute()) {
        return Err(PlanError::UnsupportedArm(format!(
            "the closed-form IK needs six revolute joints after the prismatic external axes (if any); this chain has {}",
            model.describe_chain()
        )));
    }
    Ok(k + 1)
}

/// World pose of the robot base frame `B` (parent of the arm's first MDH frame) at guide
/// position `q1_mm`: the frame after the prismatic joints in front of the arm (the first at
/// `q1_mm`, any others at 0; `q1_mm` is ignored without one), followed by the fixed part
/// `Rx(alpha) Tx(a) Ry(beta)` of the arm's first row. Includes the model's base pose and the
/// guide effects. See [`robot_base_frame_at`] to give every external axis.
pub fn robot_base_frame(model: &Model, q1_mm: f64) -> Frame {
    let mut q = JointVector::zeros(model.joint_count());
    if leading_prismatic_joints(model) > 0 {
        q[0] = q1_mm;
    }
    robot_base_frame_at(model, &q)
}

/// World pose of the robot base frame `B` with the prismatic joints in front of the arm at
/// their values in `q` (the arm's values in `q` are not used). On a chain without a revolute
/// joint this is the last frame.
pub fn robot_base_frame_at(model: &Model, q: &JointVector) -> Frame {
    let k = leading_prismatic_joints(model);
    let chain = model.chain(q);
    if k >= model.joint_count() {
        return chain.frames[k];
    }
    let row = model.row(k + 1);
    let fixed = Frame { r: rot_x(row.alpha) * rot_y(row.beta), p: Vector3::new(row.a, 0.0, 0.0) };
    chain.frames[k].compose(&fixed)
}

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
    rx: [Matrix3<f64>; 6],
}

/// Up to eight closed-form solutions (the six arm joints, rad) for one tool pose.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ArmSolutions {
    q: [[f64; 6]; 8],
    beyond_reach: [bool; 8],
    branch: [u8; 8],
    len: usize,
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

/// Why a chain does not qualify for the closed form: in joint row `row` (1-based), the value
/// of `field` (its cell-file name) is `value`, the closed form needs `want` (`why`).
pub(crate) fn structure_error(row: usize, field: &str, value: String, want: &str, why: &str) -> PlanError {
    PlanError::UnsupportedArm(format!(
        "joint row {row}: {field} = {value}, the closed form needs {want} ({why})"
    ))
}

/// `Ok(±pi/2)` when `alpha` is within the tolerance of ±90 deg.
pub(crate) fn quarter_turn(row: usize, alpha: f64, why: &str) -> Result<f64, PlanError> {
    use std::f64::consts::FRAC_PI_2;
    let sign = if wrap_angle(alpha - FRAC_PI_2).abs() <= STRUCTURE_ANGLE_TOL_RAD {
        1.0
    } else if wrap_angle(alpha + FRAC_PI_2).abs() <= STRUCTURE_ANGLE_TOL_RAD {
        -1.0
    } else {
        return Err(structure_error(
            row,
            "alpha_deg",
            format!("{:.3}", alpha.to_degrees()),
            &format!("±90 ± {:.1} deg", STRUCTURE_ANGLE_TOL_RAD.to_degrees()),
            why,
        ));
    };
    Ok(sign * FRAC_PI_2)
}

/// `Ok(0)` or `Ok(pi)` when `alpha` (a structure angle of joint row `row`) is within the
/// tolerance of 0 or 180 deg (parallel axes).
pub(crate) fn zero_or_half_turn(row: usize, alpha: f64, why: &str) -> Result<f64, PlanError> {
    use std::f64::consts::PI;
    if wrap_angle(alpha).abs() <= STRUCTURE_ANGLE_TOL_RAD {
        Ok(0.0)
    } else if wrap_angle(alpha - PI).abs() <= STRUCTURE_ANGLE_TOL_RAD {
        Ok(PI)
    } else {
        Err(structure_error(
            row,
            "alpha_deg",
            format!("{:.3}", alpha.to_degrees()),
            &format!("0 or 180 ± {:.1} deg", STRUCTURE_ANGLE_TOL_RAD.to_degrees()),
            why,
        ))
    }
}

/// `cos` of an exact structure angle 0 or pi: +1 or -1.
pub(crate) fn sign_of_cos(alpha: f64) -> f64 {
    if alpha == 0.0 { 1.0 } else { -1.0 }
}

/// One MDH link `Rx(alpha) Tx(a) Rz(theta) Tz(d)` with `Rx(alpha)` given.
pub(crate) fn mdh_link(rx: &Matrix3<f64>, a: f64, theta: f64, d: f64) -> Frame {
    let r = rx * rot_z(theta);
    Frame { r, p: Vector3::new(a, 0.0, 0.0) + r.column(2) * d }
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
/// external axes), the seed source of [`ToolPoseIk`]: [`ArmGeometry`] (spherical wrist) and
/// [`ParallelArm`] (three parallel middle axes, UR-type wrist).
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
    /// needs it, [`ToolPoseIk::add_wrist_band_solutions`]).
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

/// Options of the numerical refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineOptions {
    /// maximum number of iterations
    pub max_iterations: usize,
    /// stop when the tool position error is below this (mm) ...
    pub tol_position_mm: f64,
    /// ... and the tool orientation error below this (rad)
    pub tol_rotation_rad: f64,
    /// length that weighs orientation against position in the damped step (mm/rad)
    pub orientation_scale_mm: f64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            tol_position_mm: 1e-10,
            tol_rotation_rad: 1e-13,
            orientation_scale_mm: 100.0,
        }
    }
}

/// Result of a converged refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    /// joints (q1 as given in the seed)
    pub q: JointVector,
    /// iterations used
    pub iterations: usize,
    /// final tool position error (mm)
    pub position_error_mm: f64,
    /// final tool orientation error (rad)
    pub rotation_error_rad: f64,
}

/// The 6×6 joint Jacobian (q2..q7, the canonical cell's arm) of the tool frame:
/// `[z_i × (p - o_i); z_i]` (world axes; rows: translation, then rotation).
#[inline]
pub fn tool_jacobian(chain: &vatcal_kinematics::Chain) -> Matrix6<f64> {
    arm_tool_jacobian(chain, 2)
}

/// The 6×6 Jacobian of the tool frame in the six revolute joints `first..first + 6`
/// (1-based cell joints): `[z_i × (p - o_i); z_i]` (world axes; rows: translation, then
/// rotation).
#[inline]
pub fn arm_tool_jacobian(chain: &vatcal_kinematics::Chain, first: usize) -> Matrix6<f64> {
    let p = chain.tool.p;
    let mut j = Matrix6::zeros();
    for k in 0..6 {
        let f = &chain.frames[k + first];
        let z = f.z_axis();
        let lin = z.cross(&(p - f.p));
        for r in 0..3 {
            j[(r, k)] = lin[r];
            j[(r + 3, k)] = z[r];
        }
    }
    j
}

/// The arm of a [`Model`] with the guide held at `q1_mm`, as a [`ToolKinematics`] of the six
/// revolute joints after the prismatic joints in front of the arm (`[q2..q7]` on the canonical
/// cell, rad): tool-changer frame in the world and [`arm_tool_jacobian`]. The first prismatic
/// joint is at `q1_mm` (ignored without one), any further ones at 0; the model must have six
/// joints after them (the `joints` of a shorter chain panics).
#[derive(Debug, Clone, Copy)]
pub struct ArmAtGuide<'a> {
    /// the model
    pub model: &'a Model,
    /// guide position (mm)
    pub q1_mm: f64,
}

impl<'a> ArmAtGuide<'a> {
    /// The cell's joint vector for arm joints `q` (rad).
    pub fn joints(&self, q: &[f64]) -> JointVector {
        self.arm().joints(q)
    }

    fn arm(&self) -> ArmWithFixed<'a> {
        let first = leading_prismatic_joints(self.model) + 1;
        let mut fixed = JointVector::zeros(self.model.joint_count());
        if first > 1 {
            fixed[0] = self.q1_mm;
        }
        ArmWithFixed { model: self.model, fixed, first }
    }
}

impl ToolKinematics for ArmAtGuide<'_> {
    type Eval = vatcal_kinematics::Chain;

    fn dof(&self) -> usize {
        6
    }

    fn evaluate(&self, q: &[f64]) -> (Frame, vatcal_kinematics::Chain) {
        self.arm().evaluate(q)
    }

    fn jacobian(&self, chain: &vatcal_kinematics::Chain, jacobian: &mut Matrix6xX<f64>) {
        self.arm().jacobian(chain, jacobian)
    }
}

/// Six revolute joints `first..first + 6` (1-based) of a model solved for, every other joint
/// held at its value in `fixed`.
#[derive(Debug, Clone, Copy)]
struct ArmWithFixed<'a> {
    model: &'a Model,
    fixed: JointVector,
    first: usize,
}

impl ArmWithFixed<'_> {
    fn joints(&self, q: &[f64]) -> JointVector {
        let mut v = self.fixed;
        v.as_mut_slice()[self.first - 1..self.first + 5].copy_from_slice(&q[..6]);
        v
    }
}

impl ToolKinematics for ArmWithFixed<'_> {
    type Eval = vatcal_kinematics::Chain;

    fn dof(&self) -> usize {
        6
    }

    fn evaluate(&self, q: &[f64]) -> (Frame, vatcal_kinematics::Chain) {
        let chain = self.model.chain(&self.joints(q));
        (chain.tool, chain)
    }

    fn jacobian(&self, chain: &vatcal_kinematics::Chain, jacobian: &mut Matrix6xX<f64>) {
        jacobian.copy_from(&arm_tool_jacobian(chain, self.first));
    }
}

/// Any joints of a [`Model`]'s chain as a [`ToolKinematics`]: the joints `free` (1-based cell
/// joints, in this order) are solved for, the others are held at their values in `fixed`.
/// Jacobian column of joint `i`: `[z_i × (p - o_i); z_i]` (revolute) or `[z_i; 0]` (prismatic),
/// with the axes of MDH frame `i` from [`vatcal_kinematics::Chain::frames`] (effects and
/// compliance held fixed, as in [`tool_jacobian`]).
#[derive(Debug, Clone)]
pub struct ChainTool<'a> {
    /// the model
    pub model: &'a Model,
    /// values of the joints that are not solved for (internal units)
    pub fixed: JointVector,
    /// the joints solved for (1-based)
    pub free: Vec<usize>,
    /// per free joint: true when revolute
    pub revolute: Vec<bool>,
}

impl ChainTool<'_> {
    /// The cell's joint vector for the free joints' values `q`.
    pub fn joints(&self, q: &[f64]) -> JointVector {
        let mut v = self.fixed;
        for (i, x) in self.free.iter().zip(q) {
            v.set(*i, *x);
        }
        v
    }
}

impl ToolKinematics for ChainTool<'_> {
    type Eval = vatcal_kinematics::Chain;

    fn dof(&self) -> usize {
        self.free.len()
    }

    fn evaluate(&self, q: &[f64]) -> (Frame, vatcal_kinematics::Chain) {
        let chain = self.model.chain(&self.joints(q));
        (chain.tool, chain)
    }

    fn jacobian(&self, chain: &vatcal_kinematics::Chain, jacobian: &mut Matrix6xX<f64>) {
        let p = chain.tool.p;
        for (c, (i, revolute)) in self.free.iter().zip(&self.revolute).enumerate() {
            let f = &chain.frames[*i];
            let z = f.z_axis();
            let (lin, ang) = if *revolute { (z.cross(&(p - f.p)), z) } else { (z, Vector3::zeros()) };
            for r in 0..3 {
                jacobian[(r, c)] = lin[r];
                jacobian[(r + 3, c)] = ang[r];
            }
        }
    }
}

/// Refines `seed` so that the model's tool-changer frame reaches `target` (world), solving
/// for the six revolute joints after the prismatic joints in front of the arm (q2..q7 on the
/// canonical cell) and holding those prismatic joints (q1, the guide) at their seed values.
/// Levenberg–Marquardt on the weighted 6-DOF error (no joint limits):
/// [`crate::numeric_ik::solve_local`] on the arm (as [`ArmAtGuide`]); see the module docs.
///
/// # Errors
/// [`PlanError::IkNotConverged`] when the tolerances are missed; [`PlanError::UnsupportedArm`]
/// when the model has no six revolute joints after its leading prismatic joints, or `seed`
/// has the wrong length.
pub fn refine_tool_pose(
    model: &Model,
    seed: &JointVector,
    target: &Frame,
    opts: &RefineOptions,
) -> Result<Refined, PlanError> {
    let first = leading_prismatic_joints(model) + 1;
    let n = model.joint_count();
    if n < first + 5
        || seed.len() != n
        || !model.joint_kinds()[first - 1..first + 5].iter().all(|k| k.is_revolute())
    {
        return Err(PlanError::UnsupportedArm(format!(
            "the refinement needs six revolute joints after the prismatic external axes and one seed value per joint; this chain has {}, the seed {} values",
            model.describe_chain(),
            seed.len()
        )));
    }
    refine_arm(model, first, seed, target, opts)
}

/// [`refine_tool_pose`] for a chain already checked: arm joints `first..first + 6`, one seed
/// value per joint.
fn refine_arm(
    model: &Model,
    first: usize,
    seed: &JointVector,
    target: &Frame,
    opts: &RefineOptions,
) -> Result<Refined, PlanError> {
    let arm = ArmWithFixed { model, fixed: *seed, first };
    let r = solve_local(
        &arm,
        &[JointSpec::continuous(); 6],
        &seed.as_slice()[first - 1..first + 5],
        &IkTarget::Pose(*target),
        opts,
    )?;
    Ok(Refined {
        q: arm.joints(&r.q),
        iterations: r.iterations,
        position_error_mm: r.position_error_mm,
        rotation_error_rad: r.rotation_error_rad,
    })
}

/// A closed-form seed of the refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkSeed {
    /// joints (the external axes, q1, as given)
    pub q: JointVector,
    /// true for a seed just beyond the nominal arm's reach (not an exact nominal solution)
    pub beyond_reach: bool,
}

/// Closed-form seeds + refinement for the tool-changer frame pose of a model.
///
/// When the model is not exactly the nominal-structure arm (a calibrated model), each
/// closed-form seed is first corrected [`SEED_CORRECTIONS`] times on its own branch: with
/// `E(q) = T_nom(q)⁻¹ T_model(q)` the error of the nominal structure at the seed, the closed
/// form is solved again for `T* E(q)⁻¹`. Near a singularity a small model error moves the
/// solution a lot, and this keeps the seed on the right branch before the refinement.
///
/// The closed form is `A`: [`ArmGeometry`] (a spherical wrist, the default) or
/// [`ParallelArm`] (three parallel middle axes and a UR-type wrist), see [`ClosedFormArm`].
#[derive(Debug, Clone)]
pub struct ToolPoseIk<'a, A: ClosedFormArm = ArmGeometry> {
    model: &'a Model,
    arm: A,
    refine: RefineOptions,
    corrections: usize,
}

/// Branch-preserving closed-form corrections of a seed on a calibrated model.
pub const SEED_CORRECTIONS: usize = 2;

/// Band around the wrist singularity (`|sin theta_5| < sin(band)`) in which the soft wrist
/// direction of a refined solution on a calibrated model is scanned
/// ([`ToolPoseIk::add_wrist_band_solutions`]) (deg).
pub const WRIST_SCAN_BAND_DEG: f64 = 15.0;

/// Steps per turn of `theta_4` of the scan of the soft wrist direction
/// ([`ToolPoseIk::add_wrist_band_solutions`]; every 5 deg: further solutions were seen 8 deg
/// apart in `theta_4`).
pub const WRIST_SCAN_STEPS: usize = 72;

/// Re-seeds per turn of `theta_4` of a solution in the wrist band, besides the scan (every
/// 30 deg; [`ToolPoseIk::add_wrist_band_solutions`]).
pub const WRIST_RESEEDS: usize = 12;

/// At most this many distinct solutions has the inverse kinematics of a 6R arm (a general 6R
/// arm has up to 16); the wrist band search stops there.
const MAX_6R_SOLUTIONS: usize = 16;

/// Gauss–Newton steps of each fit of that scan (continued from the previous step's fit).
const WRIST_FIT_ITERATIONS: usize = 8;

/// Regula falsi steps on `theta_4` for each solution bracketed by that scan.
const WRIST_ROOT_ITERATIONS: usize = 40;

/// True when the model's tool frame is the closed-form arm's at a few test configurations
/// (nominal model: no seed correction needed).
fn closed_form_is_exact<A: ClosedFormArm>(model: &Model, arm: &A) -> bool {
    let tests = [
        [120.0, 30.0, 20.0, -40.0, 50.0, 60.0, -70.0],
        [10.0, -100.0, -50.0, 30.0, -120.0, -20.0, 150.0],
        [280.0, 150.0, 80.0, -120.0, 10.0, 100.0, 5.0],
    ];
    let k = arm.first_joint() - 1;
    tests.iter().all(|t| {
        let mut q = JointVector::zeros(model.joint_count());
        if k > 0 {
            q[0] = t[0];
        }
        for j in 0..6 {
            q[k + j] = deg_to_rad(t[j + 1]);
        }
        let arm_q: [f64; 6] = std::array::from_fn(|j| q[k + j]);
        let nominal = robot_base_frame(model, t[0]).compose(&arm.forward(&arm_q));
        let actual = model.chain(&q).tool;
        (nominal.p - actual.p).norm() < 1e-9 && rotation_angle_between(&nominal.r, &actual.r) < 1e-12
    })
}

impl<'a> ToolPoseIk<'a> {
    /// IK for `model`: a 6R arm with a spherical wrist ([`ArmGeometry::from_model`]), with at
    /// most one prismatic joint (the guide, joint 1) in front of it.
    ///
    /// # Examples
    /// Every solution that puts the tool-changer frame at a target pose with the guide at 150 mm,
    /// each checked by forward kinematics:
    /// ```
    /// use vatcal_core::{CellFile, JointVector};
    /// use vatcal_kinematics::Model;
    /// use vatcal_planning::ik::{RefineOptions, ToolPoseIk};
    ///
    /// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
    /// // a reachable target: the tool frame at a known configuration
    /// let known = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    /// let target = model.chain(&known).tool;
    /// let ik = ToolPoseIk::new(&model, RefineOptions::default())?;
    /// let solutions = ik.solve_at_guide(150.0, &target);
    /// assert!(solutions.len() >= 2, "several branches reach this pose");
    /// for q in &solutions {
    ///     assert!((model.chain(q).tool.p - target.p).norm() < 1e-8);
    /// }
    /// assert!(solutions.iter().any(|q| (1..=7).all(|j| (q.get(j) - known.get(j)).abs() < 1e-7)));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`PlanError::UnsupportedArm`] when the model's arm does not have the structure the
    /// closed form needs (see [`ArmGeometry::from_model`]; the message names the row and value)
    /// or has more than one prismatic joint in front of the arm.
    pub fn new(model: &'a Model, refine: RefineOptions) -> Result<Self, PlanError> {
        Self::with_closed_form(model, refine)
    }
}

impl<'a, A: ClosedFormArm> ToolPoseIk<'a, A> {
    /// IK for `model` with the closed form `A` ([`ClosedFormArm::from_model`]), with at most
    /// one prismatic joint (the guide, joint 1) in front of the arm; e.g.
    /// `ToolPoseIk::<ParallelArm>::with_closed_form` for a UR-type arm.
    ///
    /// # Errors
    /// [`PlanError::UnsupportedArm`] when the model's arm does not have the structure `A`
    /// needs (the message names the row and value) or has more than one prismatic joint in
    /// front of the arm.
    pub fn with_closed_form(model: &'a Model, refine: RefineOptions) -> Result<Self, PlanError> {
        let arm = A::from_model(model)?;
        if arm.first_joint() > 2 {
            return Err(PlanError::UnsupportedArm(format!(
                "the closed-form IK holds one prismatic joint (the guide) at given positions; this chain has {} prismatic joints in front of the arm ({})",
                arm.first_joint() - 1,
                model.describe_chain()
            )));
        }
        let corrections = if closed_form_is_exact(model, &arm) { 0 } else { SEED_CORRECTIONS };
        Ok(Self { model, arm, refine, corrections })
    }

    /// The closed-form geometry in use.
    pub fn arm(&self) -> &A {
        &self.arm
    }

    /// True when the model is exactly the closed form's nominal structure (the seeds are
    /// solutions; no correction, no wrist-band search).
    pub fn is_exact(&self) -> bool {
        self.corrections == 0
    }

    /// The model.
    pub fn model(&self) -> &'a Model {
        self.model
    }

    /// The guide joint held at the guide positions (1-based): `Some(1)` when the chain has a
    /// prismatic joint in front of the arm, `None` for an arm alone (guide positions ignored).
    pub fn guide_joint(&self) -> Option<usize> {
        (self.arm.first_joint() > 1).then_some(1)
    }

    /// The cell's joint vector for the guide at `q1_mm` (if the chain has one) and arm joints
    /// `arm` (rad).
    fn joints(&self, q1_mm: f64, arm: &[f64; 6]) -> JointVector {
        let k = self.arm.first_joint() - 1;
        let mut q = JointVector::zeros(self.model.joint_count());
        if k > 0 {
            q[0] = q1_mm;
        }
        q.as_mut_slice()[k..k + 6].copy_from_slice(arm);
        q
    }

    /// Closed-form seeds at guide position `q1_mm` (ignored without a guide) for the world tool
    /// pose `target`, given the robot base frame `base` at that guide position
    /// ([`robot_base_frame`]); corrected on their branch for a calibrated model (see the type
    /// docs).
    pub fn seeds(&self, q1_mm: f64, base: &Frame, target: &Frame) -> Vec<IkSeed> {
        let base_inv = base.inverse();
        let solutions = self.arm.solve_with_reach_slack(&base_inv.compose(target), SEED_REACH_SLACK);
        let joints = |arm: &[f64; 6]| self.joints(q1_mm, arm);
        let mut out = Vec::with_capacity(solutions.len());
        for ((arm, beyond), branch) in
            solutions.as_slice().iter().zip(solutions.beyond_reach()).zip(solutions.branches())
        {
            let mut q = *arm;
            for _ in 0..self.corrections {
                let actual = self.model.chain(&joints(&q)).tool;
                let nominal = base.compose(&self.arm.forward(&q));
                let corrected = base_inv.compose(target).compose(&actual.inverse()).compose(&nominal);
                match self.arm.solve_with_reach_slack(&corrected, SEED_REACH_SLACK).of_branch(*branch) {
                    Some(next) => q = next,
                    None => break,
                }
            }
            out.push(IkSeed { q: joints(&q), beyond_reach: *beyond });
        }
        out
    }

    /// Refines one seed on the model.
    ///
    /// # Errors
    /// As [`refine_tool_pose`].
    pub fn refine(&self, seed: &JointVector, target: &Frame) -> Result<Refined, PlanError> {
        if seed.len() != self.model.joint_count() {
            return refine_tool_pose(self.model, seed, target, &self.refine);
        }
        refine_arm(self.model, self.arm.first_joint(), seed, target, &self.refine)
    }

    /// Every solution at guide position `q1_mm` (ignored without a guide; closed-form seeds
    /// refined on the model; seeds that do not converge are dropped; duplicates merged; on a
    /// calibrated model, the soft wrist direction scanned near the wrist singularity, see
    /// [`ToolPoseIk::add_wrist_band_solutions`]), each arm joint wrapped to (-pi, pi]. The
    /// closed-form branches come first, in branch order; up to 8 of them, plus any further
    /// solutions of a calibrated wrist near its singularity.
    pub fn solve_at_guide(&self, q1_mm: f64, target: &Frame) -> Vec<JointVector> {
        let base = robot_base_frame(self.model, q1_mm);
        let mut out: Vec<JointVector> = Vec::with_capacity(8);
        for seed in self.seeds(q1_mm, &base, target) {
            if let Ok(r) = self.refine(&seed.q, target) {
                let q = self.wrapped(r.q);
                if !out.iter().any(|p| max_abs_diff(p, &q) < 1e-9) {
                    out.push(q);
                }
            }
        }
        self.add_wrist_band_solutions(target, &mut out);
        out
    }

    /// `q` with every arm joint wrapped to (-pi, pi].
    fn wrapped(&self, mut q: JointVector) -> JointVector {
        for v in q.as_mut_slice().iter_mut().skip(self.arm.first_joint() - 1) {
            *v = wrap_angle(*v);
        }
        q
    }

    /// Completes `solutions` (refined solutions for the world tool pose `target`, arm joints
    /// wrapped) near the wrist singularity of a calibrated model; does nothing on a model the
    /// closed form solves exactly (a spherical wrist has no further solutions), and on an arm
    /// without a spherical wrist ([`ParallelArm`]: its wrist singularity is another one, not
    /// searched; see `docs/planning.md`).
    ///
    /// Why: the closed form's eight branches are those of the spherical wrist. Within a few
    /// degrees of the wrist singularity (`sin theta_5 = 0`, axes 4 and 6 aligned) the tool
    /// orientation fixes `theta_4 + k theta_6` well and the difference badly (`k = ±1`); a
    /// calibrated wrist, whose axes no longer meet exactly, couples that soft direction to the
    /// arm joints, and where the wrist centre is also close to the axis of arm joint 1 (the
    /// shoulder singularity) one spherical-wrist branch can become three solutions of the model
    /// (a fold), or two seeds can refine to the same solution so that a branch is lost. Each
    /// refined branch is the continuation of a nominal one and correct, but the other solutions
    /// are missed.
    ///
    /// What: every solution (given or found here) with `|sin theta_5| <
    /// sin(`[`WRIST_SCAN_BAND_DEG`]`)` that no earlier scan met has its soft direction searched
    /// in two ways (`k = -sign(alpha_4 alpha_5) sign(cos theta_5)`, so that `theta_4 + k
    /// theta_6` is kept):
    ///
    /// * a scan over a whole turn of `theta_4`: every `360 deg /` [`WRIST_SCAN_STEPS`] the pose
    ///   is fitted in least squares with `theta_4` held (the other five arm joints, continued
    ///   from the previous step). The weighted error `e` of the fit is then normal to the five
    ///   columns of the weighted Jacobian; its component `r = n . e` along the unit normal `n`
    ///   of those columns (the sign of `n` carried on from step to step, starting as the part of
    ///   the `theta_4` column normal to them) is continuous in `theta_4` and zero exactly at the
    ///   solutions. Every sign change of `r` between two steps brackets a solution, which regula
    ///   falsi on `theta_4` (fits with `theta_4` held) converges to the refinement tolerances;
    ///   this finds solutions a few degrees apart;
    /// * the solution turned by every multiple of `360 deg /` [`WRIST_RESEEDS`] (`theta_4 +
    ///   phi`, `theta_6 - k phi`) and refined as the closed-form seeds are: the curve of fits
    ///   need not stay near the singularity over a whole turn (near the shoulder singularity it
    ///   can swing to large `theta_5` before reaching the wrist-flipped solution).
    ///
    /// Each converged solution that differs from every solution already in `solutions` by more
    /// than 1e-6 rad in some arm joint (modulo a whole turn) is appended (and searched in turn;
    /// the search stops at 16 solutions, the most a 6R arm has); every appended solution
    /// reproduces `target` to the refinement tolerances.
    pub fn add_wrist_band_solutions(&self, target: &Frame, solutions: &mut Vec<JointVector>) {
        let Some(wrist) = self.arm.spherical_wrist() else {
            return;
        };
        if self.corrections == 0 {
            return;
        }
        let (theta5_offset, s45) =
            (wrist.theta_offset_rad[4], wrist.alpha_rad[3].signum() * wrist.alpha_rad[4].signum());
        let first = self.arm.first_joint() - 1;
        let band = deg_to_rad(WRIST_SCAN_BAND_DEG).sin();
        // solutions whose soft direction is still to be searched (every one in the band,
        // including those found here), and those met by a scan (their curve has been scanned)
        let mut queue: Vec<JointVector> = solutions.clone();
        let mut scanned: Vec<JointVector> = Vec::new();
        while let Some(q) = queue.pop() {
            if solutions.len() >= MAX_6R_SOLUTIONS {
                break;
            }
            let theta5 = q[first + 4] + theta5_offset;
            if theta5.sin().abs() >= band || scanned.iter().any(|p| self.same_arm_joints(p, &q, 1e-6)) {
                continue;
            }
            scanned.push(q);
            let (on_curve, other) = self.search_soft_wrist_direction(&q, theta5, s45, target);
            for (found, met) in
                on_curve.into_iter().map(|f| (f, true)).chain(other.into_iter().map(|f| (f, false)))
            {
                let found = self.wrapped(found);
                if met && !scanned.iter().any(|p| self.same_arm_joints(p, &found, 1e-6)) {
                    scanned.push(found);
                }
                if !solutions.iter().any(|p| self.same_arm_joints(p, &found, 1e-6)) {
                    solutions.push(found);
                    queue.push(found);
                }
            }
        }
    }

    /// The solutions near the solution `q` (MDH `theta_5` = `theta5`) along its soft wrist
    /// direction ([`ToolPoseIk::add_wrist_band_solutions`]): those bracketed by the scan of the
    /// curve of least-squares fits with arm joint 4 held (first), and those refined from `q`
    /// turned by a multiple of `360 deg /` [`WRIST_RESEEDS`] (second; the curve need not stay
    /// near the singularity over a whole turn, e.g. to the wrist-flipped solution).
    fn search_soft_wrist_direction(
        &self,
        q: &JointVector,
        theta5: f64,
        s45: f64,
        target: &Frame,
    ) -> (Vec<JointVector>, Vec<JointVector>) {
        let first = self.arm.first_joint() - 1;
        // theta_4 + k theta_6 is the well-determined combination (k = -1 near theta_5 = pi)
        let k = -s45 * theta5.cos().signum();
        let turn = |mut v: JointVector, by: f64| {
            v[first + 3] += by;
            v[first + 5] -= k * by;
            v
        };
        let step = std::f64::consts::TAU / WRIST_SCAN_STEPS as f64;
        // (fit, r, normal) at every step, and once more at the start after the whole turn
        let mut fits: Vec<(JointVector, f64, nalgebra::Vector6<f64>)> =
            Vec::with_capacity(WRIST_SCAN_STEPS + 1);
        let mut current = *q;
        let mut normal: Option<nalgebra::Vector6<f64>> = None;
        for _ in 0..=WRIST_SCAN_STEPS {
            let fit = self.fit_with_joint4_held(current, target, WRIST_FIT_ITERATIONS, 1e-6);
            let Some(n) = fit.normal(normal.unwrap_or(fit.j4)) else {
                break;
            };
            normal = Some(n);
            fits.push((fit.q, n.dot(&fit.e), n));
            current = turn(fit.q, step);
        }
        // the scan starts and ends at the known solution `q`: r = 0 there (up to rounding),
        // and the steps next to it bracket `q` itself
        if let Some(f) = fits.first_mut() {
            f.1 = 0.0;
        }
        if fits.len() == WRIST_SCAN_STEPS + 1 {
            fits[WRIST_SCAN_STEPS].1 = 0.0;
        }
        let mut on_curve = Vec::new();
        for w in fits.windows(2) {
            let ((a, ra, na), (_, rb, _)) = (w[0], w[1]);
            if ra == 0.0 || rb == 0.0 || (ra > 0.0) == (rb > 0.0) {
                continue;
            }
            let seed = self.wrist_root(target, (a, na), (ra, rb), step, &turn);
            if let Ok(r) = self.refine(&seed, target) {
                on_curve.push(r.q);
            }
        }
        let other = (1..WRIST_RESEEDS)
            .filter_map(|m| {
                let by = std::f64::consts::TAU * m as f64 / WRIST_RESEEDS as f64;
                self.refine(&turn(*q, by), target).ok().map(|r| r.q)
            })
            .collect();
        (on_curve, other)
    }

    /// The solution bracketed by a scan step of [`ToolPoseIk::add_wrist_band_solutions`]: the
    /// fit `a` (with its normal `na`) and the next step `step` further, with `r` values `ra`,
    /// `rb` of opposite signs. Regula falsi (Illinois) on the turn `x` in `[0, step]` from `a`
    /// (`turn(a, x)`), each `r` from a fit with arm joint 4 held, until the fit meets the
    /// refinement tolerances; returns the last fit (the refinement decides). A root search in
    /// the one soft variable, not a Newton step of the full arm: at a fold of the solution set
    /// the arm's Jacobian is nearly singular, and its quasi-Newton iteration (gravity torques held
    /// fixed, see the module docs) can stall just short of the tolerances there.
    fn wrist_root(
        &self,
        target: &Frame,
        (a, na): (JointVector, nalgebra::Vector6<f64>),
        (ra, rb): (f64, f64),
        step: f64,
        turn: &dyn Fn(JointVector, f64) -> JointVector,
    ) -> JointVector {
        let scale = self.refine.orientation_scale_mm;
        let (mut xa, mut ra, mut xb, mut rb) = (0.0, ra, step, rb);
        let mut last_side = 0;
        let mut best = turn(a, step * ra / (ra - rb));
        for _ in 0..WRIST_ROOT_ITERATIONS {
            let x = (xa * rb - xb * ra) / (rb - ra);
            let fit = self.fit_with_joint4_held(turn(a, x), target, 2 * WRIST_FIT_ITERATIONS, 1e-14);
            best = fit.q;
            let done = fit.e.fixed_rows::<3>(0).norm() <= self.refine.tol_position_mm
                && fit.e.fixed_rows::<3>(3).norm() / scale <= self.refine.tol_rotation_rad;
            let Some(n) = fit.normal(na) else {
                break;
            };
            let r = n.dot(&fit.e);
            if done || r == 0.0 || xb - xa <= f64::EPSILON * step {
                break;
            }
            if (r > 0.0) == (rb > 0.0) {
                (xb, rb) = (x, r);
                if last_side == -1 {
                    ra /= 2.0;
                }
                last_side = -1;
            } else {
                (xa, ra) = (x, r);
                if last_side == 1 {
                    rb /= 2.0;
                }
                last_side = 1;
            }
        }
        best
    }

    /// Least-squares fit of the tool pose `target` with arm joint 4 held at its value in `q`:
    /// damped Gauss–Newton steps on the other five arm joints (weighted error as in the
    /// refinement) from `q`, up to `iterations`, until a step lowers the cost by less than
    /// `rel_tol` times the cost.
    fn fit_with_joint4_held(
        &self,
        q: JointVector,
        target: &Frame,
        iterations: usize,
        rel_tol: f64,
    ) -> WristFit {
        use nalgebra::{Matrix6x5, Vector6};
        let first = self.arm.first_joint() - 1;
        let scale = self.refine.orientation_scale_mm;
        let weights = Vector6::new(1.0, 1.0, 1.0, scale, scale, scale);
        let free = [0usize, 1, 2, 4, 5];
        let error = |chain: &vatcal_kinematics::Chain| {
            let dp = target.p - chain.tool.p;
            let dr = rotation_vector(&(target.r * chain.tool.r.transpose()));
            Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z).component_mul(&weights)
        };
        let columns = |chain: &vatcal_kinematics::Chain| {
            let j = arm_tool_jacobian(chain, self.arm.first_joint());
            let mut a = Matrix6x5::zeros();
            for (c, f) in free.iter().enumerate() {
                a.set_column(c, &j.column(*f).component_mul(&weights));
            }
            (a, j.column(3).component_mul(&weights))
        };
        let mut q = q;
        let mut chain = self.model.chain(&q);
        let mut e = error(&chain);
        let mut lambda = 1e-9;
        for _ in 0..iterations {
            let (a, _) = columns(&chain);
            let jtj = a.transpose() * a;
            let jte = a.transpose() * e;
            let c0 = e.norm_squared();
            let mut improved = false;
            for _ in 0..8 {
                let mut m = jtj;
                for d in 0..5 {
                    m[(d, d)] += lambda * (1.0 + jtj[(d, d)]);
                }
                let Some(delta) = m.cholesky().map(|ch| ch.solve(&jte)) else {
                    lambda *= 10.0;
                    continue;
                };
                let mut trial = q;
                for (r, f) in free.iter().enumerate() {
                    trial[first + f] += delta[r];
                }
                let trial_chain = self.model.chain(&trial);
                let trial_e = error(&trial_chain);
                let c1 = trial_e.norm_squared();
                if c1 < c0 {
                    (q, chain, e) = (trial, trial_chain, trial_e);
                    lambda = (lambda * 0.1).max(1e-15);
                    improved = c0 - c1 > rel_tol * c0;
                    break;
                }
                lambda *= 10.0;
            }
            if !improved {
                break;
            }
        }
        let (a, j4) = columns(&chain);
        WristFit { q, e, a, j4 }
    }

    /// True when the arm joints of `a` and `b` differ by less than `tol_rad` each (modulo a
    /// whole turn) and the guide is the same.
    fn same_arm_joints(&self, a: &JointVector, b: &JointVector, tol_rad: f64) -> bool {
        let first = self.arm.first_joint() - 1;
        a.as_slice()
            .iter()
            .zip(b.as_slice())
            .enumerate()
            .all(|(j, (x, y))| if j < first { x == y } else { wrap_angle(x - y).abs() < tol_rad })
    }

    /// Every solution over several guide positions (as [`ToolPoseIk::solve_at_guide`] at each:
    /// up to 8 per position, more near the wrist singularity of a calibrated model; one pass for
    /// an arm without a guide).
    pub fn solve(&self, guide_positions_mm: &[f64], target: &Frame) -> Vec<JointVector> {
        if self.guide_joint().is_none() {
            return self.solve_at_guide(0.0, target);
        }
        guide_positions_mm.iter().flat_map(|q1| self.solve_at_guide(*q1, target)).collect()
    }
}

/// A least-squares fit of the tool pose with arm joint 4 held
/// ([`ToolPoseIk::add_wrist_band_solutions`]); all vectors weighted as in the refinement.
struct WristFit {
    /// the fitted joints
    q: JointVector,
    /// weighted error `[p* - p; log(R* R^T)]` at the fit
    e: nalgebra::Vector6<f64>,
    /// weighted Jacobian columns of the five fitted arm joints
    a: nalgebra::Matrix6x5<f64>,
    /// weighted Jacobian column of arm joint 4
    j4: nalgebra::Vector6<f64>,
}

impl WristFit {
    /// The unit normal of the five fitted columns closest to `near` (the part of `near` normal
    /// to them, normalised); `None` when `near` lies in their span or they are dependent.
    fn normal(&self, near: nalgebra::Vector6<f64>) -> Option<nalgebra::Vector6<f64>> {
        let ch = (self.a.transpose() * self.a).cholesky()?;
        let v = near - self.a * ch.solve(&(self.a.transpose() * near));
        let norm = v.norm();
        (norm > 1e-9 * near.norm()).then(|| v / norm)
    }
}

/// Per joint of `model` (1..=N): true when revolute.
fn revolute_joints(model: &Model) -> Vec<bool> {
    model.joint_kinds().iter().map(|k| k.is_revolute()).collect()
}

/// The numerical IK's view of joint `i` (1-based) of `model`: kind and limits (none for a
/// continuous joint).
fn joint_spec(model: &Model, i: usize, revolute: bool) -> JointSpec {
    match (model.joint_limit(i), revolute) {
        (Some((lo, hi)), true) => JointSpec::revolute(lo, hi),
        (Some((lo, hi)), false) => JointSpec::prismatic(lo, hi),
        (None, true) => JointSpec::continuous(),
        // a prismatic joint always has limits in a valid cell; NumericIk::new reports it otherwise
        (None, false) => JointSpec { revolute: false, limits: None },
    }
}

/// Which inverse kinematics a [`ModelIk`] uses.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum IkMethod {
    /// Closed form on the nominal geometry (6R arm with a spherical wrist, up to 8 branches),
    /// refined on the full model ([`ToolPoseIk`]).
    ClosedForm,
    /// Closed form on the nominal geometry of a 6R arm with three parallel middle axes and a
    /// UR-type wrist ([`ParallelArm`], up to 8 branches), refined on the full model
    /// ([`ToolPoseIk`]).
    ParallelClosedForm,
    /// Multi-start numerical IK ([`crate::numeric_ik::NumericIk`]); `reason` says why the
    /// closed form does not apply (`None` when the numerical IK was asked for).
    Numerical {
        /// why the chain does not qualify for the closed form
        reason: Option<String>,
    },
}

impl std::fmt::Display for IkMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::ClosedForm => {
                write!(
                    f,
                    "closed form (6R arm with a spherical wrist, up to 8 branches), refined on the model"
                )
            }
            Self::ParallelClosedForm => {
                write!(
                    f,
                    "closed form (6R arm with three parallel middle axes and a UR-type wrist, up to 8 branches), refined on the model"
                )
            }
            Self::Numerical { reason: Some(r) } => write!(f, "multi-start numerical (no closed form: {r})"),
            Self::Numerical { reason: None } => write!(f, "multi-start numerical"),
        }
    }
}

/// Inverse kinematics of the tool-changer frame of any [`Model`]: the closed form + refinement
/// ([`ToolPoseIk`]) when the chain is a 6R arm with a spherical wrist
/// ([`ArmGeometry::from_model`]) or — with [`ModelIk::closed_form_first`] — with three parallel
/// middle axes and a UR-type wrist ([`ParallelArm::from_model`]), alone or behind one prismatic
/// guide, the multi-start numerical IK ([`crate::numeric_ik::NumericIk`] on a [`ChainTool`])
/// otherwise ([`ModelIk::method`] says which, and why not a closed form). The first prismatic joint, if any, is the guide: it is
/// held at the given guide positions and the other joints are solved for; a chain without one
/// ignores the guide positions.
#[derive(Debug)]
pub struct ModelIk<'a> {
    model: &'a Model,
    solver: Solver<'a>,
}

#[derive(Debug)]
enum Solver<'a> {
    /// the closed form, and every joint's spec (to normalise the solutions into the limits)
    ClosedForm(Box<ToolPoseIk<'a>>, Vec<JointSpec>),
    /// the closed form of an arm with three parallel middle axes, and every joint's spec
    Parallel(Box<ToolPoseIk<'a, ParallelArm>>, Vec<JointSpec>),
    Numeric {
        guide: Option<usize>,
        free: Vec<usize>,
        specs: Vec<JointSpec>,
        opts: MultiStartOptions,
        reason: Option<String>,
    },
}

impl<'a> ModelIk<'a> {
    /// The spherical-wrist closed form when the model allows it, the numerical IK otherwise
    /// (the IK of every user of this type outside the candidate generator: compensation,
    /// validation, the campaign; see [`ModelIk::closed_form_first`] for the closed form of arms
    /// with three parallel middle axes too).
    ///
    /// # Examples
    /// The Meca500 alone on a table has a spherical wrist; the UR5e has not:
    /// ```
    /// use vatcal_core::CellFile;
    /// use vatcal_kinematics::Model;
    /// use vatcal_planning::ik::{IkMethod, ModelIk, RefineOptions};
    /// use vatcal_planning::numeric_ik::MultiStartOptions;
    ///
    /// let fixture = |name: &str| -> Result<Model, Box<dyn std::error::Error>> {
    ///     let path = format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    ///     Ok(Model::from_cell(&CellFile::load(path)?)?)
    /// };
    /// let table = fixture("meca500-table.toml")?;
    /// let ik = ModelIk::new(&table, RefineOptions::default(), MultiStartOptions::default())?;
    /// assert_eq!(ik.method(), IkMethod::ClosedForm);
    /// let ur5e = fixture("ur5e.toml")?;
    /// let ik = ModelIk::new(&ur5e, RefineOptions::default(), MultiStartOptions::default())?;
    /// assert!(ik.method().to_string().contains("spherical wrist"));
    /// // it has three parallel middle axes and a UR-type wrist
    /// let ik = ModelIk::closed_form_first(&ur5e, RefineOptions::default(), MultiStartOptions::default())?;
    /// assert_eq!(ik.method(), IkMethod::ParallelClosedForm);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// Invalid numerical-IK options or joint limits ([`PlanError::Option`]).
    pub fn new(
        model: &'a Model,
        refine: RefineOptions,
        numeric: MultiStartOptions,
    ) -> Result<Self, PlanError> {
        match ToolPoseIk::new(model, refine) {
            Ok(ik) => Ok(Self { model, solver: Solver::ClosedForm(Box::new(ik), all_joint_specs(model)) }),
            Err(PlanError::UnsupportedArm(reason)) => Self::numerical_because(model, numeric, reason),
            Err(e) => Err(e),
        }
    }

    /// A closed form when the model allows it — a spherical wrist ([`ArmGeometry`]) first, then
    /// three parallel middle axes with a UR-type wrist ([`ParallelArm`]) — the numerical IK
    /// otherwise, naming why neither closed form applies. The candidate generator's default
    /// ([`crate::candidates::IkChoice::ClosedFormFirst`]).
    ///
    /// The solutions of a pose are the same set as [`ModelIk::new`]'s up to rounding where the
    /// numerical IK finds every branch, in closed-form branch order instead of the order the
    /// starts found them; callers that pick among equally good solutions by their order get
    /// other picks.
    ///
    /// # Errors
    /// Invalid numerical-IK options or joint limits ([`PlanError::Option`]).
    pub fn closed_form_first(
        model: &'a Model,
        refine: RefineOptions,
        numeric: MultiStartOptions,
    ) -> Result<Self, PlanError> {
        let spherical = match ToolPoseIk::new(model, refine) {
            Ok(ik) => {
                return Ok(Self { model, solver: Solver::ClosedForm(Box::new(ik), all_joint_specs(model)) });
            }
            Err(PlanError::UnsupportedArm(reason)) => reason,
            Err(e) => return Err(e),
        };
        let parallel = match ToolPoseIk::<ParallelArm>::with_closed_form(model, refine) {
            Ok(ik) => {
                return Ok(Self { model, solver: Solver::Parallel(Box::new(ik), all_joint_specs(model)) });
            }
            Err(PlanError::UnsupportedArm(reason)) => reason,
            Err(e) => return Err(e),
        };
        let reason = if spherical == parallel { spherical } else { format!("{spherical}; {parallel}") };
        Self::numerical_because(model, numeric, reason)
    }

    /// The numerical IK, `reason` saying why no closed form applies.
    fn numerical_because(
        model: &'a Model,
        numeric: MultiStartOptions,
        reason: String,
    ) -> Result<Self, PlanError> {
        let mut me = Self::numerical(model, numeric)?;
        if let Solver::Numeric { reason: r, .. } = &mut me.solver {
            *r = Some(reason);
        }
        Ok(me)
    }

    /// Always the numerical IK (also for a Meca500-like arm, e.g. to cross-check the closed form).
    ///
    /// # Errors
    /// Invalid options or joint limits ([`PlanError::Option`]).
    pub fn numerical(model: &'a Model, numeric: MultiStartOptions) -> Result<Self, PlanError> {
        let revolute = revolute_joints(model);
        let guide = revolute.iter().position(|r| !r).map(|k| k + 1);
        let free: Vec<usize> = (1..=revolute.len()).filter(|i| Some(*i) != guide).collect();
        let specs: Vec<JointSpec> = free.iter().map(|i| joint_spec(model, *i, revolute[i - 1])).collect();
        let me = Self { model, solver: Solver::Numeric { guide, free, specs, opts: numeric, reason: None } };
        // validate the options and limits once
        me.numeric_at(0.0).transpose()?;
        Ok(me)
    }

    /// True when a closed form is in use.
    pub fn is_closed_form(&self) -> bool {
        matches!(self.solver, Solver::ClosedForm(..) | Solver::Parallel(..))
    }

    /// The IK in use (and why not the closed form).
    pub fn method(&self) -> IkMethod {
        match &self.solver {
            Solver::ClosedForm(..) => IkMethod::ClosedForm,
            Solver::Parallel(..) => IkMethod::ParallelClosedForm,
            Solver::Numeric { reason, .. } => IkMethod::Numerical { reason: reason.clone() },
        }
    }

    /// The joint held at the guide positions (1-based), if the chain has one.
    pub fn guide_joint(&self) -> Option<usize> {
        match &self.solver {
            Solver::ClosedForm(ik, _) => ik.guide_joint(),
            Solver::Parallel(ik, _) => ik.guide_joint(),
            Solver::Numeric { guide, .. } => *guide,
        }
    }

    /// The model.
    pub fn model(&self) -> &'a Model {
        self.model
    }

    /// The numerical solver with the guide at `guide_mm` (`None` for the closed form).
    fn numeric_at(&self, guide_mm: f64) -> Option<Result<NumericIk<ChainTool<'a>>, PlanError>> {
        let Solver::Numeric { guide, free, specs, opts, .. } = &self.solver else {
            return None;
        };
        let mut fixed = JointVector::zeros(self.model.joint_count());
        if let Some(g) = guide {
            fixed.set(*g, guide_mm);
        }
        let revolute = specs.iter().map(|s| s.revolute).collect();
        let tool = ChainTool { model: self.model, fixed, free: free.clone(), revolute };
        Some(NumericIk::new(tool, specs, *opts))
    }

    /// Every solution with the guide at `guide_mm` (ignored without a guide), duplicates
    /// merged; revolute joints wrapped to (-pi, pi] where the limits allow, else moved by whole
    /// turns into the limits. The numerical IK returns solutions inside the limits only, the
    /// closed form every branch (also outside the limits, as [`ToolPoseIk`]).
    pub fn solve_at_guide(&self, guide_mm: f64, target: &Frame) -> Vec<JointVector> {
        match self.numeric_at(guide_mm) {
            None => match &self.solver {
                Solver::ClosedForm(ik, specs) => normalised(ik.solve_at_guide(guide_mm, target), specs),
                Solver::Parallel(ik, specs) => normalised(ik.solve_at_guide(guide_mm, target), specs),
                Solver::Numeric { .. } => Vec::new(),
            },
            Some(Err(_)) => Vec::new(),
            Some(Ok(ik)) => {
                let out = ik.solve(&IkTarget::Pose(*target));
                out.joints().map(|q| ik.kinematics().joints(q)).collect()
            }
        }
    }

    /// Like [`ModelIk::solve_at_guide`], warm-started when the numerical IK is in use: the
    /// joint vectors `warm` (solutions of a neighbouring target, e.g. the previous guide step
    /// or a nearby tool orientation; their guide value is ignored) are tried first, and the
    /// search stops as soon as `enough` distinct solutions are found (0: every start is tried;
    /// see [`NumericIk::solve_warm`]). A closed form ignores `warm` and `enough` (it is exact
    /// and complete). Deterministic for given arguments.
    pub fn solve_at_guide_warm(
        &self,
        guide_mm: f64,
        target: &Frame,
        warm: &[JointVector],
        enough: usize,
    ) -> Vec<JointVector> {
        let (Solver::Numeric { free, .. }, Some(Ok(ik))) = (&self.solver, self.numeric_at(guide_mm)) else {
            return self.solve_at_guide(guide_mm, target);
        };
        let starts: Vec<Vec<f64>> = warm.iter().map(|q| free.iter().map(|i| q.get(*i)).collect()).collect();
        let starts: Vec<&[f64]> = starts.iter().map(Vec::as_slice).collect();
        let out = ik.solve_warm(&IkTarget::Pose(*target), &starts, enough);
        out.joints().map(|q| ik.kinematics().joints(q)).collect()
    }

    /// Every solution over several guide positions (one pass when the chain has no guide).
    pub fn solve(&self, guide_positions_mm: &[f64], target: &Frame) -> Vec<JointVector> {
        if self.guide_joint().is_none() {
            return self.solve_at_guide(0.0, target);
        }
        guide_positions_mm.iter().flat_map(|g| self.solve_at_guide(*g, target)).collect()
    }

    /// One local solve ([`solve_local`]) from `q` so that the tool-changer frame reaches
    /// `target`, with the guide joint (the first prismatic joint, if any) held at its value in
    /// `q` and the other joints kept inside their limits; each revolute value of the result is
    /// then moved by whole turns to the representative nearest its value in `q` (a short move
    /// from `q`, e.g. to a retreat pose). Works on any chain, closed form or not.
    ///
    /// # Errors
    /// [`PlanError::IkNotConverged`] when the local solve misses the tolerances of `refine`.
    pub fn refine_from(
        &self,
        q: &JointVector,
        target: &Frame,
        refine: &RefineOptions,
    ) -> Result<JointVector, PlanError> {
        let revolute = revolute_joints(self.model);
        let guide = revolute.iter().position(|r| !r).map(|k| k + 1);
        let free: Vec<usize> = (1..=revolute.len()).filter(|i| Some(*i) != guide).collect();
        let specs: Vec<JointSpec> =
            free.iter().map(|i| joint_spec(self.model, *i, revolute[i - 1])).collect();
        let tool = ChainTool {
            model: self.model,
            fixed: *q,
            free: free.clone(),
            revolute: free.iter().map(|i| revolute[i - 1]).collect(),
        };
        let start: Vec<f64> = free.iter().map(|i| q.get(*i)).collect();
        let r = solve_local(&tool, &specs, &start, &IkTarget::Pose(*target), refine)?;
        let mut out = tool.joints(&r.q);
        for i in free.into_iter().filter(|i| revolute[i - 1]) {
            let q0 = q.get(i);
            out.set(i, q0 + wrap_angle(out.get(i) - q0));
        }
        Ok(out)
    }
}

/// Every joint's spec of `model` (the closed forms normalise their solutions into the limits
/// with them).
fn all_joint_specs(model: &Model) -> Vec<JointSpec> {
    let revolute = revolute_joints(model);
    (1..=revolute.len()).map(|i| joint_spec(model, i, revolute[i - 1])).collect()
}

/// `solutions` with every value normalised into its joint's limits ([`JointSpec::normalise`]).
fn normalised(mut solutions: Vec<JointVector>, specs: &[JointSpec]) -> Vec<JointVector> {
    for q in &mut solutions {
        for (v, spec) in q.as_mut_slice().iter_mut().zip(specs) {
            *v = spec.normalise(*v);
        }
    }
    solutions
}

/// Largest absolute componentwise difference of two joint vectors (internal units).
pub(crate) fn max_abs_diff(a: &JointVector, b: &JointVector) -> f64 {
    a.as_slice().iter().zip(b.as_slice()).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// World tool-changer-frame pose that puts TCP offset `tcp_in_tool` at `point_world` with tool
/// orientation `rotation` (world).
pub fn tool_pose_for_tcp(
    rotation: &Matrix3<f64>,
    tcp_in_tool: &Vector3<f64>,
    point_world: &Vector3<f64>,
) -> Frame {
    Frame { r: *rotation, p: point_world - rotation * tcp_in_tool }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_angle_range() {
        use std::f64::consts::{PI, TAU};
        for a in [-10.0, -PI, 0.0, 3.0, PI, 7.0, 100.0] {
            let w = wrap_angle(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            let turns = (a - w) / TAU;
            assert!((turns - turns.round()).abs() < 1e-12, "{a} -> {w} is not a whole number of turns away");
        }
    }

    #[test]
    fn rotation_vector_small_and_large_angles() {
        for (axis, angle) in [
            (Vector3::new(1.0, 2.0, 3.0).normalize(), 1e-9),
            (Vector3::new(0.0, 0.0, 1.0), 0.7),
            (Vector3::new(1.0, -1.0, 0.5).normalize(), std::f64::consts::PI - 1e-9),
        ] {
            let r =
                *nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle).matrix();
            let v = rotation_vector(&r);
            assert!((v - axis * angle).norm() < 1e-8 * angle.max(1e-6), "{v} vs {}", axis * angle);
        }
    }
}
