//! The accept/serve loop of the protocol simulators (and of `vatcal sim-cell`'s cell-control
//! port): one background thread owns some TCP listeners and their clients and feeds a
//! [`SimService`] — the protocol's state machine — with connections, received bytes and time.
//!
//! The loop is the same for every device: accept new clients, take what each client sent, hand
//! the bytes to the service, write what the service answers to the right clients, wait for the
//! next bytes (at most one [`TICK`]) when nothing arrived, repeat. Each client's socket is read
//! by a small thread of its own that passes the bytes to the loop over a channel, so the loop
//! wakes as soon as a request arrives instead of at the next tick (a simulated campaign makes
//! thousands of request/answer round trips). A [`SimServer`] handle injects the socket-level
//! faults every simulator offers: drop every client, stall (keep the connections open but
//! answer nothing), stop.

use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender};
use std::thread::JoinHandle;
use std::time::Duration;

/// Granularity of the loop: the longest wait of a turn in which no client sent anything (the
/// loop wakes as soon as bytes arrive), the sleep of a stalled turn, and how long a new
/// connection may wait to be accepted.
pub const TICK: Duration = Duration::from_millis(1);
/// A client that does not read its answers for this long is dropped.
pub const WRITE_TIMEOUT: Duration = Duration::from_millis(500);
/// Reads in flight from the clients' reader threads to the loop; a full channel holds the
/// readers back (while stalled, the bytes then wait in the kernel as they would unread).
const EVENTS_IN_FLIGHT: usize = 256;
/// Stack of a client's reader thread (a read loop with a 4 KiB buffer).
const READER_STACK: usize = 128 * 1024;

/// A connected client: its number (unique for the server's lifetime) and the index of the
/// listener it came through (the order given to [`SimServer::spawn`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ClientId {
    /// unique number
    pub id: u64,
    /// listener index
    pub listener: usize,
}

/// Who receives bytes produced by the service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Audience {
    /// one client
    Client(ClientId),
    /// every client of listener `.0`
    Listener(usize),
    /// every client
    All,
}

/// What to do with a new connection.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Admission {
    /// keep it and send these bytes first (a banner, or nothing)
    Accept(Vec<u8>),
    /// send these bytes and close it (e.g. "another user is connected")
    Refuse(Vec<u8>),
}

/// A protocol state machine served by [`SimServer`]. All calls come from the server's thread.
pub trait SimService: Send + 'static {
    /// A client connected.
    fn connect(&mut self, client: ClientId) -> Admission;
    /// `bytes` arrived from `client`; returns what to send, and to whom.
    fn input(&mut self, client: ClientId, bytes: &[u8]) -> Vec<(Audience, Vec<u8>)>;
    /// Called once per loop turn (about every [`TICK`] while clients are connected): time
    /// passed; returns what to send, and to whom.
    fn poll(&mut self) -> Vec<(Audience, Vec<u8>)> {
        Vec::new()
    }
    /// `client` is gone (closed by the peer, dropped by a fault, or a write failed).
    fn disconnected(&mut self, client: ClientId) {
        let _ = client;
    }
}

#[derive(Debug, Default)]
struct Flags {
    stop: AtomicBool,
    stalled: AtomicBool,
    drop_clients: AtomicBool,
}

/// A running server thread. Dropping it stops the thread and closes every socket.
#[derive(Debug)]
pub struct SimServer {
    addrs: Vec<SocketAddr>,
    flags: Arc<Flags>,
    thread: Option<JoinHandle<()>>,
}

impl SimServer {
    /// Binds every address of `binds` (port 0: ephemeral) and serves `service` on them from a
    /// thread named `name`.
    pub fn spawn(name: &str, binds: &[SocketAddr], service: impl SimService) -> io::Result<Self> {
        let listeners = binds
            .iter()
            .map(|a| {
                let l = TcpListener::bind(a)?;
                l.set_nonblocking(true)?;
                Ok(l)
            })
            .collect::<io::Result<Vec<_>>>()?;
        let addrs = listeners.iter().map(TcpListener::local_addr).collect::<io::Result<Vec<_>>>()?;
        let flags = Arc::new(Flags::default());
        let (events_tx, events) = mpsc::sync_channel(EVENTS_IN_FLIGHT);
        let mut server = Server {
            name: name.to_owned(),
            listeners,
            clients: Vec::new(),
            next_id: 0,
            service,
            flags: Arc::clone(&flags),
            events_tx,
            events,
        };
        let thread = std::thread::Builder::new().name(name.to_owned()).spawn(move || server.run())?;
        Ok(Self { addrs, flags, thread: Some(thread) })
    }

    /// The bound addresses, in the order of the binds.
    pub fn addrs(&self) -> &[SocketAddr] {
        &self.addrs
    }

    /// Stops (`true`) or restarts (`false`) every answer while keeping the connections open:
    /// received bytes wait, so the peer's calls time out.
    pub fn set_stalled(&self, stalled: bool) {
        self.flags.stalled.store(stalled, Ordering::SeqCst);
    }

    /// Closes every client connection (the listeners stay open).
    pub fn drop_clients(&self) {
        self.flags.drop_clients.store(true, Ordering::SeqCst);
    }
}

impl Drop for SimServer {
    fn drop(&mut self) {
        self.flags.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[derive(Debug)]
struct Client {
    id: ClientId,
    stream: TcpStream,
    /// bytes received and not yet handed to the service (all of them while stalled)
    held: Vec<u8>,
    /// the reader thread saw the end of the stream (or a read error) after `held`
    ended: bool,
    open: bool,
}

impl Client {
    /// True when the peer has closed the connection (pending input counts as open).
    fn is_closed(&self) -> bool {
        if !self.held.is_empty() {
            return false;
        }
        if self.ended {
            return true;
        }
        // its reader thread may not have run since the peer left: ask the socket (the reader
        // takes a timeout of its own read in this window as "nothing yet")
        let mut probe = [0u8; 1];
        let _ = self.stream.set_read_timeout(Some(TICK));
        let peeked = self.stream.peek(&mut probe);
        let _ = self.stream.set_read_timeout(None);
        match peeked {
            Ok(0) => true,
            Ok(_) => false,
            Err(e) => !is_transient(&e),
        }
    }
}

impl Drop for Client {
    /// Shuts the socket down (its reader thread holds a clone, so dropping alone would not
    /// close it): the peer sees the end of the stream and the reader thread ends.
    fn drop(&mut self) {
        let _ = self.stream.shutdown(Shutdown::Both);
    }
}

/// What a client's reader thread passes to the loop.
enum Event {
    /// bytes from client number `.0`
    Bytes(u64, Vec<u8>),
    /// client number `.0` closed its side or its socket failed
    Ended(u64),
}

/// The reader thread of client `id`: blocking reads, each one's bytes sent to the loop, until
/// the stream ends (the peer closed, or the loop shut the socket down) or the loop is gone.
fn read_client(mut stream: TcpStream, id: u64, events: SyncSender<Event>) {
    let mut buf = [0u8; 4096];
    loop {
        match stream.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                if events.send(Event::Bytes(id, buf[..n].to_vec())).is_err() {
                    return;
                }
            }
            Err(e) if is_transient(&e) => {}
            Err(_) => break,
        }
    }
    let _ = events.send(Event::Ended(id));
}

fn is_transient(e: &io::Error) -> bool {
    matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted)
}

struct Server<S> {
    /// the thread name, also the prefix of the reader threads' names
    name: String,
    listeners: Vec<TcpListener>,
    clients: Vec<Client>,
    next_id: u64,
    service: S,
    flags: Arc<Flags>,
    /// cloned into every reader thread (so the channel never disconnects while the loop runs)
    events_tx: SyncSender<Event>,
    events: Receiver<Event>,
}

impl<S: SimService> Server<S> {
    fn run(&mut self) {
        while !self.flags.stop.load(Ordering::SeqCst) {
            self.accept();
            if self.flags.drop_clients.swap(false, Ordering::SeqCst) {
                for c in &mut self.clients {
                    c.open = false;
                }
                self.reap();
            }
            if self.flags.stalled.load(Ordering::SeqCst) {
                std::thread::sleep(TICK);
                continue;
            }
            let busy = self.serve_once();
            self.reap();
            if !busy {
                // until a client sends something, at most one tick (the service's poll cadence)
                if let Ok(event) = self.events.recv_timeout(TICK) {
                    self.note(event);
                }
            }
        }
    }

    /// Files a reader thread's event with its client (events of forgotten clients are dropped).
    fn note(&mut self, event: Event) {
        let (id, bytes) = match event {
            Event::Bytes(id, bytes) => (id, Some(bytes)),
            Event::Ended(id) => (id, None),
        };
        if let Some(c) = self.clients.iter_mut().find(|c| c.id.id == id) {
            match bytes {
                Some(bytes) => c.held.extend_from_slice(&bytes),
                None => c.ended = true,
            }
        }
    }

    /// Files every event already waiting.
    fn note_waiting(&mut self) {
        while let Ok(event) = self.events.try_recv() {
            self.note(event);
        }
    }

    /// Starts the reader thread of a new client.
    fn spawn_reader(&self, stream: &TcpStream, id: u64) -> io::Result<()> {
        let stream = stream.try_clone()?;
        let events = self.events_tx.clone();
        std::thread::Builder::new()
            .name(format!("{}-rx{id}", self.name))
            .stack_size(READER_STACK)
            .spawn(move || read_client(stream, id, events))
            .map(drop)
    }

    fn accept(&mut self) {
        for listener in 0..self.listeners.len() {
            while let Ok((stream, _)) = self.listeners[listener].accept() {
                // a peer that left since the last turn must not block a newcomer
                self.note_waiting();
                for c in &mut self.clients {
                    if c.open && c.is_closed() {
                        c.open = false;
                    }
                }
                self.reap();
                let _ = stream.set_nonblocking(false);
                let _ = stream.set_nodelay(true);
                let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
                let _ = stream.set_read_timeout(None);
                let id = ClientId { id: self.next_id, listener };
                self.next_id += 1;
                let mut stream = stream;
                match self.service.connect(id) {
                    Admission::Accept(greeting) => {
                        if (greeting.is_empty() || stream.write_all(&greeting).is_ok())
                            && self.spawn_reader(&stream, id.id).is_ok()
                        {
                            let client = Client { id, stream, held: Vec::new(), ended: false, open: true };
                            self.clients.push(client);
                        } else {
                            let _ = stream.shutdown(Shutdown::Both);
                            self.service.disconnected(id);
                        }
                    }
                    Admission::Refuse(bytes) => {
                        let _ = stream.write_all(&bytes);
                    }
                }
            }
        }
    }

    /// One turn: every client's waiting bytes (received by its reader thread), the service's
    /// timed answers. Returns whether any bytes arrived (else the loop waits for some, at most
    /// one [`TICK`]).
    fn serve_once(&mut self) -> bool {
        self.note_waiting();
        let mut out = Vec::new();
        let mut busy = false;
        for client in &mut self.clients {
            if self.flags.stalled.load(Ordering::SeqCst) {
                // stalled during the turn: keep the bytes, answer later
                continue;
            }
            let input = std::mem::take(&mut client.held);
            if client.ended {
                client.open = false;
            }
            if !input.is_empty() {
                busy = true;
                out.extend(self.service.input(client.id, &input));
            }
        }
        out.extend(self.service.poll());
        self.deliver(out);
        busy
    }

    fn deliver(&mut self, out: Vec<(Audience, Vec<u8>)>) {
        for (audience, bytes) in out {
            if bytes.is_empty() {
                continue;
            }
            for c in self.clients.iter_mut().filter(|c| c.open) {
                let wanted = match audience {
                    Audience::Client(id) => c.id == id,
                    Audience::Listener(l) => c.id.listener == l,
                    Audience::All => true,
                };
                if wanted && c.stream.write_all(&bytes).is_err() {
                    c.open = false;
                }
            }
        }
    }

    /// Forgets closed clients, telling the service.
    fn reap(&mut self) {
        let service = &mut self.service;
        self.clients.retain(|c| {
            if !c.open {
                service.disconnected(c.id);
            }
            c.open
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::BufRead;

    /// Echoes lines upper-cased; a second client of listener 1 is refused.
    #[derive(Default)]
    struct Upper {
        buffers: std::collections::HashMap<u64, Vec<u8>>,
        on_one: Option<ClientId>,
        ticks: u64,
    }

    impl SimService for Upper {
        fn connect(&mut self, client: ClientId) -> Admission {
            if client.listener == 1 {
                if self.on_one.is_some() {
                    return Admission::Refuse(b"busy\n".to_vec());
                }
                self.on_one = Some(client);
            }
            Admission::Accept(b"hello\n".to_vec())
        }
        fn input(&mut self, client: ClientId, bytes: &[u8]) -> Vec<(Audience, Vec<u8>)> {
            let buf = self.buffers.entry(client.id).or_default();
            buf.extend_from_slice(bytes);
            let mut out = Vec::new();
            while let Some(end) = buf.iter().position(|b| *b == b'\n') {
                let line: Vec<u8> = buf.drain(..=end).collect();
                out.push((Audience::Client(client), line.to_ascii_uppercase()));
            }
            out
        }
        fn poll(&mut self) -> Vec<(Audience, Vec<u8>)> {
            self.ticks += 1;
            Vec::new()
        }
        fn disconnected(&mut self, client: ClientId) {
            if self.on_one == Some(client) {
                self.on_one = None;
            }
        }
    }

    fn line(r: &mut io::BufReader<TcpStream>) -> String {
        let mut s = String::new();
        r.read_line(&mut s).expect("read");
        s
    }

    fn connect(addr: SocketAddr) -> (TcpStream, io::BufReader<TcpStream>) {
        let s = TcpStream::connect(addr).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(2))).expect("timeout");
        let r = io::BufReader::new(s.try_clone().expect("clone"));
        (s, r)
    }

    #[test]
    fn serves_refuses_stalls_and_drops() {
        let local: SocketAddr = ([127, 0, 0, 1], 0).into();
        let server = SimServer::spawn("test-sim", &[local, local], Upper::default()).expect("spawn");
        let [a0, a1] = [server.addrs()[0], server.addrs()[1]];
        let (mut s, mut r) = connect(a0);
        assert_eq!(line(&mut r), "hello\n");
        s.write_all(b"abc\nde").expect("write");
        assert_eq!(line(&mut r), "ABC\n");
        s.write_all(b"f\n").expect("write");
        assert_eq!(line(&mut r), "DEF\n");

        let (_one, mut r1) = connect(a1);
        assert_eq!(line(&mut r1), "hello\n");
        let (_two, mut r2) = connect(a1);
        assert_eq!(line(&mut r2), "busy\n");
        assert_eq!(line(&mut r2), "", "refused client is closed");

        server.set_stalled(true);
        std::thread::sleep(Duration::from_millis(20));
        s.write_all(b"late\n").expect("write");
        s.set_read_timeout(Some(Duration::from_millis(100))).expect("timeout");
        let mut buf = [0u8; 8];
        assert!(s.peek(&mut buf).is_err(), "no answer while stalled");
        server.set_stalled(false);
        assert_eq!(line(&mut r), "LATE\n", "held bytes answered after the stall");

        server.drop_clients();
        s.set_read_timeout(Some(Duration::from_secs(2))).expect("timeout");
        assert_eq!(line(&mut r), "", "dropped");
        let (_again, mut r3) = connect(a1);
        assert_eq!(line(&mut r3), "hello\n", "listener 1 free again after the drop");
    }
}
