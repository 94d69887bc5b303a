//! Sockets of the simulator: the shared accept/serve loop of `vatcal-hardware-traits`
//! (`sim_server`), any number of TCP clients.

use std::collections::HashMap;
use std::io;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use vatcal_hardware_traits::sim_server::{Admission, Audience, ClientId, SimServer, SimService};

use super::SimConfig;
use super::device::{SimDevice, SimState};
use crate::codec::{Command, LineDeframer, Message};

#[derive(Debug)]
struct Shared {
    device: Mutex<SimDevice>,
    injected: Mutex<Vec<Message>>,
}

/// A running Zaber simulator. Dropping it stops the thread and closes every socket.
#[derive(Debug)]
pub struct ZaberSim {
    addr: SocketAddr,
    shared: Arc<Shared>,
    config: SimConfig,
    server: SimServer,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl ZaberSim {
    /// Binds [`SimConfig::bind`] and starts serving.
    pub fn start(config: SimConfig) -> io::Result<Self> {
        let shared = Arc::new(Shared {
            device: Mutex::new(SimDevice::new(config.clone())),
            injected: Mutex::new(Vec::new()),
        });
        let service = Service {
            shared: Arc::clone(&shared),
            config: config.clone(),
            deframers: HashMap::new(),
            answered: false,
        };
        let server = SimServer::spawn("zaber-sim", &[config.bind], service)?;
        Ok(Self { addr: server.addrs()[0], shared, config, server })
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
        self.server.set_stalled(stalled);
    }

    /// Closes every client connection.
    pub fn drop_clients(&self) {
        self.server.drop_clients();
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

/// The protocol on the device: per-client line framing, replies to the sender, alerts to all.
#[derive(Debug)]
struct Service {
    shared: Arc<Shared>,
    config: SimConfig,
    deframers: HashMap<u64, LineDeframer>,
    /// commands were answered in this turn of the loop
    answered: bool,
}

impl Service {
    /// Injected alerts and those of finished moves, for every client.
    fn alerts(&mut self, now: Duration) -> Vec<(Audience, Vec<u8>)> {
        let mut bytes: Vec<u8> =
            std::mem::take(&mut *lock(&self.shared.injected)).iter().flat_map(|m| m.encode(false)).collect();
        bytes.extend(lock(&self.shared.device).tick(now).iter().flat_map(|m| m.encode(false)));
        vec![(Audience::All, bytes)]
    }
}

impl SimService for Service {
    fn connect(&mut self, client: ClientId) -> Admission {
        // nothing is sent on connect
        self.deframers.insert(client.id, LineDeframer::new());
        Admission::Accept(Vec::new())
    }

    fn input(&mut self, client: ClientId, bytes: &[u8]) -> Vec<(Audience, Vec<u8>)> {
        let now = self.config.clock.now();
        // alerts of moves that finished before this command come first
        let mut out = self.alerts(now);
        let deframer = self.deframers.entry(client.id).or_default();
        deframer.push(bytes);
        let mut replies = Vec::new();
        while let Ok(Some(line)) = deframer.next_line() {
            // lines with a wrong checksum or that are not commands are ignored
            let Ok((cmd, checksum)) = Command::parse(&line) else { continue };
            if let Some(reply) = lock(&self.shared.device).handle(&cmd, now) {
                replies.extend(reply.encode(checksum));
            }
        }
        out.push((Audience::Client(client), replies));
        self.answered = true;
        out
    }

    fn poll(&mut self) -> Vec<(Audience, Vec<u8>)> {
        // a move started by this turn's commands is looked at from the next turn on (its
        // alert never shares a read with the command's reply)
        if std::mem::take(&mut self.answered) {
            return Vec::new();
        }
        let now = self.config.clock.now();
        self.alerts(now)
    }

    fn disconnected(&mut self, client: ClientId) {
        self.deframers.remove(&client.id);
    }
}
