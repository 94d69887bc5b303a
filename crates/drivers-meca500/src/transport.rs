//! The byte transport under the driver: anything that can send bytes and receive bytes with a
//! timeout. [`std::net::TcpStream`] implements it (the robot is a TCP server); tests can plug in
//! an in-memory implementation.

pub use vatcal_hardware_traits::transport::{Transport, is_timeout};
