//! The byte transport under the driver: anything that can send bytes and receive bytes with a
//! timeout. [`std::net::TcpStream`] implements it (Zaber Ethernet devices serve raw ASCII on
//! TCP port 55550/55551); with the `serial` feature, `SerialTransport` wraps a
//! `serialport` port (115200 8N1 by default).

#[cfg(feature = "serial")]
use std::io::{self, Read, Write};
#[cfg(feature = "serial")]
use std::time::Duration;
#[cfg(feature = "serial")]
use vatcal_hardware_traits::transport::MIN_READ_TIMEOUT;

pub use vatcal_hardware_traits::transport::{Transport, is_timeout};

/// A serial port (RS-232 daisy chain or USB-serial) as a [`Transport`].
#[cfg(feature = "serial")]
#[derive(Debug)]
pub struct SerialTransport(pub Box<dyn serialport::SerialPort>);

#[cfg(feature = "serial")]
impl SerialTransport {
    /// Opens `path` with the Zaber ASCII defaults: `baud` (115200 by default on the device),
    /// 8 data bits, no parity, 1 stop bit, no flow control.
    pub fn open(path: &str, baud: u32) -> Result<Self, serialport::Error> {
        let port = serialport::new(path, baud)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(100))
            .open()?;
        Ok(Self(port))
    }
}

#[cfg(feature = "serial")]
impl Transport for SerialTransport {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.0.write_all(bytes)?;
        self.0.flush()
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.0.set_timeout(timeout.max(MIN_READ_TIMEOUT)).map_err(io::Error::other)?;
        self.0.read(buf)
    }
}
