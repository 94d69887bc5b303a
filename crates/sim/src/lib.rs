#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! The virtual cell. [`truth`] builds a hidden "true" cell (nominal model + realistic random
//! errors + any catalog effects) and synthesises measurements from it: probe measurements
//! (the true TCP put on a calibration position, with the paper's noise budget) and tracker
//! measurements at random poses. Every random process takes a seed (ChaCha8).
//!
//! [`VirtualCell`] simulates the devices of the cell on that truth, implementing the traits of
//! `vatcal-hardware-traits`: a robot arm whose controller believes the nominal model
//! ([`SimArm`]: relative linear moves are solved on the nominal geometry, the physics is the
//! truth), the guide ([`SimGuide`]), the three TriCal gauges with slightly tilted true axes
//! ([`SimGauge`]), a laser tracker ([`SimTracker`]), a thermometer when the cell has a
//! temperature channel ([`SimThermometer`]) and an operator ([`SimOperator`]), with the
//! paper's error budget ([`NoiseBudget`]), virtual time, and noise derived from
//! `(seed, command, state)` so that a resumed campaign sees exactly the same noise.

pub mod truth;

// --- simulated devices (virtual cell) ---
mod cell;
mod config;
mod controller;
mod devices;
pub mod external;
mod noise;
mod world;

pub use cell::VirtualCell;
pub use config::{
    CellPhysics, NoiseBudget, ProbeImperfections, SimConfig, SimFaults, SimTiming, ThermalProfile,
    ThermometerSpec,
};
pub use controller::{flange_jacobian, translation_joint_gain};
pub use devices::{SIM_IO_TIMEOUT, SimArm, SimGauge, SimGuide, SimOperator, SimThermometer, SimTracker};
