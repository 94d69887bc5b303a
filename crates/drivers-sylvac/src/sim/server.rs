//! Sockets of the simulator: one background thread, any number of TCP clients on loopback.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use super::SimConfig;
use super::gauge::{SimGauge, SimState};
use crate::codec::LineDeframer;

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
    gauge: Mutex<SimGauge>,
    flags: Flags,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A running gauge simulator. Dropping it stops the thread and closes every socket.
#[derive(Debug)]
pub struct SylvacSim {
    addr: SocketAddr,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl SylvacSim {
    /// Binds [`SimConfig::bind`] and starts serving.
    pub fn start(config: SimConfig) -> io::Result<Self> {
        let listener = TcpListener::bind(config.bind)?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let shared =
            Arc::new(Shared { gauge: Mutex::new(SimGauge::new(config.clone())), flags: Flags::default() });
        let server =
            Server { listener, clients: Vec::new(), shared: Arc::clone(&shared), config, next_output: None };
        let thread = std::thread::Builder::new().name("sylvac-sim".to_owned()).spawn(move || server.run())?;
        Ok(Self { addr, shared, thread: Some(thread) })
    }

    /// The address to connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Moves the plunger to `mm` (0 = fully extended; beyond `0..=range_mm` the gauge answers
    /// `ERR3`).
    pub fn set_plunger_mm(&self, mm: f64) {
        lock(&self.shared.gauge).set_plunger_mm(mm);
    }

    /// Injects or clears a sensor fault (`ERR0`).
    pub fn set_sensor_error(&self, on: bool) {
        lock(&self.shared.gauge).set_sensor_error(on);
    }

    /// A snapshot of the gauge.
    pub fn state(&self) -> SimState {
        lock(&self.shared.gauge).snapshot()
    }

    /// Stops (`true`) or restarts all answers while keeping the connections open.
    pub fn set_stalled(&self, stalled: bool) {
        self.shared.flags.stalled.store(stalled, Ordering::SeqCst);
    }

    /// Closes every client connection.
    pub fn drop_clients(&self) {
        self.shared.flags.drop_clients.store(true, Ordering::SeqCst);
    }
}

impl Drop for SylvacSim {
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
    next_output: Option<Duration>,
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
        let stream_line = self.continuous_output(now);
        for client in &mut self.clients {
            let mut buf = [0u8; 512];
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
            let mut out = stream_line.clone().unwrap_or_default();
            while let Ok(Some(line)) = client.deframer.next_line() {
                if let Some(answer) = lock(&self.shared.gauge).handle_line(&line, now) {
                    out.push_str(&answer);
                    out.push('\r');
                }
            }
            if !out.is_empty() && client.stream.write_all(out.as_bytes()).is_err() {
                client.open = false;
            }
        }
    }

    /// The periodic value line when `OUT1` is on.
    fn continuous_output(&mut self, now: Duration) -> Option<String> {
        let mut gauge = lock(&self.shared.gauge);
        if !gauge.continuous_output() {
            self.next_output = None;
            return None;
        }
        let due = self.next_output.is_none_or(|t| now >= t);
        if !due {
            return None;
        }
        self.next_output = Some(now.saturating_add(self.config.output_interval));
        Some(format!("{}\r", gauge.value_answer(now)))
    }
}
