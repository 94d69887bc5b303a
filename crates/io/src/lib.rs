#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Reading and writing the CSV files of `docs/formats.md`:
//!
//! | file | columns | reader | writer |
//! |---|---|---|---|
//! | joint rows | `tcp,q1..qN` | [`read_joint_rows`] | [`write_joint_rows_for`] |
//! | probe measurements | `position,tcp,q1..qN` (+ `time_s`, `temperature_c`, `dir{i}`, `offset_x_mm,offset_y_mm,offset_z_mm`) | [`read_probe_measurements`] | [`write_measurements_for`] |
//! | tracker measurements | `tcp,q1..qN,x,y,z` | [`read_tracker_measurements`] | [`write_measurements_for`] |
//! | candidate poses | `position,tcp,q1..qN` | [`read_candidates`] | [`CandidateTable::write_subset`] |
//! | pose requests | `tcp`, the given joints' `q{i}` (`q1` on the canonical cell, none on a six-joint arm), `x,y,z,alpha,beta,gamma` (+ `time_s`, `temperature_c`, `dir{i}`) | [`read_pose_requests`] | (`vatcal compensate`) |
//!
//! Rules: a header line, columns found by name in any order, unknown columns ignored, `#`
//! comment lines and blank lines skipped (a `# vatcal-noise:` metadata line is read by
//! [`metadata::read_metadata`], written by [`write_measurements_with_noise`]). An N-joint model reads and writes the joint columns
//! `q1..qN`, in mm for prismatic and degrees for revolute joints (the canonical cell: `q1` in
//! mm, `q2..q7` in degrees), and the context columns `dir{i}` of its revolute joints i
//! (`dir2..dir7` on the canonical cell). A file whose q-columns do not match the model's joint
//! count is an error naming the file, the header line and the expected columns
//! ([`IoError::JointColumns`]). A bad row is an error naming the file, the line, the column and
//! the reason ([`IoError::Row`]); nothing is silently dropped. Numbers are written with Rust's
//! shortest round-trip formatting.

mod candidates;
mod columns;
mod error;
mod file_checks;
mod joint_rows;
mod joint_values;
mod measurements;
pub mod metadata;
mod options;
mod pose_requests;
mod pose_rows;
mod row_lines;
mod table;
mod write;

#[cfg(test)]
mod tests;

pub use candidates::{CandidateTable, read_candidates};
pub use columns::{OFFSET_COLUMNS, dir_columns, joint_columns};
pub use error::IoError;
pub use joint_rows::{JointRow, read_joint_rows, read_joint_rows_with};
pub use measurements::{
    read_measurements, read_measurements_with, read_probe_measurements, read_probe_measurements_with,
    read_tracker_measurements, read_tracker_measurements_with,
};
pub use options::{
    AngleUnit, DIR_DEADBAND_DEG, LengthUnit, LimitTolerance, ReadOptions, ReadOutcome, ReadWarning,
    RowSource, dirs_from_row_order,
};
pub use pose_requests::{PoseRequestRow, read_pose_requests};
pub use pose_rows::{
    QUATERNION_NORM_TOLERANCE, has_pose_header, is_pose_header, read_any_measurements_with,
    read_pose_measurements, read_pose_measurements_with,
};
pub use vatcal_core::MECA500_ON_GUIDE_KINDS;
pub use write::{
    measurements_to_csv, measurements_to_csv_for, write_joint_rows, write_joint_rows_for, write_measurements,
    write_measurements_for, write_measurements_with_noise,
};
