#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! The geometric model of a serial chain of 1..=12 joints (paper Section 3, generalised) with
//! joint compliance and a catalog of further error effects, in internal units (mm, rad):
//!
//! * MDH rows exactly as Eq. (1): `H_i^{i-1} = Rx(alpha_{i-1}) Tx(a_{i-1}) Ry(beta_{i-1})
//!   Rz(theta_i) Tz(d_i)`, beta accepted on every row;
//! * each joint prismatic (`d_i = q_i + d_offset_i`) or revolute
//!   (`theta_i = q_i + theta_offset_i + c_i tau_i + effects`), in any order — on the canonical
//!   cell joint 1 is the prismatic guide and joints 2..7 the revolute Meca500 joints;
//! * base pose `H_0^W = T(x,y,z) Rx(alpha) Ry(beta) Rz(gamma)`;
//! * TCP k at `t_k` in the tool-changer frame (frame N).
//!
//! [`Model`] holds the parameters, [`Model::chain`] computes every frame, [`Model::tcp_position`]
//! the TCP, and [`Model::jacobian`] the analytic derivative of a TCP position with respect to
//! any list of [`ParamId`]s (gravity torques held fixed, as in the paper). Effects of the
//! catalog ([`vatcal_core::EffectSpec`]) are switched on with [`Model::enable_effect`]; they
//! change FK and contribute Jacobian columns through the same code path (see [`effects`]).

mod chain;
mod contact_plane;
pub mod effects;
mod jacobian;
mod model;
mod orientation;
mod plane;

pub use chain::{Chain, GravityLoads};
pub use contact_plane::ContactPlane;
pub use model::{MdhRow, Model, ModelError};
pub use vatcal_core::Frame;
/// The cell file a [`Model`] is built from ([`Model::from_cell`]), re-exported so that a user of
/// this crate needs no other.
pub use vatcal_core::{CellError, CellFile};
pub use vatcal_core::{JointVector, Measurement, MeasurementContext, ParamId, ParamSet, Target};
