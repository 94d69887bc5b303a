//! Sockets of the simulator: one background thread, any number of TCP clients on loopback.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use super::SimConfig;
use super::device::{SimDevice, SimState};
use crate::codec::{Command, LineDeframer, Message};

const TICK: Duration = Duration::from_millis(1);
const WRITE_TIMEOUT: Duration = Duration::from_millis(500);

#[derive(Debug, Default)]
struct Flags {
    stop: AtomicBool,
    stalled: AtomicBool,
    drop_clients: AtomicBool,
}

#[derive(Debug)]
struct Shared {
    device: Mutex<SimDevice>,
    injected: Mutex<Vec<Message>>,
    flags: Flags,
}

/// A running Zaber simulator. Dropping it stops the thread and closes every socket.
#[derive(Debug)]
pub struct ZaberSim {
    addr: SocketAddr,
    shared: Arc<Shared>,
    config: SimConfig,
    thread: Option<JoinHandle<()>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl ZaberSim {
    /// Binds [`SimConfig::bind`] and starts serving.
    pub fn start(config: SimConfig) -> io::Result<Self> {
        let listener = TcpListener::bind(config.bind)?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let shared = Arc::new(Shared {
            device: Mutex::new(SimDevice::new(config.clone())),
            injected: Mutex::new(Vec::new()),
            flags: Flags::default(),
        });
        let server =
            Server { listener, clients: Vec::new(), shared: Arc::clone(&shared), config: config.clone() };
        let thread = std::thread::Builder::new().name("zaber-sim".to_owned()).spawn(move || server.run())?;
        Ok(Self { addr, shared, config, thread: Some(thread) })
    }

    /// The address to connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    fn now(&self) -> Duration {
        self.config.clock.now()
    }

    /// A snapshot of the device.
    pub fn state(&self) -> SimState {
        let now = self.now();
        lock(&self.shared.device).snapshot(now)
    }

    /// Stops (`true`) or restarts all answers while keeping the connections open.
    pub fn set_stalled(&self, stalled: bool) {
        self.shared.flags.stalled.store(stalled, Ordering::SeqCst);
    }

    /// Closes every client connection.
    pub fn drop_clients(&self) {
        self.shared.flags.drop_clients.store(true, Ordering::SeqCst);
    }

    /// The motor stalls (`FS`); a running move stops where it is.
    pub fn inject_stall(&self) {
        let now = self.now();
        let alerts = lock(&self.shared.device).inject_stall(now);
        lock(&self.shared.injected).extend(alerts);
    }

    /// A limit switch triggers (`WL`); a running move stops where it is.
    pub fn inject_limit_hit(&self) {
        let now = self.now();
        let alerts = lock(&self.shared.device).inject_limit_hit(now);
        lock(&self.shared.injected).extend(alerts);
    }
}

impl Drop for ZaberSim {
    fn drop(&mut self) {
        self.shared.flags.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[derive(Debug)]
struct Client {
    stream: TcpStream,
    deframer: LineDeframer,
    open: bool,
}

#[derive(Debug)]
struct Server {
    listener: TcpListener,
    clients: Vec<Client>,
    shared: Arc<Shared>,
    config: SimConfig,
}

impl Server {
    fn run(mut self) {
        while !self.shared.flags.stop.load(Ordering::SeqCst) {
            while let Ok((stream, _)) = self.listener.accept() {
                let _ = stream.set_nonblocking(false);
                let _ = stream.set_nodelay(true);
                let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
                let _ = stream.set_read_timeout(Some(TICK));
                self.clients.push(Client { stream, deframer: LineDeframer::new(), open: true });
            }
            if self.shared.flags.drop_clients.swap(false, Ordering::SeqCst) {
                self.clients.clear();
            }
            if self.clients.is_empty() || self.shared.flags.stalled.load(Ordering::SeqCst) {
                std::thread::sleep(TICK);
                continue;
            }
            self.serve_once();
            self.clients.retain(|c| c.open);
        }
    }

    fn serve_once(&mut self) {
        let now = self.config.clock.now();
        let mut broadcast: Vec<u8> =
            std::mem::take(&mut *lock(&self.shared.injected)).iter().flat_map(|m| m.encode(false)).collect();
        broadcast.extend(lock(&self.shared.device).tick(now).iter().flat_map(|m| m.encode(false)));
        for client in &mut self.clients {
            let mut buf = [0u8; 2048];
            match client.stream.read(&mut buf) {
                Ok(0) => client.open = false,
                Ok(n) => client.deframer.push(&buf[..n]),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                    ) => {}
                Err(_) => client.open = false,
            }
            if self.shared.flags.stalled.load(Ordering::SeqCst) {
                continue; // keep the bytes, answer later
            }
            let mut out = broadcast.clone();
            while let Ok(Some(line)) = client.deframer.next_line() {
                // lines with a wrong checksum or that are not commands are ignored
                let Ok((cmd, checksum)) = Command::parse(&line) else { continue };
                if let Some(reply) = lock(&self.shared.device).handle(&cmd, now) {
                    out.extend(reply.encode(checksum));
                }
            }
            if !out.is_empty() && client.stream.write_all(&out).is_err() {
                client.open = false;
            }
        }
    }
}
