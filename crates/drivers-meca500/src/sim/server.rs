//! Sockets of the simulator: the shared accept/serve loop of `vatcal-hardware-traits`
//! (`sim_server`) serving the control port (one client) and the monitoring port (any number
//! of clients).

use std::io;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use vatcal_hardware_traits::sim_server::{Admission, Audience, ClientId, SimServer, SimService};

use super::robot::{SimRobot, SimState};
use super::{SimAddrs, SimConfig};
use crate::codec::{Deframer, FrameError, Reply, Six, code};

/// Listener index of the control port.
const CONTROL: usize = 0;
/// Listener index of the monitoring port.
const MONITORING: usize = 1;

/// Where a message goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Route {
    /// control client only
    Control,
    /// monitoring clients, and the control client if `SetCtrlPortMonitoring(1)`
    Monitoring,
}

#[derive(Debug)]
struct Shared {
    robot: Mutex<SimRobot>,
    injected: Mutex<Vec<Reply>>,
}

/// A running Meca500 simulator. Dropping it stops the server thread and closes every socket.
#[derive(Debug)]
pub struct Meca500Sim {
    addrs: SimAddrs,
    shared: Arc<Shared>,
    config: SimConfig,
    server: SimServer,
}

impl Meca500Sim {
    /// Binds [`SimConfig::control_bind`] (and [`SimConfig::monitoring_bind`] if the monitoring
    /// port is enabled) and starts serving.
    pub fn start(config: SimConfig) -> io::Result<Self> {
        let shared = Arc::new(Shared {
            robot: Mutex::new(SimRobot::new(config.clone())),
            injected: Mutex::new(Vec::new()),
        });
        let mut binds = vec![config.control_bind];
        if config.monitoring_port {
            binds.push(config.monitoring_bind);
        }
        let service = Service {
            shared: Arc::clone(&shared),
            config: config.clone(),
            control: None,
            next_cycle: Duration::ZERO,
        };
        let server = SimServer::spawn("meca500-sim", &binds, service)?;
        let addrs = SimAddrs {
            control: server.addrs()[CONTROL],
            monitoring: server.addrs().get(MONITORING).copied(),
        };
        Ok(Self { addrs, shared, config, server })
    }

    /// The control address (give it to `Meca500::connect_tcp`).
    pub fn control_addr(&self) -> SocketAddr {
        self.addrs.control
    }

    /// The monitoring address, if enabled.
    pub fn monitoring_addr(&self) -> Option<SocketAddr> {
        self.addrs.monitoring
    }

    /// Both addresses.
    pub fn addrs(&self) -> SimAddrs {
        self.addrs
    }

    fn robot(&self) -> MutexGuard<'_, SimRobot> {
        lock(&self.shared.robot)
    }

    fn now(&self) -> Duration {
        self.config.clock.now()
    }

    /// A snapshot of the simulated controller.
    pub fn state(&self) -> SimState {
        let now = self.now();
        self.robot().snapshot(now)
    }

    /// Stops (`true`) or restarts (`false`) all socket I/O while keeping the connections open:
    /// the robot "hangs", so a driver's calls time out.
    pub fn set_stalled(&self, stalled: bool) {
        self.server.set_stalled(stalled);
    }

    /// Closes the control connection (the robot drops the client), and the monitoring ones.
    pub fn drop_client(&self) {
        self.server.drop_clients();
    }

    /// Raises an asynchronous error (e.g. `[3005]` motion error): error mode, message sent on
    /// the control port.
    pub fn inject_error(&self, code: u16, text: &str) {
        let now = self.now();
        // queued under the robot's lock: a command handled after the error entered error
        // mode is answered after the error message, as by the robot (`[3005]` before `[1011]`)
        let mut robot = self.robot();
        let reply = robot.inject_error(code, text, now);
        lock(&self.shared.injected).push(reply);
    }

    /// The next move that starts executing fails with `code` (e.g. `[1012]` singularity).
    pub fn fail_next_move(&self, code: u16) {
        self.robot().fail_next_move(code);
    }

    /// Presses or releases the E-Stop (`[3070][1]` / `[3070][0]`).
    pub fn set_estop(&self, pressed: bool) {
        let now = self.now();
        let mut robot = self.robot();
        let reply = robot.set_estop(pressed, now);
        lock(&self.shared.injected).push(reply);
    }

    /// Places the arm at `q` \[deg\] (test set-up; refused while a motion runs).
    pub fn set_joints_deg(&self, q: Six) -> bool {
        self.robot().set_joints_deg(q)
    }
}

/// Locks a mutex, recovering the data if a panicking thread poisoned it.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The robot's protocol on the two ports.
#[derive(Debug)]
struct Service {
    shared: Arc<Shared>,
    config: SimConfig,
    /// the control client and its frame buffer
    control: Option<(ClientId, Deframer)>,
    next_cycle: Duration,
}

impl Service {
    /// Feeds input and time to the robot; returns the routed output.
    fn step(&mut self, input: &[u8]) -> Vec<(Route, Reply)> {
        let now = self.config.clock.now();
        // the robot's lock first, then the injected messages (the order `inject_error` uses)
        let mut robot = lock(&self.shared.robot);
        let mut out: Vec<(Route, Reply)> = std::mem::take(&mut *lock(&self.shared.injected))
            .into_iter()
            .map(|r| (Route::Control, r))
            .collect();
        if let Some((_, deframer)) = &mut self.control {
            deframer.push(input);
            while !robot.is_busy() {
                let replies = match deframer.next_frame() {
                    Ok(Some(frame)) => robot.handle_frame(&frame, now),
                    Ok(None) => break,
                    Err(FrameError::TooLong { .. }) => {
                        vec![Reply::new(
                            code::COMMAND_TOO_LONG,
                            "Command too long or missing NUL terminator.",
                        )]
                    }
                };
                out.extend(replies.into_iter().map(|r| (Route::Control, r)));
                out.extend(robot.tick(now).into_iter().map(|r| (Route::Control, r)));
                out.extend(robot.status_change(now).map(|s| (Route::Monitoring, s)));
            }
        }
        out.extend(robot.tick(now).into_iter().map(|r| (Route::Control, r)));
        out.extend(robot.status_change(now).map(|s| (Route::Monitoring, s)));
        if now >= self.next_cycle {
            self.next_cycle = now.saturating_add(robot.monitoring_interval());
            out.extend(robot.monitoring_cycle(now).into_iter().map(|r| (Route::Monitoring, r)));
        }
        out
    }

    /// Routes the robot's messages to the clients.
    fn deliver(&self, out: Vec<(Route, Reply)>) -> Vec<(Audience, Vec<u8>)> {
        let mirrored = lock(&self.shared.robot).ctrl_port_monitoring();
        let mut control = Vec::new();
        let mut monitoring = Vec::new();
        for (route, reply) in &out {
            let bytes = reply.encode();
            match route {
                Route::Control => control.extend_from_slice(&bytes),
                Route::Monitoring => {
                    monitoring.extend_from_slice(&bytes);
                    if mirrored {
                        control.extend_from_slice(&bytes);
                    }
                }
            }
        }
        let mut routed = vec![(Audience::Listener(MONITORING), monitoring)];
        if let Some((id, _)) = &self.control {
            routed.push((Audience::Client(*id), control));
        }
        routed
    }
}

impl SimService for Service {
    fn connect(&mut self, client: ClientId) -> Admission {
        let now = self.config.clock.now();
        let robot = lock(&self.shared.robot);
        if client.listener == MONITORING {
            let mut bytes = robot.banner().to_reply().encode();
            bytes.extend(robot.status_word(now).to_reply().encode());
            return Admission::Accept(bytes);
        }
        if self.control.is_some() {
            let refusal =
                Reply::new(code::ANOTHER_USER, "Another user is already connected, closing connection.");
            return Admission::Refuse(refusal.encode());
        }
        self.control = Some((client, Deframer::nul_or_lf()));
        Admission::Accept(robot.banner().to_reply().encode())
    }

    fn input(&mut self, client: ClientId, bytes: &[u8]) -> Vec<(Audience, Vec<u8>)> {
        // the monitoring port is output only
        if self.control.as_ref().is_none_or(|(id, _)| *id != client) {
            return Vec::new();
        }
        let out = self.step(bytes);
        self.deliver(out)
    }

    fn poll(&mut self) -> Vec<(Audience, Vec<u8>)> {
        let out = self.step(&[]);
        self.deliver(out)
    }

    fn disconnected(&mut self, client: ClientId) {
        if self.control.as_ref().is_some_and(|(id, _)| *id == client) {
            self.control = None;
        }
    }
}
