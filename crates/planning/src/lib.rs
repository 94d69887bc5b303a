//! # vatcal-planning
//!
//! Planning of a measurement campaign (paper Sections 2.4, 4.1, 4.2).
pub mod error;
pub mod ik;

pub use error::PlanError;
pub mod collision;
pub mod geometry;
pub mod motion;
pub mod paths;
pub mod candidates;
pub mod tour;
pub mod plan;
pub mod output;
