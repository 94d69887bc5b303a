//! The byte transport under every driver, and a deadline helper.
//!
//! Drivers are generic over a [`Transport`]: anything that sends bytes and receives bytes with
//! a timeout. [`std::net::TcpStream`] implements it (the Meca500 is a TCP server, Zaber Ethernet
//! devices serve ASCII on TCP, serial-to-TCP bridges, and every protocol simulator); drivers add
//! serial ports behind their own features, and tests can plug in in-memory implementations.

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

/// Smallest read timeout handed to the OS (a zero timeout means "block forever" for sockets).
pub const MIN_READ_TIMEOUT: Duration = Duration::from_millis(1);

/// A bidirectional byte stream with timed reads.
pub trait Transport: Send {
    /// Writes all bytes.
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// Reads whatever is available into `buf`, waiting at most `timeout`.
    ///
    /// Returns `Ok(n > 0)` for data, `Ok(0)` when the peer closed the stream, and an error of
    /// kind [`io::ErrorKind::TimedOut`] or [`io::ErrorKind::WouldBlock`] when nothing arrived in
    /// time (see [`is_timeout`]).
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

/// Connects to the first address of `addr` that accepts within `timeout` each, with Nagle's
/// algorithm off (commands are short lines that must go out at once).
pub fn connect_tcp(addr: impl ToSocketAddrs, timeout: Duration) -> io::Result<TcpStream> {
    let mut last = None;
    for a in addr.to_socket_addrs()? {
        match TcpStream::connect_timeout(&a, timeout) {
            Ok(stream) => {
                stream.set_nodelay(true)?;
                return Ok(stream);
            }
            Err(e) => last = Some(e),
        }
    }
    Err(last.unwrap_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "no address to connect to")))
}

/// A point in time by which an operation must finish, remembering the timeout it came from
/// (for error messages).
#[derive(Debug, Clone, Copy)]
pub struct Deadline {
    at: Instant,
    timeout: Duration,
}

impl Deadline {
    /// A deadline `timeout` from now.
    pub fn new(timeout: Duration) -> Self {
        Self { at: Instant::now() + timeout, timeout }
    }

    /// Time left, or `None` once the deadline has passed.
    pub fn remaining(&self) -> Option<Duration> {
        self.at.checked_duration_since(Instant::now()).filter(|d| !d.is_zero())
    }

    /// The timeout this deadline was made from.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deadline_expires() {
        let d = Deadline::new(Duration::from_millis(5));
        assert!(d.remaining().is_some());
        std::thread::sleep(Duration::from_millis(10));
        assert!(d.remaining().is_none());
        assert_eq!(d.timeout(), Duration::from_millis(5));
    }
}
