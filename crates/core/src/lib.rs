#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! The small crate every other vatcal crate depends on. It holds types (and the effect
//! catalog's scalar definitions):
//!
//! * [`units`] — degree/radian conversions, [`JointKind`] and the [`JointVector`] of a serial
//!   chain of 1..=[`MAX_JOINTS`] joints (mm for prismatic, rad for revolute joints);
//! * [`cell`] — serde types for the cell file (version 1 `format = "meca500-zaber-cell"`, the
//!   Meca500 on its guide; version 2 `format = "serial-robot-cell"`, any serial chain), with
//!   validation that names the offending field;
//! * [`params`] — stable, human-readable parameter identifiers ([`ParamId`]) and the named
//!   parameter sets (`paper34`, `geometric`, ...);
//! * [`frame`] — a small rigid transform ([`Frame`]);
//! * [`effects`] — the error-effect catalog, one module per effect behind the
//!   [`effects::ErrorEffect`] trait (names, parameters, bounds, candidates and the
//!   kinematic hooks `vatcal-kinematics` applies);
//! * [`measurement`] — probe / tracker measurements and their per-sample context;
//! * [`canonical`] — everything specific to the canonical Meca500-on-guide cell (the dispatch
//!   predicate, its default parameter set, its hints), in one place;
//! * [`training_range`] — the joint range a calibration was fitted on (the optional
//!   `[training_range]` of a calibrated cell file) and the check of new postures against it.
//!
//! Units: every public Rust API uses **mm, rad, N·m, rad/(N·m), kg**. Degrees appear only at the
//! file and CLI boundary (the cell file, CSV files), and conversions happen here.

pub mod canonical;
pub mod cell;
pub mod effects;
pub mod frame;
pub mod measurement;
pub mod params;
pub mod training_range;
pub mod units;
mod vocabulary;

pub use cell::{CellError, CellFile};

/// The canonical nominal cell file (TOML): a Meca500 R3 on a Zaber X-LRQ300AP guide, the
/// TriCal probe and the resin tank of the paper. The repository's
/// `fixtures/meca500-zaber.toml` is this file (a link to `crates/core/cells/`, so that the
/// packaged crate carries it); the demo, the virtual cell and `vatcal compensate` build it in.
///
/// ```
/// let cell = vatcal_core::CellFile::from_toml_str(vatcal_core::CANONICAL_CELL_TOML, "canonical cell")?;
/// assert_eq!(cell.joints.len(), 7);
/// # Ok::<(), vatcal_core::CellError>(())
/// ```
pub const CANONICAL_CELL_TOML: &str = include_str!("../cells/meca500-zaber.toml");
pub use effects::{EffectKind, EffectSpec, ThermalDriver};
pub use frame::Frame;
pub use measurement::{
    Measurement, MeasurementContext, PlaneDistance, PointDistance, Target, informative_rows, rotation_error,
};
pub use params::{Axis, BaseParam, ParamId, ParamSet, PlaneDof, ToolFrameDof};
pub use units::{
    JointKind, JointVector, JointVectorError, MAX_JOINTS, MECA500_ON_GUIDE_KINDS, deg_to_rad, rad_to_deg,
};

/// Number of joints of the canonical Meca500-on-guide cell (cell file version 1): the linear
/// guide (joint 1, prismatic) and the six Meca500 joints (2..7, revolute). Other chains have
/// 1..=[`MAX_JOINTS`] joints (`vatcal_kinematics::Model::joint_count`).
pub const JOINT_COUNT: usize = 7;
