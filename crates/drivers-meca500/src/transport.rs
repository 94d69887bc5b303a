//! The byte transport under the driver: anything that can send bytes and receive bytes with a
//! timeout. [`std::net::TcpStream`] implements it (the robot is a TCP server); tests can plug in
//! an in-memory implementation.

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
