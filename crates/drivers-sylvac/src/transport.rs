//! The byte transport under the driver: anything that can send bytes and receive bytes with a
//! timeout. [`std::net::TcpStream`] implements it (a serial-to-TCP bridge, and the simulator);
//! with the `serial` feature (on by default), the shared `SerialTransport` of
//! `vatcal_hardware_traits::transport` opens the duplex cable with [`SERIAL_SETTINGS`]
//! (4800 baud, 7 data bits, even parity, 2 stop bits).

#[cfg(feature = "serial")]
pub use vatcal_hardware_traits::transport::{SerialSettings, SerialTransport};
pub use vatcal_hardware_traits::transport::{Transport, is_timeout};

/// The OPTO-RS duplex cable settings: 4800 baud, 7 data bits, even parity, 2 stop bits, no
/// flow control.
#[cfg(feature = "serial")]
pub const SERIAL_SETTINGS: SerialSettings = SerialSettings {
    baud: 4800,
    data_bits: serialport::DataBits::Seven,
    parity: serialport::Parity::Even,
    stop_bits: serialport::StopBits::Two,
    flow_control: serialport::FlowControl::None,
};
#[cfg(feature = "serial")]
use vatcal_hardware_traits::transport::serialport;
