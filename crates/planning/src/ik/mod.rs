//! Inverse kinematics of a cell: closed form for the nominal geometry of a 6R arm with a
//! spherical wrist (the Meca500, KUKA KR, ABB IRB, Fanuc, Stäubli type) or with three parallel
//! middle axes and a UR-type wrist ([`ParallelArm`], the Universal Robots family), numerical
//! refinement on the full [`Model`](vatcal_kinematics::Model); [`ModelIk`] picks a closed form
//! wherever the chain qualifies and the multi-start numerical IK ([`crate::numeric_ik`])
//! otherwise. Both closed forms are seed sources of [`ToolPoseIk`] ([`ClosedFormArm`]); the rest of these docs
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
//! [`PlanError::UnsupportedArm`](crate::PlanError::UnsupportedArm) naming the row, field and
//! value (the wrist is checked first, so a UR5e-class arm is reported as not having a spherical wrist). [`ToolPoseIk`] and
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

mod closed_form;
mod common;
mod model_ik;
mod refine;
mod structure;
mod tool_pose;
mod wrist_band;

pub use crate::parallel_arm::ParallelArm;
pub use closed_form::{ArmGeometry, ArmSolutions, ClosedFormArm, ELBOW_SEED_RAD};
pub(crate) use common::max_abs_diff;
pub use common::{RefineOptions, rotation_angle_between, rotation_vector, wrap_angle};
pub use model_ik::{IkMethod, ModelIk, tool_pose_for_tcp};
pub use refine::{ArmAtGuide, ChainTool, Refined, arm_tool_jacobian, refine_tool_pose, tool_jacobian};
pub(crate) use structure::{
    STRUCTURE_ANGLE_TOL_RAD, STRUCTURE_LENGTH_TOL_MM, mdh_link, quarter_turn, sign_of_cos, structure_error,
    zero_or_half_turn,
};
pub use structure::{leading_prismatic_joints, robot_base_frame, robot_base_frame_at, six_revolute_arm};
pub use tool_pose::{IkSeed, SEED_CORRECTIONS, ToolPoseIk};
pub use wrist_band::{WRIST_RESEEDS, WRIST_SCAN_BAND_DEG, WRIST_SCAN_STEPS};
