#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! A [`RobotArm`](vatcal_hardware_traits::RobotArm) driver for the Mecademic Meca500 over its
//! TCP text API (control port 10000), and a protocol simulator of the robot for tests and dry
//! runs. Reference: `docs/drivers.md` and the project's protocol notes (protocols.md §1).
//!
//! ## Layers
//! * [`codec`] — sans-IO: [`Command`] → NUL-terminated bytes, bytes → [`Reply`]
//!   (`[code][payload]`), the `[2007]` [`StatusWord`], the `[3000]` [`Banner`] and a
//!   [`Deframer`] for the byte stream. Pure functions, shared with the simulator.
//! * [`transport`] — [`Transport`]: send bytes, receive with a timeout
//!   ([`std::net::TcpStream`] implements it).
//! * [`driver`] — [`Meca500`]: the blocking driver; [`Meca500Config`] holds the timeouts.
//! * [`sim`] — [`sim::Meca500Sim`]: a fake robot on `127.0.0.1:0`.
//!
//! ## How the trait maps onto the protocol
//! | `RobotArm` | wire |
//! |---|---|
//! | `activate_and_home` | `GetStatusRobot`; `ActivateRobot` → `[2000]`; `Home` → `[2002]`; `ResumeMotion` if paused; `SetTrf(0,…)` |
//! | `status` | `GetStatusRobot` → `[2007][as,hs,sm,es,pm,eob,eom]`, `moving = !eob` |
//! | `joints` | `GetRtTargetJointPos` → `[2200][t,θ1..θ6]` (degrees → rad); configurable |
//! | `move_joints` | `SetJointVel(100·f)`, `MoveJoints(θ…)`, `SyncCmdQueue(n)` → `[2097][n]` |
//! | `move_linear_relative` | `SetCartLinVel(f·vmax)`, `MoveLinRelWrf`/`MoveLinRelTrf(x,y,z,0,0,0)`, `SyncCmdQueue` |
//! | `wait_idle` | `SetCheckpoint(k)` → `[3030][k]`, then `GetStatusRobot` until eob = 1 |
//! | `stop` | `ClearMotion` → `[2044]`, `ResumeMotion` → `[2043]` |
//! | `reset_error` | `ResetError` → `[2005]`/`[2006]`, `ResumeMotion` |
//!
//! Units: the trait speaks rad and mm; degrees exist only on the wire. Errors: robot codes
//! become [`ErrorKind::DeviceFault`](vatcal_hardware_traits::ErrorKind::DeviceFault) with the
//! code (`[1007]` joint limit, `[3005]` motion error, …), except `[1005]`/`[1006]` →
//! `NotHomed` and `[1000]`/`[3001]` → `Busy`; silence past the timeout → `Timeout`; a closed
//! socket → `Disconnected`.
//!
//! ## Simulator
//! ```no_run
//! use vatcal_drivers_meca500::{Meca500, Meca500Config, sim::{Meca500Sim, SimConfig}};
//! use vatcal_hardware_traits::{ArmJoints, MotionOptions, RobotArm};
//! use std::time::Duration;
//!
//! let sim = Meca500Sim::start(SimConfig::fast(20.0))?;
//! let mut robot = Meca500::connect_tcp(sim.control_addr(), Meca500Config::default())?;
//! robot.activate_and_home(Duration::from_secs(5))?;
//! robot.move_joints_and_wait(&ArmJoints::from_deg_array([10.0, 0.0, 0.0, 0.0, 30.0, 0.0]), &MotionOptions::default())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod codec;
pub mod driver;
pub mod error;
pub mod sim;
pub mod transport;

pub use codec::{Banner, Command, Deframer, Reply, StatusWord};
pub use driver::{CONTROL_PORT, JointReadback, MONITORING_PORT, Meca500, Meca500Config};
pub use error::Meca500Error;
pub use transport::Transport;
