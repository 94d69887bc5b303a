//! The byte transport under every driver, and a deadline helper.
//!
//! Drivers are generic over a [`Transport`]: anything that sends bytes and receives bytes with
//! a timeout. [`std::net::TcpStream`] implements it (the Meca500 is a TCP server, Zaber Ethernet
//! devices serve ASCII on TCP, serial-to-TCP bridges, and every protocol simulator); with the
//! `serial` feature, [`SerialTransport`] wraps a `serialport` port (RS-232, USB-serial, and
//! pseudo-terminals in tests); tests can plug in in-memory implementations.
//!
//! Every driver's byte stream is cut into messages by the one [`LineDeframer`] here, configured
//! per protocol ([`Framing`]: NUL for the Meca500, CR/LF for Zaber and Sylvac).

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use crate::error::{Error, ErrorKind};

/// Smallest read timeout handed to the OS (a zero timeout means "block forever" for sockets).
pub const MIN_READ_TIMEOUT: Duration = Duration::from_millis(1);

/// A bidirectional byte stream with timed reads.
pub trait Transport: Send {
    /// Writes all bytes.
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// Reads whatever is available into `buf`, waiting at most `timeout`; a zero `timeout`
    /// asks only for what has already arrived (drivers drain stale input this way).
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
        if timeout.is_zero() {
            // what has already arrived, without waiting: a socket read timeout is rounded up to
            // the kernel's timer tick (4-10 ms), which a drain before every request paid in full
            self.set_nonblocking(true)?;
            let read = self.read(buf);
            self.set_nonblocking(false)?;
            return read;
        }
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

/// An in-memory [`Transport`] for tests: [`recv`](Transport::recv) hands out scripted chunks
/// in order, then either reports the peer closed (`Ok(0)`) or stays silent (waits the whole
/// timeout, then [`io::ErrorKind::TimedOut`]); [`send`](Transport::send) records the bytes.
#[derive(Debug, Clone, Default)]
pub struct ScriptedTransport {
    incoming: std::collections::VecDeque<Vec<u8>>,
    sent: Vec<u8>,
    silent_at_end: bool,
}

impl ScriptedTransport {
    /// A transport that delivers `chunks` (one per `recv`; empty chunks are dropped, since an
    /// empty read means "closed"), then reports the peer closed.
    pub fn new<I, C>(chunks: I) -> Self
    where
        I: IntoIterator<Item = C>,
        C: Into<Vec<u8>>,
    {
        let incoming = chunks.into_iter().map(Into::into).filter(|c: &Vec<u8>| !c.is_empty()).collect();
        Self { incoming, ..Self::default() }
    }

    /// After the script, stay silent (time out) instead of reporting the peer closed.
    pub fn silent_at_end(mut self) -> Self {
        self.silent_at_end = true;
        self
    }

    /// Everything sent so far.
    pub fn sent(&self) -> &[u8] {
        &self.sent
    }
}

impl Transport for ScriptedTransport {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.sent.extend_from_slice(bytes);
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        match self.incoming.pop_front() {
            Some(mut chunk) => {
                let n = chunk.len().min(buf.len());
                buf[..n].copy_from_slice(&chunk[..n]);
                if n < chunk.len() {
                    self.incoming.push_front(chunk.split_off(n));
                }
                Ok(n)
            }
            None if self.silent_at_end => {
                std::thread::sleep(timeout);
                Err(io::Error::new(io::ErrorKind::TimedOut, "scripted silence"))
            }
            None => Ok(0),
        }
    }
}

/// True for the error kinds [`Transport::recv`] uses to say "nothing arrived in time".
pub fn is_timeout(e: &io::Error) -> bool {
    matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock)
}

/// True for the error kinds that mean the link is gone (reset, aborted, broken pipe, not
/// connected, unexpected end of file): drivers report these like a closed stream.
pub fn is_disconnect(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::ConnectionReset
            | io::ErrorKind::ConnectionAborted
            | io::ErrorKind::NotConnected
            | io::ErrorKind::BrokenPipe
            | io::ErrorKind::UnexpectedEof
    )
}

/// What can go wrong on the link itself, the same for every driver. Each driver's error type
/// wraps it (`Meca500Error::Link`, `ZaberError::Link`, `SylvacError::Link`), so the three
/// link failures are written, displayed and mapped to an [`ErrorKind`] in one place.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LinkError {
    /// An OS I/O error that is neither a timeout nor a gone link.
    #[error("I/O error: {0}")]
    Io(#[from] io::Error),
    /// The connection is gone (closed or reset by the device or the network, port hung up).
    #[error("connection closed while {during}")]
    Disconnected {
        /// what the driver was doing (`sending MoveJoints`, `waiting for the answer to '?'`)
        during: String,
    },
    /// No answer in time.
    #[error("no {waiting_for} within {:.3} s", after.as_secs_f64())]
    Timeout {
        /// what the driver was waiting for
        waiting_for: String,
        /// the timeout that expired
        after: Duration,
    },
}

impl LinkError {
    /// The portable kind: [`ErrorKind::Disconnected`], [`ErrorKind::Timeout`], or the kind of
    /// the I/O error ([`ErrorKind::of_io`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            LinkError::Io(e) => ErrorKind::of_io(e),
            LinkError::Disconnected { .. } => ErrorKind::Disconnected,
            LinkError::Timeout { .. } => ErrorKind::Timeout,
        }
    }

    /// Converts into the trait-level error of device `device`, keeping `self` (or the I/O
    /// error) as source.
    pub fn into_hw(self, device: &str) -> Error {
        match self {
            LinkError::Io(e) => Error::from_io(device, e),
            other => Error::new(other.kind(), device, other.to_string()).with_source(other),
        }
    }

    /// A failed [`Transport::send`]: a gone link ([`is_disconnect`]) is
    /// [`LinkError::Disconnected`] with `during()`, anything else [`LinkError::Io`].
    pub fn from_send(e: io::Error, during: impl FnOnce() -> String) -> Self {
        if is_disconnect(&e) { LinkError::Disconnected { during: during() } } else { LinkError::Io(e) }
    }
}

/// One timed read for a driver's receive loop: `Ok(Some(n))` when `n > 0` bytes arrived,
/// `Ok(None)` when nothing arrived within `timeout` or the read was interrupted (the caller
/// checks its [`Deadline`] and reads again), [`LinkError::Disconnected`] with `during()` when
/// the peer closed the stream or the link is gone, [`LinkError::Io`] for any other error.
///
/// # Errors
/// [`LinkError::Disconnected`] or [`LinkError::Io`] as above.
pub fn recv_some<T: Transport + ?Sized>(
    transport: &mut T,
    buf: &mut [u8],
    timeout: Duration,
    during: impl FnOnce() -> String,
) -> Result<Option<usize>, LinkError> {
    match transport.recv(buf, timeout) {
        Ok(0) => Err(LinkError::Disconnected { during: during() }),
        Ok(n) => Ok(Some(n)),
        Err(e) if is_timeout(&e) || e.kind() == io::ErrorKind::Interrupted => Ok(None),
        Err(e) if is_disconnect(&e) => Err(LinkError::Disconnected { during: during() }),
        Err(e) => Err(LinkError::Io(e)),
    }
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

// ---------------------------------------------------------------------------------------------
// Framing
// ---------------------------------------------------------------------------------------------

/// A framing problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// More than `max` bytes arrived without a terminator; the message was discarded (the bytes
    /// up to the next terminator are dropped too, so the stream resynchronises on it).
    #[error("message longer than {max} bytes without terminator")]
    TooLong {
        /// the limit
        max: usize,
    },
}

/// How a [`LineDeframer`] cuts a byte stream into messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Framing {
    /// bytes that end a message (e.g. `b"\0"`, `b"\r\n"` = CR **or** LF)
    pub terminators: &'static [u8],
    /// also remove one CR right before the terminator (for LF-terminated lines sent as CRLF
    /// when CR is not itself a terminator)
    pub strip_cr: bool,
    /// skip messages that are empty or only ASCII whitespace (CRLF then yields one line)
    pub skip_blank: bool,
    /// longest message accepted, terminator excluded
    pub max_len: usize,
}

impl Framing {
    /// Lines ended by CR, LF or CRLF, blank lines skipped, at most `max_len` bytes.
    pub const fn cr_or_lf(max_len: usize) -> Self {
        Self { terminators: b"\r\n", strip_cr: false, skip_blank: true, max_len }
    }

    /// NUL-terminated messages (empty ones kept), at most `max_len` bytes.
    pub const fn nul(max_len: usize) -> Self {
        Self { terminators: b"\0", strip_cr: false, skip_blank: false, max_len }
    }

    /// NUL- or LF-terminated messages (a CR before the LF is removed), empty ones kept.
    pub const fn nul_or_lf(max_len: usize) -> Self {
        Self { terminators: b"\0\n", strip_cr: true, skip_blank: false, max_len }
    }
}

/// Cuts a byte stream into messages. TCP and serial links may split or coalesce messages:
/// [`push`](Self::push) whatever arrived, then pop complete messages with
/// [`next_frame`](Self::next_frame) / [`next_line`](Self::next_line); the unterminated tail
/// is kept for the next push. A message longer than [`Framing::max_len`] is reported once as
/// [`FrameError::TooLong`] and dropped up to its terminator, after which deframing goes on
/// normally.
#[derive(Debug, Clone)]
pub struct LineDeframer {
    framing: Framing,
    buffer: Vec<u8>,
    /// inside an overlong message already reported: drop bytes up to the next terminator
    discarding: bool,
}

impl LineDeframer {
    /// An empty deframer for `framing`.
    pub fn new(framing: Framing) -> Self {
        Self { framing, buffer: Vec::new(), discarding: false }
    }

    /// The framing this deframer applies.
    pub fn framing(&self) -> &Framing {
        &self.framing
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buffer.extend_from_slice(bytes);
    }

    /// Drops everything buffered (and any overlong message being skipped).
    pub fn clear(&mut self) {
        self.buffer.clear();
        self.discarding = false;
    }

    /// Bytes waiting for a terminator.
    pub fn pending(&self) -> usize {
        self.buffer.len()
    }

    /// The next complete message (terminator removed), `Ok(None)` when more bytes are needed,
    /// or [`FrameError::TooLong`] for an overlong message (reported once, then skipped).
    pub fn next_frame(&mut self) -> Result<Option<Vec<u8>>, FrameError> {
        let Framing { terminators, strip_cr, skip_blank, max_len } = self.framing;
        loop {
            match self.buffer.iter().position(|b| terminators.contains(b)) {
                Some(end) => {
                    let mut frame: Vec<u8> = self.buffer.drain(..=end).collect();
                    frame.pop();
                    if std::mem::take(&mut self.discarding) {
                        continue; // the tail of an overlong message already reported
                    }
                    if strip_cr && frame.last() == Some(&b'\r') {
                        frame.pop();
                    }
                    if frame.len() > max_len {
                        return Err(FrameError::TooLong { max: max_len });
                    }
                    if skip_blank && frame.iter().all(u8::is_ascii_whitespace) {
                        continue;
                    }
                    return Ok(Some(frame));
                }
                None if self.discarding => {
                    self.buffer.clear();
                    return Ok(None);
                }
                // (one byte of slack for a CR that `strip_cr` may still remove)
                None if self.buffer.len() > max_len + usize::from(strip_cr) => {
                    self.buffer.clear();
                    self.discarding = true;
                    return Err(FrameError::TooLong { max: max_len });
                }
                None => return Ok(None),
            }
        }
    }

    /// [`next_frame`](Self::next_frame) decoded as text (invalid UTF-8 replaced by U+FFFD).
    pub fn next_line(&mut self) -> Result<Option<String>, FrameError> {
        Ok(self.next_frame()?.map(|f| String::from_utf8_lossy(&f).into_owned()))
    }
}

// ---------------------------------------------------------------------------------------------
// Serial ports
// ---------------------------------------------------------------------------------------------

/// The `serialport` crate (built without default features: no libudev), for callers that
/// build ports themselves (e.g. `serialport::TTYPort::pair()` in tests).
#[cfg(feature = "serial")]
pub use serialport;

/// Line settings of a serial port.
#[cfg(feature = "serial")]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialSettings {
    /// baud rate
    pub baud: u32,
    /// data bits
    pub data_bits: serialport::DataBits,
    /// parity
    pub parity: serialport::Parity,
    /// stop bits
    pub stop_bits: serialport::StopBits,
    /// flow control
    pub flow_control: serialport::FlowControl,
}

#[cfg(feature = "serial")]
impl SerialSettings {
    /// `baud` 8N1, no flow control.
    pub const fn eight_n_one(baud: u32) -> Self {
        Self {
            baud,
            data_bits: serialport::DataBits::Eight,
            parity: serialport::Parity::None,
            stop_bits: serialport::StopBits::One,
            flow_control: serialport::FlowControl::None,
        }
    }
}

/// A serial port (RS-232, USB-serial, a pseudo-terminal) as a [`Transport`]. A hang-up of
/// the other side is reported like a closed socket (`recv` returns `Ok(0)`).
#[cfg(feature = "serial")]
pub struct SerialTransport {
    port: Box<dyn serialport::SerialPort>,
    name: String,
}

#[cfg(feature = "serial")]
impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport").field("name", &self.name).finish_non_exhaustive()
    }
}

#[cfg(feature = "serial")]
impl SerialTransport {
    /// Opens `path` with `settings`.
    pub fn open(path: &str, settings: &SerialSettings) -> io::Result<Self> {
        let port = serialport::new(path, settings.baud)
            .data_bits(settings.data_bits)
            .parity(settings.parity)
            .stop_bits(settings.stop_bits)
            .flow_control(settings.flow_control)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|e| {
                let kind = match e.kind() {
                    serialport::ErrorKind::NoDevice => io::ErrorKind::NotFound,
                    serialport::ErrorKind::InvalidInput => io::ErrorKind::InvalidInput,
                    serialport::ErrorKind::Io(kind) => kind,
                    _ => io::ErrorKind::Other,
                };
                io::Error::new(kind, format!("{path}: {e}"))
            })?;
        Ok(Self { port, name: path.to_owned() })
    }

    /// Wraps a port opened elsewhere (e.g. one end of `serialport::TTYPort::pair()`).
    pub fn from_port(port: Box<dyn serialport::SerialPort>) -> Self {
        let name = port.name().unwrap_or_else(|| "serial port".to_owned());
        Self { port, name }
    }

    /// The port's path (or `"serial port"` if unknown), for error messages.
    pub fn name(&self) -> &str {
        &self.name
    }
}

#[cfg(feature = "serial")]
impl Transport for SerialTransport {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.port.set_timeout(timeout.max(MIN_READ_TIMEOUT)).map_err(io::Error::from)?;
        match self.port.read(buf) {
            // a hang-up (pty master closed, adapter unplugged): the peer is gone, like EOF
            Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(0),
            other => other,
        }
    }
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

/// A [`LineDeframer`] for line protocols ended by CR, LF or CRLF with lines of at most
/// `MAX_LEN` bytes ([`Framing::cr_or_lf`]): the Zaber ASCII and Sylvac protocols each name
/// theirs as a type alias. Every method of [`LineDeframer`] is available through `Deref`.
#[derive(Debug, Clone)]
pub struct CrOrLfDeframer<const MAX_LEN: usize>(LineDeframer);

impl<const MAX_LEN: usize> CrOrLfDeframer<MAX_LEN> {
    /// An empty deframer.
    pub fn new() -> Self {
        Self(LineDeframer::new(Framing::cr_or_lf(MAX_LEN)))
    }
}

impl<const MAX_LEN: usize> Default for CrOrLfDeframer<MAX_LEN> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const MAX_LEN: usize> std::ops::Deref for CrOrLfDeframer<MAX_LEN> {
    type Target = LineDeframer;

    fn deref(&self) -> &LineDeframer {
        &self.0
    }
}

impl<const MAX_LEN: usize> std::ops::DerefMut for CrOrLfDeframer<MAX_LEN> {
    fn deref_mut(&mut self) -> &mut LineDeframer {
        &mut self.0
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn all_frames(d: &mut LineDeframer) -> Vec<Result<Vec<u8>, FrameError>> {
        let mut out = Vec::new();
        loop {
            match d.next_frame() {
                Ok(None) => return out,
                Ok(Some(f)) => out.push(Ok(f)),
                Err(e) => out.push(Err(e)),
            }
        }
    }

    #[test]
    fn a_zero_timeout_on_tcp_reads_what_has_arrived_and_leaves_the_socket_blocking() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        let mut client =
            connect_tcp(listener.local_addr().expect("addr"), Duration::from_secs(2)).expect("connect");
        let (mut server, _) = listener.accept().expect("accept");
        let mut buf = [0u8; 8];
        let e = client.recv(&mut buf, Duration::ZERO).expect_err("nothing sent yet");
        assert!(is_timeout(&e), "{e}");
        server.write_all(b"abc").expect("send");
        // one byte by a timed read: the rest has arrived by then
        assert_eq!(client.recv(&mut buf[..1], Duration::from_secs(2)).expect("first byte"), 1);
        assert_eq!(client.recv(&mut buf[1..], Duration::ZERO).expect("arrived bytes"), 2);
        assert_eq!(&buf[..3], b"abc");
        let e = client.recv(&mut buf, Duration::ZERO).expect_err("drained");
        assert!(is_timeout(&e), "{e}");
        // a timed read afterwards still waits for its timeout (the socket is blocking again)
        let t0 = Instant::now();
        let e = client.recv(&mut buf, Duration::from_millis(50)).expect_err("silence");
        assert!(is_timeout(&e), "{e}");
        assert!(t0.elapsed() >= Duration::from_millis(45), "returned after {:?}", t0.elapsed());
    }

    #[test]
    fn recv_some_sorts_data_silence_and_a_closed_link() {
        let mut t = ScriptedTransport::new([b"abc".to_vec()]).silent_at_end();
        let mut buf = [0u8; 8];
        let during = || "waiting for the reply".to_owned();
        assert_eq!(recv_some(&mut t, &mut buf, Duration::from_millis(1), during).ok(), Some(Some(3)));
        assert_eq!(recv_some(&mut t, &mut buf, Duration::from_millis(1), during).ok(), Some(None));
        let mut closed = ScriptedTransport::new(Vec::<Vec<u8>>::new());
        let Err(e) = recv_some(&mut closed, &mut buf, Duration::from_millis(1), during) else {
            panic!("a closed stream must be an error")
        };
        assert_eq!(e.kind(), ErrorKind::Disconnected);
        assert_eq!(e.to_string(), "connection closed while waiting for the reply");
        let hw = e.into_hw("gauge 1");
        assert_eq!((hw.kind(), hw.device()), (ErrorKind::Disconnected, "gauge 1"));
    }

    #[test]
    fn send_errors_split_into_gone_links_and_other_io_errors() {
        let gone = LinkError::from_send(io::Error::from(io::ErrorKind::BrokenPipe), || "sending '?'".into());
        assert_eq!(gone.to_string(), "connection closed while sending '?'");
        let other = LinkError::from_send(io::Error::from(io::ErrorKind::PermissionDenied), || unreachable!());
        assert_eq!(other.kind(), ErrorKind::Io);
        let late = LinkError::Timeout { waiting_for: "IDLE".into(), after: Duration::from_millis(1500) };
        assert_eq!(
            (late.kind(), late.to_string()),
            (ErrorKind::Timeout, "no IDLE within 1.500 s".to_owned())
        );
    }

    #[test]
    fn cr_lf_lines_skip_blanks_and_keep_partial_tails() {
        let mut d = LineDeframer::new(Framing::cr_or_lf(16));
        d.push(b"@01 1 OK\r\n\r\n  \r#01");
        assert_eq!(d.next_line(), Ok(Some("@01 1 OK".to_owned())));
        assert_eq!(d.next_line(), Ok(None));
        assert_eq!(d.pending(), 3);
        d.push(b" 1 x\n");
        assert_eq!(d.next_line(), Ok(Some("#01 1 x".to_owned())));
    }

    #[test]
    fn nul_frames_keep_empty_ones_and_nul_or_lf_strips_cr() {
        let mut d = LineDeframer::new(Framing::nul(16));
        d.push(b"[2007][1]\0\0a\n");
        assert_eq!(all_frames(&mut d), vec![Ok(b"[2007][1]".to_vec()), Ok(Vec::new())]);
        assert_eq!(d.pending(), 2);
        let mut d = LineDeframer::new(Framing::nul_or_lf(16));
        d.push(b"Home\r\nPause\0");
        assert_eq!(all_frames(&mut d), vec![Ok(b"Home".to_vec()), Ok(b"Pause".to_vec())]);
    }

    #[test]
    fn overlong_message_is_reported_once_and_the_stream_resynchronises() {
        let mut d = LineDeframer::new(Framing::cr_or_lf(8));
        d.push(b"0123456789");
        assert_eq!(d.next_line(), Err(FrameError::TooLong { max: 8 }));
        d.push(b"abcdef\rok\r");
        assert_eq!(d.next_line(), Ok(Some("ok".to_owned())));
        // terminated but too long in one push
        d.push(b"0123456789\rok2\r");
        assert_eq!(d.next_line(), Err(FrameError::TooLong { max: 8 }));
        assert_eq!(d.next_line(), Ok(Some("ok2".to_owned())));
        assert_eq!(
            FrameError::TooLong { max: 8 }.to_string(),
            "message longer than 8 bytes without terminator"
        );
    }

    proptest! {
        /// Any chunking of any byte stream gives the same messages as one push, no message
        /// holds a terminator or exceeds the limit, and nothing panics.
        #[test]
        fn chunking_does_not_change_the_messages(
            bytes in proptest::collection::vec(prop_oneof![Just(b'\r'), Just(b'\n'), Just(0u8), Just(b' '), any::<u8>()], 0..400),
            cuts in proptest::collection::vec(0usize..400, 0..20),
            which in 0usize..3,
        ) {
            let framing = [Framing::cr_or_lf(24), Framing::nul(24), Framing::nul_or_lf(24)][which];
            let mut whole = LineDeframer::new(framing);
            whole.push(&bytes);
            let expected = all_frames(&mut whole);
            let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c.min(bytes.len())).collect();
            cuts.sort_unstable();
            let mut d = LineDeframer::new(framing);
            let mut got = Vec::new();
            let mut start = 0;
            for c in cuts.into_iter().chain(std::iter::once(bytes.len())) {
                d.push(&bytes[start..c]);
                start = c;
                got.extend(all_frames(&mut d));
            }
            // an overlong unterminated tail is reported as soon as it is seen, so only compare
            // the successful messages and that errors occur in both or neither
            let ok = |v: &[Result<Vec<u8>, FrameError>]| v.iter().filter_map(|r| r.clone().ok()).collect::<Vec<_>>();
            prop_assert_eq!(ok(&got), ok(&expected));
            prop_assert_eq!(got.iter().any(Result::is_err), expected.iter().any(Result::is_err));
            for f in ok(&got) {
                prop_assert!(f.len() <= framing.max_len);
                prop_assert!(!f.iter().any(|b| framing.terminators.contains(b)));
            }
        }

        /// Messages without terminators inside come back unchanged.
        #[test]
        fn round_trip(lines in proptest::collection::vec("[!-~][ -~]{0,20}", 0..10)) {
            let mut d = LineDeframer::new(Framing::cr_or_lf(64));
            for l in &lines {
                d.push(l.as_bytes());
                d.push(b"\r\n");
            }
            let got: Vec<String> = std::iter::from_fn(|| d.next_line().ok().flatten()).collect();
            prop_assert_eq!(got, lines);
        }
    }

    #[test]
    fn deadline_expires() {
        let d = Deadline::new(Duration::from_millis(5));
        assert!(d.remaining().is_some());
        std::thread::sleep(Duration::from_millis(10));
        assert!(d.remaining().is_none());
        assert_eq!(d.timeout(), Duration::from_millis(5));
    }
}
