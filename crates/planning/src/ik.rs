//! Inverse kinematics of the cell: closed form for the nominal Meca500 arm, numerical
//! refinement on the full [`Model`].
//!
//! # Frames
//! The *robot base frame* `B` is the parent of MDH frame 2: the carriage frame 1 (after the
//! guide) followed by the fixed part `Rx(alpha_1) Tx(a_1) Ry(beta_1)` of row 2 (the sideways
//! mounting, `alpha_1 = -90 deg`). It depends on q1 only ([`robot_base_frame`]). In `B` the arm
//! is the ordinary Meca500: rows 2..7 of the cell.
//!
//! # Closed form ([`ArmGeometry::solve`])
//! Written in the MDH angles `theta_i = q_i + theta_offset_i` of rows 2..7 and the structure
//! `alpha = (-90, 0, -90, 90, -90) deg` for rows 3..7, `a_2 = a_5 = a_6 = 0`,
//! `d_3 = d_4 = d_6 = 0` (spherical wrist; the 38 mm elbow offset is `a_4`):
//!
//! 1. wrist centre `w = p_7 - d_7 z_7` (origin of frames 5 and 6);
//! 2. shoulder: `theta_2 = atan2(w_y, w_x)` with the arm-plane abscissa `r = +rho`, or
//!    `theta_2 + pi` with `r = -rho` (`rho = |(w_x, w_y)|`), height `h = w_z - d_2`;
//! 3. elbow: `a_4 cos theta_4 - d_5 sin theta_4 = (r^2 + h^2 - a_3^2 - a_4^2 - d_5^2) / (2 a_3)`,
//!    i.e. `theta_4 = ±acos(K / L) - delta` with `L = |(a_4, d_5)|`, `delta = atan2(d_5, a_4)`;
//! 4. `theta_3 = atan2(v_h, v_r) - atan2(h, r)` where `v = a_3 e(0) + a_4 e(-theta_4) +
//!    d_5 e(-theta_4 - 90 deg)` is the wrist centre in the upper-arm frame (`e(phi)` = unit vector
//!    at angle phi in the arm plane);
//! 5. wrist: `M = R_4^T R_7 Rx(90 deg) = Ry(theta_5) Rz(theta_6) Ry(theta_7)` (Y-Z-Y Euler
//!    angles), two branches `theta_6 = ±acos(M_11)`.
//!
//! Two shoulder × two elbow × two wrist branches give up to 8 solutions; `q_i = theta_i -
//! theta_offset_i`, wrapped into (-pi, pi]. The closed form uses the model's own lengths and
//! theta offsets; the small angular errors of a calibrated model (alpha, beta, compliance,
//! effects) are removed by [`refine_tool_pose`].
//!
//! # Seeds on a calibrated model ([`ToolPoseIk::seeds`])
//! Each closed-form branch is corrected on its own branch before the refinement
//! (`T* E(q)⁻¹` with `E` the nominal-structure error at the seed, [`SEED_CORRECTIONS`] times),
//! and a wrist centre up to 2 % beyond the nominal reach still gives seeds
//! ([`ArmGeometry::solve_with_reach_slack`]). Within a few degrees of the wrist singularity a
//! calibrated wrist (axes no longer exactly intersecting) can have more than eight solutions;
//! the eight branches of the spherical wrist are the ones returned.
//!
//! # Refinement ([`refine_tool_pose`])
//! Levenberg–Marquardt on the 6-DOF tool-frame error `[p* - p; log(R* R^T)]` with q1 held fixed.
//! The Jacobian columns are `z_i × (p - o_i)` (position; identical to the
//! `ParamId::ThetaOffset(i)` columns of `Model::jacobian`) and `z_i` (orientation), with the joint
//! axes from [`vatcal_kinematics::Chain::frames`]. Gravity torques are held fixed in the
//! Jacobian, so with compliance the iteration is quasi-Newton (still converging to machine
//! precision because `c_i d(tau_i)/dq` is tiny). The iteration is the chain-agnostic one of
//! [`crate::numeric_ik::solve_local`], run on [`ArmAtGuide`] (the arm with q1 fixed).

use nalgebra::{Matrix3, Matrix6, Matrix6xX, Vector3};
use vatcal_core::frame::{rot_x, rot_y, rot_z};
use vatcal_core::{Frame, JointVector};
use vatcal_kinematics::Model;

use crate::error::PlanError;
use crate::numeric_ik::{IkTarget, JointSpec, MultiStartOptions, NumericIk, ToolKinematics, solve_local};

/// Elbow angle from the stretched / folded arm at which seeds are placed for a wrist centre
/// just beyond the nominal reach (rad).
pub const ELBOW_SEED_RAD: f64 = 0.05;
/// Relative reach slack of the seeds used for refinement (see
/// [`ArmGeometry::solve_with_reach_slack`]).
const SEED_REACH_SLACK: f64 = 0.02;
/// Tolerance on the structural angles (alpha) for the closed form to be used as a seed (rad).
const STRUCTURE_ANGLE_TOL_RAD: f64 = 0.05;
/// Tolerance on the structural lengths that must be zero (mm).
const STRUCTURE_LENGTH_TOL_MM: f64 = 5.0;

/// Rotation about x.
/// Rotation about y.
/// Rotation about z.
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

/// World pose of the robot base frame `B` (parent of MDH frame 2) at guide position `q1_mm`.
/// Includes the model's base pose, guide effects and the fixed part of row 2.
pub fn robot_base_frame(model: &Model, q1_mm: f64) -> Frame {
    let mut q = JointVector::default();
    q[0] = q1_mm;
    let chain = model.chain(&q);
    let row = model.row(2);
    let fixed = Frame { r: rot_x(row.alpha) * rot_y(row.beta), p: Vector3::new(row.a, 0.0, 0.0) };
    chain.frames[1].compose(&fixed)
}

/// The arm lengths and offsets used by the closed form (rows 2..7 of a model).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmGeometry {
    /// `d_2`: height of the shoulder (J2 axis) above the base frame (mm)
    pub shoulder_height_mm: f64,
    /// `a_3`: upper-arm length (J2 to J3 axis) (mm)
    pub upper_arm_mm: f64,
    /// `a_4`: elbow offset (mm)
    pub elbow_offset_mm: f64,
    /// `d_5`: forearm length to the wrist centre (mm)
    pub forearm_mm: f64,
    /// `d_7`: wrist centre to the tool-changer frame (mm)
    pub flange_mm: f64,
    /// `theta_offset_2..7` (rad)
    pub theta_offset_rad: [f64; 6],
}

/// Up to eight closed-form solutions `[q2..q7]` (rad) for one tool pose.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ArmSolutions {
    q: [[f64; 6]; 8],
    beyond_reach: [bool; 8],
    branch: [u8; 8],
    len: usize,
}

impl ArmSolutions {
    /// The solutions found (0..=8), each `[q2, q3, q4, q5, q6, q7]` in rad, wrapped to (-pi, pi].
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
    /// J1 plane), bit 1 = elbow (0: `+acos`), bit 2 = wrist (0: `theta_6 >= 0`).
    pub fn branches(&self) -> &[u8] {
        &self.branch[..self.len]
    }

    /// The solution of branch `branch`, if present.
    pub fn of_branch(&self, branch: u8) -> Option<[f64; 6]> {
        self.branches().iter().position(|b| *b == branch).map(|k| self.q[k])
    }

    fn push(&mut self, q: [f64; 6], beyond_reach: bool, branch: u8) {
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
    /// Reads the arm geometry from rows 2..7 of `model`, checking that the model has the
    /// Meca500 structure the closed form assumes (within 0.05 rad / 5 mm, so a calibrated model
    /// is accepted: its small deviations are removed by the refinement).
    pub fn from_model(model: &Model) -> Result<Self, PlanError> {
        use std::f64::consts::FRAC_PI_2;
        if !model.is_meca500_on_guide() {
            return Err(PlanError::UnsupportedArm(format!(
                "the closed-form IK needs the 7-joint Meca500-on-guide chain (prismatic guide + 6 revolute joints); this chain has {}",
                model.describe_chain()
            )));
        }
        let angle = |row: usize, want: f64| {
            let got = model.row(row).alpha;
            if (wrap_angle(got - want)).abs() > STRUCTURE_ANGLE_TOL_RAD {
                return Err(PlanError::UnsupportedArm(format!(
                    "alpha_{} = {:.3} deg, the closed form needs {:.0} deg",
                    row - 1,
                    got.to_degrees(),
                    want.to_degrees()
                )));
            }
            Ok(())
        };
        angle(3, -FRAC_PI_2)?;
        angle(4, 0.0)?;
        angle(5, -FRAC_PI_2)?;
        angle(6, FRAC_PI_2)?;
        angle(7, -FRAC_PI_2)?;
        let zero_length = |name: &str, v: f64| {
            if v.abs() > STRUCTURE_LENGTH_TOL_MM {
                return Err(PlanError::UnsupportedArm(format!(
                    "{name} = {v:.3} mm, the closed form needs 0 (spherical wrist, no shoulder offset)"
                )));
            }
            Ok(())
        };
        zero_length("a_2", model.row(3).a)?;
        zero_length("d_3", model.row(3).d)?;
        zero_length("d_4", model.row(4).d)?;
        zero_length("a_5", model.row(6).a)?;
        zero_length("d_6", model.row(6).d)?;
        zero_length("a_6", model.row(7).a)?;
        let upper_arm_mm = model.row(4).a;
        if upper_arm_mm.abs() < 1.0 {
            return Err(PlanError::UnsupportedArm(format!("a_3 = {upper_arm_mm} mm is not an upper arm")));
        }
        let mut theta_offset_rad = [0.0; 6];
        for (k, t) in theta_offset_rad.iter_mut().enumerate() {
            *t = model.row(k + 2).theta_offset;
        }
        Ok(Self {
            shoulder_height_mm: model.row(2).d,
            upper_arm_mm,
            elbow_offset_mm: model.row(5).a,
            forearm_mm: model.row(5).d,
            flange_mm: model.row(7).d,
            theta_offset_rad,
        })
    }

    /// All closed-form solutions for the tool-changer frame (frame 7) pose `target` given in
    /// the robot base frame `B`. Each is `[q2..q7]` (rad) (model offsets removed, wrapped).
    pub fn solve(&self, target: &Frame) -> ArmSolutions {
        self.solve_with_reach_slack(target, 0.0)
    }

    /// Like [`ArmGeometry::solve`], but a wrist centre up to `slack` (relative, in the elbow
    /// equation `|K / L| <= 1 + slack`) beyond the reach of this nominal-structure arm still
    /// gives seeds: both elbow branches at ±[`ELBOW_SEED_RAD`] from the stretched/folded arm.
    /// A calibrated arm may reach what its nominal structure cannot; the refinement decides.
    pub fn solve_with_reach_slack(&self, target: &Frame, slack: f64) -> ArmSolutions {
        let mut out = ArmSolutions::default();
        let z7 = target.z_axis();
        let w = target.p - z7 * self.flange_mm;
        let rho = w.x.hypot(w.y);
        let h = w.z - self.shoulder_height_mm;
        let theta2_base = if rho > 1e-12 { w.y.atan2(w.x) } else { 0.0 };
        let (a3, a4, d5) = (self.upper_arm_mm, self.elbow_offset_mm, self.forearm_mm);
        let l = a4.hypot(d5);
        let delta = d5.atan2(a4);
        for (shoulder_bit, shoulder) in [(0u8, 1.0), (1, -1.0)] {
            let r = shoulder * rho;
            let theta2 = if shoulder > 0.0 { theta2_base } else { theta2_base + std::f64::consts::PI };
            let k = (r * r + h * h - a3 * a3 - a4 * a4 - d5 * d5) / (2.0 * a3);
            let ratio = k / l;
            if ratio.is_nan() || ratio.abs() > 1.0 + 1e-12 + slack {
                continue;
            }
            let beyond = ratio.abs() > 1.0 + 1e-12;
            let gamma = if !beyond {
                ratio.clamp(-1.0, 1.0).acos()
            } else {
                let edge = if ratio > 0.0 { 0.0 } else { std::f64::consts::PI };
                (edge - ELBOW_SEED_RAD).abs()
            };
            for (elbow_bit, elbow) in [(0u8, gamma), (2, -gamma)] {
                let theta4 = elbow - delta;
                let (s4, c4) = theta4.sin_cos();
                // v = a3 e(0) + a4 e(-theta4) + d5 e(-theta4 - 90 deg), e(phi) = (cos phi, sin phi)
                let v_r = a3 + a4 * c4 - d5 * s4;
                let v_h = -a4 * s4 - d5 * c4;
                let theta3 = v_h.atan2(v_r) - h.atan2(r);
                let branch = shoulder_bit | elbow_bit;
                self.push_wrist(&mut out, target, [theta2, theta3, theta4], beyond, branch);
                if gamma == 0.0 {
                    break;
                }
            }
        }
        out
    }

    /// Forward kinematics of this nominal-structure arm: the tool-changer frame in the robot
    /// base frame for joints `[q2..q7]` (rad) (the exact inverse of [`ArmGeometry::solve`]).
    pub fn forward(&self, q: &[f64; 6]) -> Frame {
        use std::f64::consts::FRAC_PI_2;
        let t: [f64; 6] = std::array::from_fn(|k| q[k] + self.theta_offset_rad[k]);
        let link = |alpha: f64, a: f64, theta: f64, d: f64| {
            let r = rot_x(alpha) * rot_z(theta);
            Frame { r, p: Vector3::new(a, 0.0, 0.0) + r.column(2) * d }
        };
        [
            link(0.0, 0.0, t[0], self.shoulder_height_mm),
            link(-FRAC_PI_2, 0.0, t[1], 0.0),
            link(0.0, self.upper_arm_mm, t[2], 0.0),
            link(-FRAC_PI_2, self.elbow_offset_mm, t[3], self.forearm_mm),
            link(FRAC_PI_2, 0.0, t[4], 0.0),
            link(-FRAC_PI_2, 0.0, t[5], self.flange_mm),
        ]
        .iter()
        .fold(Frame::identity(), |acc, l| acc.compose(l))
    }

    /// Adds the (up to two) wrist solutions for given arm angles theta_2..4.
    fn push_wrist(&self, out: &mut ArmSolutions, target: &Frame, arm: [f64; 3], beyond: bool, branch: u8) {
        let [t2, t3, t4] = arm;
        // R_4 in B: Rz(t2) Rx(-90) Rz(t3) Rz(t4)   (alpha_3 = 0, beta = 0)
        let r4 = rot_z(t2) * rot_x(-std::f64::consts::FRAC_PI_2) * rot_z(t3 + t4);
        let m = r4.transpose() * target.r * rot_x(std::f64::consts::FRAC_PI_2);
        let s6 = m[(0, 1)].hypot(m[(2, 1)]);
        let c6 = m[(1, 1)];
        let mut add = |t5: f64, t6: f64, t7: f64, wrist_bit: u8| {
            let theta = [t2, t3, t4, t5, t6, t7];
            let mut q = [0.0; 6];
            for k in 0..6 {
                q[k] = wrap_angle(theta[k] - self.theta_offset_rad[k]);
            }
            out.push(q, beyond, branch | wrist_bit);
        };
        if s6 > 1e-12 {
            let t6 = s6.atan2(c6);
            let t5 = m[(2, 1)].atan2(-m[(0, 1)]);
            let t7 = m[(1, 2)].atan2(m[(1, 0)]);
            add(t5, t6, t7, 0);
            add(t5 + std::f64::consts::PI, -t6, t7 + std::f64::consts::PI, 4);
        } else if c6 > 0.0 {
            // theta6 = 0: M = Ry(t5 + t7); choose t5 = 0
            add(0.0, 0.0, m[(0, 2)].atan2(m[(0, 0)]), 0);
        } else {
            // theta6 = pi: M = Ry(t5 - t7) Rz(pi); choose t5 = 0
            let mm = m * rot_z(std::f64::consts::PI).transpose();
            add(0.0, std::f64::consts::PI, -mm[(0, 2)].atan2(mm[(0, 0)]), 0);
        }
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

/// The 6×6 joint Jacobian (q2..q7) of the tool frame: `[z_i × (p - o_i); z_i]` (world axes;
/// rows: translation, then rotation).
#[inline]
pub fn tool_jacobian(chain: &vatcal_kinematics::Chain) -> Matrix6<f64> {
    let p = chain.tool.p;
    let mut j = Matrix6::zeros();
    for k in 0..6 {
        let f = &chain.frames[k + 2];
        let z = f.z_axis();
        let lin = z.cross(&(p - f.p));
        for r in 0..3 {
            j[(r, k)] = lin[r];
            j[(r + 3, k)] = z[r];
        }
    }
    j
}

/// The arm of a [`Model`] with the guide held at `q1_mm`, as a [`ToolKinematics`] of six
/// joints `[q2..q7]` (rad): tool-changer frame in the world and [`tool_jacobian`].
#[derive(Debug, Clone, Copy)]
pub struct ArmAtGuide<'a> {
    /// the model
    pub model: &'a Model,
    /// guide position (mm)
    pub q1_mm: f64,
}

impl ArmAtGuide<'_> {
    /// The cell's joint vector for arm joints `q` (rad).
    pub fn joints(&self, q: &[f64]) -> JointVector {
        let mut v = JointVector::default();
        v[0] = self.q1_mm;
        v.as_mut_slice()[1..7].copy_from_slice(&q[..6]);
        v
    }
}

impl ToolKinematics for ArmAtGuide<'_> {
    type Eval = vatcal_kinematics::Chain;

    fn dof(&self) -> usize {
        6
    }

    fn evaluate(&self, q: &[f64]) -> (Frame, vatcal_kinematics::Chain) {
        let chain = self.model.chain(&self.joints(q));
        (chain.tool, chain)
    }

    fn jacobian(&self, chain: &vatcal_kinematics::Chain, jacobian: &mut Matrix6xX<f64>) {
        jacobian.copy_from(&tool_jacobian(chain));
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

/// Refines `seed` (q1 held fixed) so that the model's tool-changer frame reaches `target`
/// (world). Levenberg–Marquardt on the weighted 6-DOF error (no joint limits):
/// [`crate::numeric_ik::solve_local`] on [`ArmAtGuide`]; see the module docs.
pub fn refine_tool_pose(
    model: &Model,
    seed: &JointVector,
    target: &Frame,
    opts: &RefineOptions,
) -> Result<Refined, PlanError> {
    let arm = ArmAtGuide { model, q1_mm: seed[0] };
    let r = solve_local(
        &arm,
        &[JointSpec::continuous(); 6],
        &seed.as_slice()[1..],
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
    /// joints (q1 as given)
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
#[derive(Debug, Clone)]
pub struct ToolPoseIk<'a> {
    model: &'a Model,
    arm: ArmGeometry,
    refine: RefineOptions,
    corrections: usize,
}

/// Branch-preserving closed-form corrections of a seed on a calibrated model.
pub const SEED_CORRECTIONS: usize = 2;

/// True when the model's tool frame is the closed-form arm's at a few test configurations
/// (nominal model: no seed correction needed).
fn closed_form_is_exact(model: &Model, arm: &ArmGeometry) -> bool {
    let tests = [
        [120.0, 30.0, 20.0, -40.0, 50.0, 60.0, -70.0],
        [10.0, -100.0, -50.0, 30.0, -120.0, -20.0, 150.0],
        [280.0, 150.0, 80.0, -120.0, 10.0, 100.0, 5.0],
    ];
    tests.iter().all(|t| {
        let q = JointVector::from_mm_deg(t[0], [t[1], t[2], t[3], t[4], t[5], t[6]]);
        let arm_q: [f64; 6] = std::array::from_fn(|k| q[k + 1]);
        let nominal = robot_base_frame(model, q[0]).compose(&arm.forward(&arm_q));
        let actual = model.chain(&q).tool;
        (nominal.p - actual.p).norm() < 1e-9 && rotation_angle_between(&nominal.r, &actual.r) < 1e-12
    })
}

impl<'a> ToolPoseIk<'a> {
    /// IK for `model` (its arm must have the Meca500 structure, see [`ArmGeometry::from_model`]).
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
    /// [`PlanError::UnsupportedArm`] when the model's arm does not have the Meca500 structure the
    /// closed-form seeds need (intersecting wrist axes, the row layout of the canonical cell).
    pub fn new(model: &'a Model, refine: RefineOptions) -> Result<Self, PlanError> {
        let arm = ArmGeometry::from_model(model)?;
        let corrections = if closed_form_is_exact(model, &arm) { 0 } else { SEED_CORRECTIONS };
        Ok(Self { model, arm, refine, corrections })
    }

    /// The closed-form geometry in use.
    pub fn arm(&self) -> &ArmGeometry {
        &self.arm
    }

    /// The model.
    pub fn model(&self) -> &'a Model {
        self.model
    }

    /// Closed-form seeds at guide position `q1_mm` for the world tool pose `target`, given the
    /// robot base frame `base` at that guide position ([`robot_base_frame`]); corrected on
    /// their branch for a calibrated model (see the type docs).
    pub fn seeds(&self, q1_mm: f64, base: &Frame, target: &Frame) -> Vec<IkSeed> {
        let base_inv = base.inverse();
        let solutions = self.arm.solve_with_reach_slack(&base_inv.compose(target), SEED_REACH_SLACK);
        let joints = |arm: &[f64; 6]| {
            let mut q = [0.0; 7];
            q[0] = q1_mm;
            q[1..].copy_from_slice(arm);
            JointVector::new(q)
        };
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
    pub fn refine(&self, seed: &JointVector, target: &Frame) -> Result<Refined, PlanError> {
        refine_tool_pose(self.model, seed, target, &self.refine)
    }

    /// Every solution at guide position `q1_mm` (closed-form seeds refined on the model; seeds
    /// that do not converge are dropped; duplicates merged), each wrapped to (-pi, pi].
    pub fn solve_at_guide(&self, q1_mm: f64, target: &Frame) -> Vec<JointVector> {
        let base = robot_base_frame(self.model, q1_mm);
        let mut out: Vec<JointVector> = Vec::with_capacity(8);
        for seed in self.seeds(q1_mm, &base, target) {
            if let Ok(r) = self.refine(&seed.q, target) {
                let mut q = r.q;
                for v in q.as_mut_slice().iter_mut().skip(1) {
                    *v = wrap_angle(*v);
                }
                if !out.iter().any(|p| max_abs_diff(p, &q) < 1e-9) {
                    out.push(q);
                }
            }
        }
        out
    }

    /// Every solution over several guide positions (up to 8 per position).
    pub fn solve(&self, guide_positions_mm: &[f64], target: &Frame) -> Vec<JointVector> {
        guide_positions_mm.iter().flat_map(|q1| self.solve_at_guide(*q1, target)).collect()
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

/// Inverse kinematics of the tool-changer frame of any [`Model`]: the closed form + refinement
/// ([`ToolPoseIk`]) when the arm has the Meca500 structure ([`ArmGeometry::from_model`]), the
/// multi-start numerical IK ([`crate::numeric_ik::NumericIk`] on a [`ChainTool`]) otherwise.
/// The first prismatic joint, if any, is the guide: it is held at the given guide positions
/// and the other joints are solved for; a chain without one ignores the guide positions.
#[derive(Debug)]
pub struct ModelIk<'a> {
    model: &'a Model,
    solver: Solver<'a>,
}

#[derive(Debug)]
enum Solver<'a> {
    ClosedForm(ToolPoseIk<'a>),
    Numeric { guide: Option<usize>, free: Vec<usize>, specs: Vec<JointSpec>, opts: MultiStartOptions },
}

impl<'a> ModelIk<'a> {
    /// The closed form when the model allows it, the numerical IK otherwise.
    ///
    /// # Errors
    /// Invalid numerical-IK options or joint limits ([`PlanError::Option`]).
    pub fn new(
        model: &'a Model,
        refine: RefineOptions,
        numeric: MultiStartOptions,
    ) -> Result<Self, PlanError> {
        match ToolPoseIk::new(model, refine) {
            Ok(ik) => Ok(Self { model, solver: Solver::ClosedForm(ik) }),
            Err(PlanError::UnsupportedArm(_)) => Self::numerical(model, numeric),
            Err(e) => Err(e),
        }
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
        let me = Self { model, solver: Solver::Numeric { guide, free, specs, opts: numeric } };
        // validate the options and limits once
        me.numeric_at(0.0).transpose()?;
        Ok(me)
    }

    /// True when the closed form is in use.
    pub fn is_closed_form(&self) -> bool {
        matches!(self.solver, Solver::ClosedForm(_))
    }

    /// The joint held at the guide positions (1-based), if the chain has one.
    pub fn guide_joint(&self) -> Option<usize> {
        match &self.solver {
            Solver::ClosedForm(_) => Some(1),
            Solver::Numeric { guide, .. } => *guide,
        }
    }

    /// The model.
    pub fn model(&self) -> &'a Model {
        self.model
    }

    /// The numerical solver with the guide at `guide_mm` (`None` for the closed form).
    fn numeric_at(&self, guide_mm: f64) -> Option<Result<NumericIk<ChainTool<'a>>, PlanError>> {
        let Solver::Numeric { guide, free, specs, opts } = &self.solver else {
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
    /// merged; revolute joints wrapped to (-pi, pi] where the limits allow.
    pub fn solve_at_guide(&self, guide_mm: f64, target: &Frame) -> Vec<JointVector> {
        match self.numeric_at(guide_mm) {
            None => match &self.solver {
                Solver::ClosedForm(ik) => ik.solve_at_guide(guide_mm, target),
                Solver::Numeric { .. } => Vec::new(),
            },
            Some(Err(_)) => Vec::new(),
            Some(Ok(ik)) => {
                let out = ik.solve(&IkTarget::Pose(*target));
                out.joints().map(|q| ik.kinematics().joints(q)).collect()
            }
        }
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
