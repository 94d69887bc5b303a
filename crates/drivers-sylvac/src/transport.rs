//! The byte transport under the driver: anything that can send bytes and receive bytes with a
//! timeout. [`std::net::TcpStream`] implements it (a serial-to-TCP bridge, and the simulator);
//! with the `serial` feature, `SerialTransport` wraps a `serialport` port for the duplex
//! cable (4800 baud, 7 data bits, even parity, 2 stop bits).

#[cfg(feature = "serial")]
use std::io::{self, Read, Write};
#[cfg(feature = "serial")]
use std::time::Duration;
#[cfg(feature = "serial")]
use vatcal_hardware_traits::transport::MIN_READ_TIMEOUT;

pub use vatcal_hardware_traits::transport::{Transport, is_timeout};

/// A Sylvac duplex cable (RS-232 or USB) as a [`Transport`].
#[cfg(feature = "serial")]
#[derive(Debug)]
pub struct SerialTransport(pub Box<dyn serialport::SerialPort>);

#[cfg(feature = "serial")]
impl SerialTransport {
    /// Opens `path` with the OPTO-RS settings: 4800 baud, 7 data bits, even parity, 2 stop
    /// bits, no flow control.
    pub fn open(path: &str) -> Result<Self, serialport::Error> {
        let port = serialport::new(path, 4800)
            .data_bits(serialport::DataBits::Seven)
            .parity(serialport::Parity::Even)
            .stop_bits(serialport::StopBits::Two)
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
