//! Sockets of the simulator: one background thread serving the control port (one client) and
//! the monitoring port (any number of clients) on loopback.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use super::robot::{SimRobot, SimState};
use super::{SimAddrs, SimConfig};
use crate::codec::{Deframer, FrameError, Reply, Six, code};

/// Granularity of the server loop (socket read timeout / idle sleep).
const TICK: Duration = Duration::from_millis(1);
/// A client that does not read for this long is dropped.
const WRITE_TIMEOUT: Duration = Duration::from_millis(500);

/// Where a message goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Route {
    /// control client only
    Control,
    /// monitoring clients, and the control client if `SetCtrlPortMonitoring(1)`
    Monitoring,
}

#[derive(Debug, Default)]
struct Flags {
    stop: AtomicBool,
    stalled: AtomicBool,
    drop_client: AtomicBool,
}

#[derive(Debug)]
struct Shared {
    robot: Mutex<SimRobot>,
    injected: Mutex<Vec<Reply>>,
    flags: Flags,
}

/// A running Meca500 simulator. Dropping it stops the server thread and closes every socket.
#[derive(Debug)]
pub struct Meca500Sim {
    addrs: SimAddrs,
    shared: Arc<Shared>,
    config: SimConfig,
    thread: Option<JoinHandle<()>>,
}

impl Meca500Sim {
    /// Binds [`SimConfig::control_bind`] (and [`SimConfig::monitoring_bind`] if the monitoring
    /// port is enabled) and starts serving.
    pub fn start(config: SimConfig) -> io::Result<Self> {
        let control = TcpListener::bind(config.control_bind)?;
        control.set_nonblocking(true)?;
        let monitoring = if config.monitoring_port {
            let l = TcpListener::bind(config.monitoring_bind)?;
            l.set_nonblocking(true)?;
            Some(l)
        } else {
            None
        };
        let addrs = SimAddrs {
            control: control.local_addr()?,
            monitoring: monitoring.as_ref().map(TcpListener::local_addr).transpose()?,
        };
        let shared = Arc::new(Shared {
            robot: Mutex::new(SimRobot::new(config.clone())),
            injected: Mutex::new(Vec::new()),
            flags: Flags::default(),
        });
        let server = Server {
            control,
            monitoring,
            client: None,
            monitors: Vec::new(),
            shared: Arc::clone(&shared),
            config: config.clone(),
            next_cycle: Duration::ZERO,
        };
        let thread =
            std::thread::Builder::new().name("meca500-sim".to_owned()).spawn(move || server.run())?;
        Ok(Self { addrs, shared, config, thread: Some(thread) })
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
        self.shared.flags.stalled.store(stalled, Ordering::SeqCst);
    }

    /// Closes the control connection (the robot drops the client).
    pub fn drop_client(&self) {
        self.shared.flags.drop_client.store(true, Ordering::SeqCst);
    }

    /// Raises an asynchronous error (e.g. `[3005]` motion error): error mode, message sent on
    /// the control port.
    pub fn inject_error(&self, code: u16, text: &str) {
        let now = self.now();
        let reply = self.robot().inject_error(code, text, now);
        lock(&self.shared.injected).push(reply);
    }

    /// The next move that starts executing fails with `code` (e.g. `[1012]` singularity).
    pub fn fail_next_move(&self, code: u16) {
        self.robot().fail_next_move(code);
    }

    /// Presses or releases the E-Stop (`[3070][1]` / `[3070][0]`).
    pub fn set_estop(&self, pressed: bool) {
        let now = self.now();
        let reply = self.robot().set_estop(pressed, now);
        lock(&self.shared.injected).push(reply);
    }

    /// Places the arm at `q` \[deg\] (test set-up; refused while a motion runs).
    pub fn set_joints_deg(&self, q: Six) -> bool {
        self.robot().set_joints_deg(q)
    }
}

impl Drop for Meca500Sim {
    fn drop(&mut self) {
        self.shared.flags.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Locks a mutex, recovering the data if a panicking thread poisoned it.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[derive(Debug)]
struct Client {
    stream: TcpStream,
    deframer: Deframer,
}

impl Client {
    /// True when the peer has closed the connection (pending input counts as open).
    fn is_closed(&mut self) -> bool {
        let mut probe = [0u8; 1];
        match self.stream.peek(&mut probe) {
            Ok(0) => true,
            Ok(_) => false,
            Err(e) => !matches!(
                e.kind(),
                io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
            ),
        }
    }
}

#[derive(Debug)]
struct Server {
    control: TcpListener,
    monitoring: Option<TcpListener>,
    client: Option<Client>,
    monitors: Vec<TcpStream>,
    shared: Arc<Shared>,
    config: SimConfig,
    next_cycle: Duration,
}

impl Server {
    fn run(mut self) {
        while !self.shared.flags.stop.load(Ordering::SeqCst) {
            self.accept_control();
            self.accept_monitors();
            if self.shared.flags.drop_client.swap(false, Ordering::SeqCst) {
                self.client = None;
            }
            if self.shared.flags.stalled.load(Ordering::SeqCst) {
                std::thread::sleep(TICK);
                continue;
            }
            let input = self.read_control();
            if self.shared.flags.stalled.load(Ordering::SeqCst) {
                // stalled while reading: keep the bytes for later, answer nothing
                if let Some(client) = &mut self.client {
                    client.deframer.push(&input);
                }
                continue;
            }
            let out = self.step(&input);
            self.deliver(out);
            if self.client.is_none() {
                std::thread::sleep(TICK);
            }
        }
    }

    fn accept_control(&mut self) {
        while let Ok((stream, _)) = self.control.accept() {
            let _ = stream.set_nonblocking(false);
            let _ = stream.set_nodelay(true);
            let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
            let _ = stream.set_read_timeout(Some(TICK));
            if self.client.as_mut().is_some_and(|c| !c.is_closed()) {
                let refusal =
                    Reply::new(code::ANOTHER_USER, "Another user is already connected, closing connection.");
                let mut s = stream;
                let _ = s.write_all(&refusal.encode());
                continue;
            }
            let banner = lock(&self.shared.robot).banner().to_reply();
            let mut client = Client { stream, deframer: Deframer::nul_or_lf() };
            if client.stream.write_all(&banner.encode()).is_ok() {
                self.client = Some(client);
            }
        }
    }

    fn accept_monitors(&mut self) {
        let Some(listener) = &self.monitoring else { return };
        while let Ok((stream, _)) = listener.accept() {
            let _ = stream.set_nonblocking(false);
            let _ = stream.set_nodelay(true);
            let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
            let now = self.config.clock.now();
            let (banner, status) = {
                let r = lock(&self.shared.robot);
                (r.banner().to_reply(), r.status_word(now).to_reply())
            };
            let mut s = stream;
            let mut bytes = banner.encode();
            bytes.extend(status.encode());
            if s.write_all(&bytes).is_ok() {
                self.monitors.push(s);
            }
        }
    }

    /// Bytes from the control client (waits up to one tick); `None` client on close.
    fn read_control(&mut self) -> Vec<u8> {
        let Some(client) = &mut self.client else { return Vec::new() };
        let mut buf = [0u8; 4096];
        match client.stream.read(&mut buf) {
            Ok(0) => {
                self.client = None;
                Vec::new()
            }
            Ok(n) => buf[..n].to_vec(),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                ) =>
            {
                Vec::new()
            }
            Err(_) => {
                self.client = None;
                Vec::new()
            }
        }
    }

    /// Feeds input and time to the robot; returns the routed output.
    fn step(&mut self, input: &[u8]) -> Vec<(Route, Reply)> {
        let now = self.config.clock.now();
        let mut out: Vec<(Route, Reply)> = std::mem::take(&mut *lock(&self.shared.injected))
            .into_iter()
            .map(|r| (Route::Control, r))
            .collect();
        let mut robot = lock(&self.shared.robot);
        if let Some(client) = &mut self.client {
            client.deframer.push(input);
            while !robot.is_busy() {
                let replies = match client.deframer.next_frame() {
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

    fn deliver(&mut self, out: Vec<(Route, Reply)>) {
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
        if let Some(client) = &mut self.client
            && !control.is_empty()
            && client.stream.write_all(&control).is_err()
        {
            self.client = None;
        }
        if !monitoring.is_empty() {
            self.monitors.retain_mut(|m| m.write_all(&monitoring).is_ok());
        }
    }
}
