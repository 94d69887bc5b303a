//! The byte transport under the driver: anything that can send bytes and receive bytes with a
//! timeout. [`std::net::TcpStream`] implements it (a serial-to-TCP bridge, and the simulator);
//! with the `serial` feature, `SerialTransport` wraps a `serialport` port for the duplex
//! cable (4800 baud, 7 data bits, even parity, 2 stop bits).

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
