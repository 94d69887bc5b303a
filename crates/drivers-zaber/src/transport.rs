//! The byte transport under the driver: anything that can send bytes and receive bytes with a
//! timeout. [`std::net::TcpStream`] implements it (Zaber Ethernet devices serve raw ASCII on
//! TCP port 55550/55551); with the `serial` feature (on by default), the shared
//! `SerialTransport` of `vatcal_hardware_traits::transport` opens an RS-232 daisy chain or a
//! USB-serial adapter with [`serial_settings`] (115200 8N1 by default on the device).

#[cfg(feature = "serial")]
pub use vatcal_hardware_traits::transport::{SerialSettings, SerialTransport};
pub use vatcal_hardware_traits::transport::{Transport, is_timeout};

/// Baud rate of Zaber ASCII devices out of the factory.
pub const DEFAULT_BAUD: u32 = 115_200;

/// Zaber ASCII line settings: `baud` 8N1, no flow control.
#[cfg(feature = "serial")]
pub fn serial_settings(baud: u32) -> SerialSettings {
    SerialSettings::eight_n_one(baud)
}
