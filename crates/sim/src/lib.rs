//! # vatcal-sim
//!
//! The virtual cell. [`truth`] builds a hidden "true" cell (nominal model + realistic random
//! errors + any catalog effects) and synthesises measurements from it: probe measurements
//! (the true TCP put on a calibration position, with the paper's noise budget) and tracker
//! measurements at random poses. Every random process takes a seed (ChaCha8).

pub mod truth;

// --- simulated devices (virtual cell) ---
mod cell;
mod config;
pub(crate) mod controller;
mod devices;
mod noise;
mod world;

pub use cell::VirtualCell;
pub use controller::{flange_jacobian, translation_joint_gain};
pub use config::{NoiseBudget, ProbeImperfections, SimConfig, SimFaults, SimTiming};
pub use devices::{SIM_IO_TIMEOUT, SimArm, SimGauge, SimGuide, SimOperator, SimTracker};
