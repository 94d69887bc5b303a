#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Planning of a measurement campaign (paper Sections 2.4, 4.1 and 4.2): which joint
//! configurations to measure, in which order, and how to move between them.
//!
//! 1. [`ik`] — closed-form inverse kinematics of the nominal Meca500 and any 6R arm with a
//!    spherical wrist, [`parallel_arm`] — of any 6R arm with three parallel middle axes and a
//!    UR-type wrist (up to 8 branches per tool pose and guide position each), and their
//!    Levenberg–Marquardt refinement on the full, possibly calibrated,
//!    [`vatcal_kinematics::Model`]; [`numeric_ik`] — multi-start numerical IK for any serial
//!    chain (used by [`ik::ModelIk`] when there is no closed form);
//! 2. [`candidates`] — random tool orientations per TCP × calibration position, IK at every
//!    guide step, joint-limit, singularity and collision screening (paper: 3,284 candidates);
//! 3. selection — Detmax (`vatcal-observability`) of `count` candidates, with O1..O5;
//! 4. [`tour`] — the visiting order that minimises the campaign time (joint-move times and
//!    probe re-placements; nearest neighbour + 2-opt + Or-opt + block reordering, exact
//!    Held–Karp for small instances);
//! 5. [`paths`] — a verified collision-free joint-space path for every leg (straight or
//!    RRT-Connect with shortcutting);
//! 6. [`plan`] — the whole pipeline, [`plan_campaign`], and [`output`] — the files of
//!    `vatcal plan`.
//!
//! Collision geometry ([`geometry`], [`collision`]): robot links as capsules, end-effector plate
//! and balls, guide box, tank, TriCal and floor from the cell file, checked with parry3d-f64.
//!
//! Units: mm and rad inside; option fields and files carry their unit in their name (`_deg`,
//! `_mm`, `_s`). See `docs/planning.md`.

pub mod candidates;
pub mod collision;
pub mod error;
pub mod geometry;
pub mod ik;
pub mod motion;
pub mod numeric_ik;
pub mod output;
pub mod parallel_arm;
pub mod paths;
pub mod plan;
pub mod tour;

pub use error::PlanError;
pub use geometry::CellGeometry;
pub use plan::{Plan, PlanOptions, plan_campaign};
