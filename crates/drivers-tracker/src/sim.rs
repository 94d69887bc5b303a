//! A tracker simulator speaking the line protocol ([`crate::codec`]) on `127.0.0.1`, built on
//! the shared accept/serve loop `vatcal_hardware_traits::sim_server`.
//!
//! [`TrackerSim::start`] binds [`SimConfig::bind`] (default `127.0.0.1:0`) and serves any
//! number of clients from a background thread until dropped. Where the targets are is decided
//! by the test ([`TrackerSim::set_target_mm`], exact positions) or by a [`TargetSource`] (a
//! simulated world: `vatcal sim-cell` couples it to its virtual cell, with the in-process
//! tracker's noise, line-of-sight loss and registration error). Each measurement is answered
//! after [`TargetSource::measure_duration`] (default [`SimConfig::measure_time`]).
//!
//! Fault injection: [`TrackerSim::set_line_of_sight`] (`ERR LOS`), [`TrackerSim::set_garbled`]
//! (answers that are not replies), [`TrackerSim::set_stalled`] (silence),
//! [`TrackerSim::drop_clients`].

use std::collections::{BTreeMap, HashMap};
use std::io;
use std::net::{Ipv4Addr, SocketAddr};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use nalgebra::Vector3;
use vatcal_hardware_traits::sim_server::{Admission, Audience, ClientId, SimServer, SimService};
use vatcal_hardware_traits::transport::LineDeframer;

use crate::codec::{ErrorCode, FRAMING, Reply, Request, format_xyz_mm};

/// Why a simulated measurement fails.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SimFault {
    /// the SMR cannot be seen (`ERR LOS`)
    LineOfSight(String),
    /// no such target (`ERR TARGET`)
    UnknownTarget(String),
    /// anything else (`ERR DEVICE`)
    Device(String),
}

/// Where the targets are, when a simulated world decides it. Called from the server thread
/// for every `MEASURE`.
pub trait TargetSource: Send + Sync + std::fmt::Debug {
    /// One reading of `target` in the tracker's frame \[mm\] (noise included).
    ///
    /// # Errors
    /// The fault the tracker answers instead.
    fn measure_mm(&self, target: u32) -> Result<Vector3<f64>, SimFault>;

    /// Wall time one measurement takes before its answer is sent.
    fn measure_duration(&self) -> Option<Duration> {
        None
    }
}

/// Simulator settings.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// `ID?` answer
    pub identity: String,
    /// address to listen on (port 0: ephemeral)
    pub bind: SocketAddr,
    /// the world that decides where targets are (`None`: [`TrackerSim::set_target_mm`])
    pub source: Option<Arc<dyn TargetSource>>,
    /// wall time of one measurement when the source does not say
    pub measure_time: Duration,
}

impl Default for SimConfig {
    /// `vatcal tracker simulator`, an ephemeral port on 127.0.0.1, targets set by the test,
    /// answers at once.
    fn default() -> Self {
        Self {
            identity: "vatcal tracker simulator".to_owned(),
            bind: (Ipv4Addr::LOCALHOST, 0).into(),
            source: None,
            measure_time: Duration::ZERO,
        }
    }
}

#[derive(Debug, Default)]
struct Shared {
    targets: Mutex<BTreeMap<u32, Vector3<f64>>>,
    line_of_sight_lost: AtomicBool,
    garbled: AtomicBool,
    measurements: AtomicU64,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A running tracker simulator. Dropping it stops the thread and closes every socket.
#[derive(Debug)]
pub struct TrackerSim {
    addr: SocketAddr,
    shared: Arc<Shared>,
    server: SimServer,
}

impl TrackerSim {
    /// Binds [`SimConfig::bind`] and starts serving.
    ///
    /// # Errors
    /// The address cannot be bound.
    pub fn start(config: SimConfig) -> io::Result<Self> {
        let shared = Arc::new(Shared::default());
        let bind = config.bind;
        let service =
            Service { shared: Arc::clone(&shared), config, deframers: HashMap::new(), pending: Vec::new() };
        let server = SimServer::spawn("tracker-sim", &[bind], service)?;
        Ok(Self { addr: server.addrs()[0], shared, server })
    }

    /// The address to connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Puts `target` at `p` \[mm\] (exact readings; without a [`TargetSource`]).
    pub fn set_target_mm(&self, target: u32, p: Vector3<f64>) {
        lock(&self.shared.targets).insert(target, p);
    }

    /// Clears (`false`) or restores the line of sight: while lost, every `MEASURE` answers
    /// `ERR LOS`.
    pub fn set_line_of_sight(&self, visible: bool) {
        self.shared.line_of_sight_lost.store(!visible, Ordering::SeqCst);
    }

    /// While on, every answer is garbage (not a reply of the protocol).
    pub fn set_garbled(&self, on: bool) {
        self.shared.garbled.store(on, Ordering::SeqCst);
    }

    /// Stops (`true`) or restarts all answers while keeping the connections open.
    pub fn set_stalled(&self, stalled: bool) {
        self.server.set_stalled(stalled);
    }

    /// Closes every client connection.
    pub fn drop_clients(&self) {
        self.server.drop_clients();
    }

    /// `MEASURE` requests answered so far (readings and refusals).
    pub fn measurements(&self) -> u64 {
        self.shared.measurements.load(Ordering::SeqCst)
    }
}

#[derive(Debug)]
struct Service {
    shared: Arc<Shared>,
    config: SimConfig,
    deframers: HashMap<u64, LineDeframer>,
    /// answers waiting for their measurement time
    pending: Vec<(Instant, ClientId, Vec<u8>)>,
}

impl Service {
    fn answer(&self, line: &str) -> (Vec<u8>, Duration) {
        let (id, request) = match Request::parse(line) {
            Ok(r) => r,
            Err((id, message)) => {
                return (Reply::Err { id, code: ErrorCode::BadRequest, message }.encode(), Duration::ZERO);
            }
        };
        let reply = |text: String| Reply::Ok { id, text };
        let refuse = |code, message| Reply::Err { id, code, message };
        match request {
            Request::Identify => (reply(self.config.identity.clone()).encode(), Duration::ZERO),
            Request::Measure { target } => {
                self.shared.measurements.fetch_add(1, Ordering::SeqCst);
                let delay = self
                    .config
                    .source
                    .as_ref()
                    .and_then(|s| s.measure_duration())
                    .unwrap_or(self.config.measure_time);
                if self.shared.garbled.load(Ordering::SeqCst) {
                    return (format!("{id} OK 12.5 -3,7 ??\u{7f}\n").into_bytes(), delay);
                }
                if self.shared.line_of_sight_lost.load(Ordering::SeqCst) {
                    let r = refuse(ErrorCode::LineOfSight, format!("SMR {target} not visible (beam broken)"));
                    return (r.encode(), delay);
                }
                let reading = match &self.config.source {
                    Some(source) => source.measure_mm(target),
                    None => lock(&self.shared.targets)
                        .get(&target)
                        .copied()
                        .ok_or_else(|| SimFault::UnknownTarget(format!("no target {target}"))),
                };
                let r = match reading {
                    Ok(p) => reply(format_xyz_mm(&p)),
                    Err(SimFault::LineOfSight(m)) => refuse(ErrorCode::LineOfSight, m),
                    Err(SimFault::UnknownTarget(m)) => refuse(ErrorCode::UnknownTarget, m),
                    Err(SimFault::Device(m)) => refuse(ErrorCode::Device, m),
                };
                (r.encode(), delay)
            }
        }
    }
}

impl SimService for Service {
    fn connect(&mut self, client: ClientId) -> Admission {
        self.deframers.insert(client.id, LineDeframer::new(FRAMING));
        Admission::Accept(Vec::new())
    }

    fn input(&mut self, client: ClientId, bytes: &[u8]) -> Vec<(Audience, Vec<u8>)> {
        let mut lines = Vec::new();
        let deframer = self.deframers.entry(client.id).or_insert_with(|| LineDeframer::new(FRAMING));
        deframer.push(bytes);
        loop {
            match deframer.next_line() {
                Ok(Some(line)) => lines.push(Ok(line)),
                Ok(None) => break,
                Err(e) => lines.push(Err(e.to_string())),
            }
        }
        let mut out = Vec::new();
        for line in lines {
            let (bytes, delay) = match line {
                Ok(line) => self.answer(&line),
                Err(e) => {
                    (Reply::Err { id: 0, code: ErrorCode::BadRequest, message: e }.encode(), Duration::ZERO)
                }
            };
            if delay.is_zero() {
                out.push((Audience::Client(client), bytes));
            } else {
                self.pending.push((Instant::now() + delay, client, bytes));
            }
        }
        out
    }

    fn poll(&mut self) -> Vec<(Audience, Vec<u8>)> {
        let now = Instant::now();
        let (due, later): (Vec<_>, Vec<_>) =
            std::mem::take(&mut self.pending).into_iter().partition(|p| p.0 <= now);
        self.pending = later;
        due.into_iter().map(|(_, client, bytes)| (Audience::Client(client), bytes)).collect()
    }

    fn disconnected(&mut self, client: ClientId) {
        self.deframers.remove(&client.id);
        self.pending.retain(|p| p.1 != client);
    }
}
