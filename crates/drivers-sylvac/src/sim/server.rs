//! Sockets of the simulator: the shared accept/serve loop of `vatcal-hardware-traits`
//! (`sim_server`), any number of TCP clients.

use std::collections::HashMap;
use std::io;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use vatcal_hardware_traits::sim_server::{Admission, Audience, ClientId, SimServer, SimService};

use super::SimConfig;
use super::gauge::{SimGauge, SimState};
use crate::codec::LineDeframer;

#[derive(Debug)]
struct Shared {
    gauge: Mutex<SimGauge>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A running gauge simulator. Dropping it stops the thread and closes every socket.
#[derive(Debug)]
pub struct SylvacSim {
    addr: SocketAddr,
    shared: Arc<Shared>,
    server: SimServer,
}

impl SylvacSim {
    /// Binds [`SimConfig::bind`] and starts serving.
    pub fn start(config: SimConfig) -> io::Result<Self> {
        let shared = Arc::new(Shared { gauge: Mutex::new(SimGauge::new(config.clone())) });
        let bind = config.bind;
        let service =
            Service { shared: Arc::clone(&shared), config, deframers: HashMap::new(), next_output: None };
        let server = SimServer::spawn("sylvac-sim", &[bind], service)?;
        Ok(Self { addr: server.addrs()[0], shared, server })
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
        self.server.set_stalled(stalled);
    }

    /// Closes every client connection.
    pub fn drop_clients(&self) {
        self.server.drop_clients();
    }
}

/// The gauge's command set: per-client line framing, answers to the sender, the continuous
/// output (`OUT1`) to every client.
#[derive(Debug)]
struct Service {
    shared: Arc<Shared>,
    config: SimConfig,
    deframers: HashMap<u64, LineDeframer>,
    next_output: Option<Duration>,
}

impl SimService for Service {
    fn connect(&mut self, client: ClientId) -> Admission {
        self.deframers.insert(client.id, LineDeframer::new());
        Admission::Accept(Vec::new())
    }

    fn input(&mut self, client: ClientId, bytes: &[u8]) -> Vec<(Audience, Vec<u8>)> {
        let now = self.config.clock.now();
        let deframer = self.deframers.entry(client.id).or_default();
        deframer.push(bytes);
        let mut out = String::new();
        while let Ok(Some(line)) = deframer.next_line() {
            if let Some(answer) = lock(&self.shared.gauge).handle_line(&line, now) {
                out.push_str(&answer);
                out.push('\r');
            }
        }
        vec![(Audience::Client(client), out.into_bytes())]
    }

    /// The periodic value line when `OUT1` is on.
    fn poll(&mut self) -> Vec<(Audience, Vec<u8>)> {
        let now = self.config.clock.now();
        let mut gauge = lock(&self.shared.gauge);
        if !gauge.continuous_output() {
            self.next_output = None;
            return Vec::new();
        }
        if self.next_output.is_some_and(|t| now < t) {
            return Vec::new();
        }
        self.next_output = Some(now.saturating_add(self.config.output_interval));
        vec![(Audience::All, format!("{}\r", gauge.value_answer(now)).into_bytes())]
    }

    fn disconnected(&mut self, client: ClientId) {
        self.deframers.remove(&client.id);
    }
}
