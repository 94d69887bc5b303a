//! The byte transport under the driver: anything that can send bytes and receive bytes with a
//! timeout. [`std::net::TcpStream`] implements it (Zaber Ethernet devices serve raw ASCII on
//! TCP port 55550/55551); with the `serial` feature, `SerialTransport` wraps a
//! `serialport` port (115200 8N1 by default).

use std::io::{self, Read, Write};
use std::net::TcpStream;
use std::time::Duration;

/// Smallest read timeout handed to the OS (a zero timeout means "block forever" for sockets).
const MIN_READ_TIMEOUT: Duration = Duration::from_millis(1);

/// A bidirectional byte stream with timed reads.
pub trait Transport: Send {
    /// Writes all bytes.
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// Reads whatever is available into `buf`, waiting at most `timeout`.
    ///
    /// Returns `Ok(n > 0)` for data, `Ok(0)` when the peer closed the stream, and an error of
    /// kind [`io::ErrorKind::TimedOut`] or [`io::ErrorKind::WouldBlock`] when nothing arrived in
    /// time.
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
}

impl Transport for TcpStream {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.write_all(bytes)?;
        self.flush()
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.set_read_timeout(Some(timeout.max(MIN_READ_TIMEOUT)))?;
        self.read(buf)
    }
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        (**self).send(bytes)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        (**self).recv(buf, timeout)
    }
}

/// True for the error kinds [`Transport::recv`] uses to say "nothing arrived in time".
pub fn is_timeout(e: &io::Error) -> bool {
    matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock)
}

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
