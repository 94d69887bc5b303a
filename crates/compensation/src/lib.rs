#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Puts a calibration to work: turns requested world poses into joint targets under the
//! **calibrated** model (issue 13), so that the cell physically lands where it is asked to, and
//! into the poses the robot's own (nominal) controller must be sent to get there. Works on any
//! serial chain of six or more joints (issue 12): the canonical Meca500-on-guide cell, a
//! six-joint arm (UR5e, Meca500 on a table), or a longer chain with prismatic external axes.
//!
//! * [`JointSplit`] — which joints a request gives (the prismatic external axes of a chain with
//!   more than six joints, e.g. the canonical guide `q1`; none on a six-joint arm) and which six
//!   the pose determines; fewer than six joints is an error.
//! * [`PoseRequest`] — one requested pose as a slicer writes it: TCP id, the given joints, TCP
//!   point `x, y, z` \[mm\] in the world (resin-tank) frame and the orientation of the chain's
//!   last frame (the tool-changer frame, frame 7 on the canonical cell) as Mecademic intrinsic
//!   X-Y-Z Euler angles `α, β, γ` \[deg\], plus the optional per-sample context (`time_s`,
//!   `temperature_c`, `dir`) the model's effects use. [`ToolTarget`] is the same request as a
//!   world frame.
//! * [`Compensator`] — [`Compensator::compensate_pose`] for one pose,
//!   [`Compensator::compensate_path`] for a path (same IK branch throughout, each pose seeded
//!   from the previous solution, branch changes, joint jumps, limit violations and unreachable
//!   rows named, or skipped and reported), and [`Compensator::corrected_pose`] —
//!   `FK_nominal(IK_calibrated(request))`, the pose a `MovePose` program must send.
//!   [`Compensator::compensate_each`] solves independent poses, each row on its own (on the
//!   branch it names, nearest a given configuration, or farthest from the limits:
//!   [`EachOptions`]).
//! * [`path_accuracy`] — the proof on a virtual cell: the true error along a path commanded
//!   with compensated targets and with uncompensated (nominal) targets.
//!
//! The solver ([`solve`]) is Newton's method on the analytic 6×6 Jacobian of the tool frame
//! with respect to the six solved joints (compliance and every enabled effect in the forward
//! kinematics, the Jacobian holding gravity torques fixed as in the paper), warm-started from a
//! quadratic prediction of the previous poses' solutions; the first pose of a path, or a pose
//! where the warm start fails, is seeded from the closed-form branches of `vatcal_planning::ik`
//! on the canonical cell, and from `vatcal_planning::ik::ModelIk` (closed form or multi-start
//! numerical IK) on any other chain, where the IK branch is the sign of `det J` ([`Branch`]).
//!
//! Units: mm and degrees in [`PoseRequest`] and in the files, mm and radians inside.
//! See `docs/compensation.md`.

mod accuracy;
mod branch;
mod each;
mod error;
mod path;
mod pose;
pub mod solve;
mod split;

pub use accuracy::{ErrorSummary, PathAccuracy, path_accuracy};
pub use branch::Branch;
pub use each::{EachOptions, Preference};
pub use error::CompensationError;
pub use path::{Compensated, Compensator, CorrectedPose, PathOptions, PathResult, RowOutcome, SkippedRow};
pub use pose::{
    PoseRequest, ToolTarget, euler_xyz_deg_to_rotation, frame_to_meca_pose, meca_pose_to_frame,
    rotation_to_euler_xyz_deg,
};
pub use solve::SolveOptions;
pub use split::JointSplit;
