//! The blocking driver of the tracker line protocol ([`crate::codec`]): [`LineTracker`]
//! implements [`PositionTracker`] over any [`Transport`] — the `vatcal sim-cell` tracker, the
//! crate's [`crate::sim::TrackerSim`], or a bridge a user writes to a real tracker's SDK.

use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use nalgebra::Vector3;
use vatcal_hardware_traits::transport::{Deadline, LineDeframer, LinkError, Transport, recv_some};
use vatcal_hardware_traits::{PositionTracker, Result as HwResult};

use crate::codec::{FRAMING, MAX_ID, Reply, Request, clip, parse_xyz_mm};
use crate::error::TrackerError;

/// Connection settings and timeouts.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// device name used in error messages
    pub name: String,
    /// timeout of every request (a laser-tracker measurement takes about a second)
    pub io_timeout: Duration,
    /// TCP connect timeout
    pub connect_timeout: Duration,
}

impl Default for TrackerConfig {
    /// `tracker`, 10 s per request, 5 s to connect.
    fn default() -> Self {
        Self {
            name: "tracker".to_owned(),
            io_timeout: Duration::from_secs(10),
            connect_timeout: Duration::from_secs(5),
        }
    }
}

/// A tracker speaking the line protocol on the other end of a [`Transport`].
#[derive(Debug)]
pub struct LineTracker<T: Transport = TcpStream> {
    transport: T,
    deframer: LineDeframer,
    config: TrackerConfig,
    next_id: u16,
    identity: String,
    label: String,
}

impl LineTracker<TcpStream> {
    /// Connects over TCP and asks the tracker who it is (`ID?`).
    ///
    /// # Examples
    /// ```
    /// use nalgebra::Vector3;
    /// use vatcal_drivers_tracker::sim::{SimConfig, TrackerSim};
    /// use vatcal_drivers_tracker::{LineTracker, TrackerConfig};
    /// use vatcal_hardware_traits::PositionTracker;
    ///
    /// let sim = TrackerSim::start(SimConfig::default())?;
    /// sim.set_target_mm(2, Vector3::new(812.5, -40.0, 300.0));
    /// let mut tracker = LineTracker::connect_tcp(sim.addr(), TrackerConfig::default())?;
    /// assert_eq!(tracker.measure_mm(2)?, Vector3::new(812.5, -40.0, 300.0));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// The connection cannot be made, drops or times out, or the identity is refused.
    pub fn connect_tcp(addr: impl ToSocketAddrs, config: TrackerConfig) -> Result<Self, TrackerError> {
        let stream = vatcal_hardware_traits::transport::connect_tcp(addr, config.connect_timeout)?;
        let peer = stream.peer_addr()?;
        let label = format!("{} at {peer}", config.name);
        let mut tracker = Self::unidentified(stream, config);
        tracker.label = label;
        tracker.identify()?;
        Ok(tracker)
    }
}

impl<T: Transport> LineTracker<T> {
    /// Wraps a connected transport and asks the tracker who it is (`ID?`).
    ///
    /// # Errors
    /// As [`LineTracker::connect_tcp`] after the connection.
    pub fn new(transport: T, config: TrackerConfig) -> Result<Self, TrackerError> {
        let mut tracker = Self::unidentified(transport, config);
        tracker.identify()?;
        Ok(tracker)
    }

    fn unidentified(transport: T, config: TrackerConfig) -> Self {
        Self {
            transport,
            deframer: LineDeframer::new(FRAMING),
            label: config.name.clone(),
            config,
            next_id: 0,
            identity: String::new(),
        }
    }

    fn identify(&mut self) -> Result<(), TrackerError> {
        self.identity = self.request(Request::Identify)?;
        Ok(())
    }

    /// What the tracker answered to `ID?`.
    pub fn identity(&self) -> &str {
        &self.identity
    }

    /// The name errors carry: [`TrackerConfig::name`] plus ` at <address>` when the driver
    /// opened the link itself.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// One reading of `target` in the tracker's frame \[mm\].
    ///
    /// # Errors
    /// The tracker refuses ([`TrackerError::Refused`]: line of sight, unknown target, fault),
    /// answers garbage, stays silent past the I/O timeout, or the link closes.
    pub fn measure(&mut self, target: u32) -> Result<Vector3<f64>, TrackerError> {
        let request = Request::Measure { target };
        let text = self.request(request)?;
        parse_xyz_mm(&text).map_err(|reason| TrackerError::Garbled {
            request: request_text(request),
            answer: clip(&text),
            reason,
        })
    }

    /// Sends `request` and returns the text of its `OK` reply. Replies to earlier requests
    /// (late answers after a timeout) are skipped by their id.
    fn request(&mut self, request: Request) -> Result<String, TrackerError> {
        self.discard_pending()?;
        self.next_id = self.next_id % MAX_ID + 1;
        let id = self.next_id;
        let what = request_text(request);
        self.transport
            .send(&request.encode(id))
            .map_err(|e| LinkError::from_send(e, || format!("sending '{what}'")))?;
        let wait = Deadline::new(self.config.io_timeout);
        let mut buf = [0u8; 512];
        loop {
            while let Some(line) = self.deframer.next_line()? {
                match Reply::parse(&line) {
                    Ok(reply) if reply.id() != id && reply.id() != 0 => {} // a late answer
                    Ok(Reply::Ok { text, .. }) => return Ok(text),
                    Ok(Reply::Err { code, message, .. }) => {
                        return Err(TrackerError::Refused { request: what, code, message });
                    }
                    Err(reason) => {
                        return Err(TrackerError::Garbled { request: what, answer: clip(&line), reason });
                    }
                }
            }
            let Some(remaining) = wait.remaining() else {
                return Err(LinkError::Timeout {
                    waiting_for: format!("answer to '{what}'"),
                    after: wait.timeout(),
                }
                .into());
            };
            if let Some(n) = recv_some(&mut self.transport, &mut buf, remaining, || {
                format!("waiting for the answer to '{what}'")
            })? {
                self.deframer.push(&buf[..n]);
            }
        }
    }

    /// Drops whatever arrived unasked (late answers).
    fn discard_pending(&mut self) -> Result<(), TrackerError> {
        let mut buf = [0u8; 512];
        while recv_some(&mut self.transport, &mut buf, Duration::ZERO, || {
            "idle (before a request)".to_owned()
        })?
        .is_some()
        {}
        self.deframer.clear();
        Ok(())
    }
}

fn request_text(request: Request) -> String {
    match request {
        Request::Identify => "ID?".into(),
        Request::Measure { target } => format!("MEASURE {target}"),
    }
}

impl<T: Transport> PositionTracker for LineTracker<T> {
    fn measure_mm(&mut self, target: u32) -> HwResult<Vector3<f64>> {
        self.measure(target).map_err(|e| e.into_hw(&self.label))
    }
}
