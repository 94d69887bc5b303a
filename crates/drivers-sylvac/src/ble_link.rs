//! Bluetooth LE link to a Sylvac Smart gauge (cargo feature `ble`, off by default).
//!
//! The SMS RemoteRequest / RemoteResponse characteristics carry exactly the ASCII command set
//! of the cable (protocols.md §3.2–3.3), so the BLE link is just another [`Transport`]:
//! [`BleTransport`] writes commands to RemoteRequest (without response, ≤ 20 bytes per write)
//! and hands the RemoteResponse notifications to the driver, which deframes them on CR. The
//! gauge over BLE is therefore the same [`SylvacGauge`] (ERR handling, presets, unit) as over
//! TCP or a cable: [`SylvacBle`]. Measurement notifications (int32 × 10^exponent m, the
//! exponent read from the 0x2904 descriptor) are decoded with [`crate::ble`] and kept as the
//! latest live value ([`SylvacBle::live_measurement`]).
//!
//! The blocking API runs over a small tokio runtime (one worker thread) owned by the
//! transport; btleplug talks to BlueZ over D-Bus (libdbus is vendored: the build needs no
//! system library; at run time a system D-Bus and `bluetoothd` must be running).

use std::io;
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use btleplug::api::{Central as _, Characteristic, Manager as _, Peripheral as _, ScanFilter, WriteType};
use btleplug::platform::{Manager, Peripheral};
use futures::StreamExt;
use uuid::Uuid;
use vatcal_hardware_traits::LinkError;
use vatcal_hardware_traits::transport::Transport;

use crate::ble::{
    DEFAULT_EXPONENT, MAX_NOTIFICATION_LEN, MEASUREMENT_UUID, PRESENTATION_FORMAT_DESCRIPTOR,
    REMOTE_REQUEST_UUID, REMOTE_RESPONSE_UUID, decode_measurement_mm, presentation_format_exponent,
};
use crate::driver::{SylvacConfig, SylvacGauge};
use crate::error::SylvacError;

/// A Sylvac gauge over Bluetooth LE: the ASCII driver over a [`BleTransport`].
pub type SylvacBle = SylvacGauge<BleTransport>;

/// Which gauge to connect to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BleTarget {
    /// the advertised name, exactly (e.g. `SY289`)
    Name(String),
    /// the Bluetooth address `AA:BB:CC:DD:EE:FF` (case-insensitive)
    Address(String),
}

impl std::fmt::Display for BleTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BleTarget::Name(n) => write!(f, "named '{n}'"),
            BleTarget::Address(a) => write!(f, "at {a}"),
        }
    }
}

/// How to find and connect to the gauge.
#[derive(Debug, Clone, PartialEq)]
pub struct BleConfig {
    /// the gauge
    pub target: BleTarget,
    /// how long to scan for it
    pub scan_timeout: Duration,
    /// timeout of the connection and of the service discovery
    pub connect_timeout: Duration,
}

impl BleConfig {
    /// `target` with a 10 s scan and a 10 s connection timeout.
    pub fn new(target: BleTarget) -> Self {
        Self { target, scan_timeout: Duration::from_secs(10), connect_timeout: Duration::from_secs(10) }
    }
}

/// The latest Measurement notification.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveMeasurement {
    /// value \[mm\] (`None`: the gauge sent the "no value" sentinel)
    pub mm: Option<f64>,
    /// when it arrived
    pub at: Instant,
}

/// The BLE link as a [`Transport`]: `send` writes RemoteRequest, `recv` returns one
/// RemoteResponse notification (or the rest of one) per call; `Ok(0)` once the link is gone.
pub struct BleTransport {
    runtime: tokio::runtime::Runtime,
    peripheral: Peripheral,
    request: Characteristic,
    responses: mpsc::Receiver<Vec<u8>>,
    pending: Vec<u8>,
    live: Arc<Mutex<Option<LiveMeasurement>>>,
    exponent: i8,
    label: String,
}

impl std::fmt::Debug for BleTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BleTransport")
            .field("label", &self.label)
            .field("exponent", &self.exponent)
            .finish_non_exhaustive()
    }
}

fn ble_error(context: &str, e: btleplug::Error) -> SylvacError {
    SylvacError::Ble(format!("{context}: {e}"))
}

fn uuid(text: &str) -> Result<Uuid, SylvacError> {
    Uuid::parse_str(text).map_err(|e| SylvacError::Ble(format!("UUID {text}: {e}")))
}

fn io_error(e: btleplug::Error) -> io::Error {
    match e {
        btleplug::Error::NotConnected | btleplug::Error::DeviceNotFound => {
            io::Error::new(io::ErrorKind::NotConnected, e.to_string())
        }
        btleplug::Error::TimedOut(_) => io::Error::new(io::ErrorKind::TimedOut, e.to_string()),
        other => io::Error::other(other.to_string()),
    }
}

impl BleTransport {
    /// Scans for the gauge, connects, discovers its services, reads the Measurement exponent
    /// (descriptor 0x2904; −9 if absent) and subscribes to RemoteResponse and Measurement.
    pub fn connect(config: &BleConfig) -> Result<Self, SylvacError> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .map_err(SylvacError::from)?;
        let (peripheral, label) = runtime.block_on(find(config))?;
        let opened = runtime.block_on(open(&peripheral, config.connect_timeout));
        let (request, stream, response_uuid, measurement_uuid, exponent) = match opened {
            Ok(o) => o,
            Err(e) => {
                let _ = runtime.block_on(peripheral.disconnect());
                return Err(e);
            }
        };
        let (tx, responses) = mpsc::channel();
        let live = Arc::new(Mutex::new(None));
        let latest = Arc::clone(&live);
        runtime.spawn(async move {
            let mut stream = stream;
            while let Some(n) = stream.next().await {
                if n.uuid == response_uuid {
                    if tx.send(n.value).is_err() {
                        break;
                    }
                } else if n.uuid == measurement_uuid
                    && let Ok(mm) = decode_measurement_mm(&n.value, exponent)
                    && let Ok(mut slot) = latest.lock()
                {
                    *slot = Some(LiveMeasurement { mm, at: Instant::now() });
                }
            }
            // stream ended: the link is gone; dropping `tx` makes `recv` report it
        });
        Ok(Self { runtime, peripheral, request, responses, pending: Vec::new(), live, exponent, label })
    }

    /// `<name> <address>` of the connected gauge.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The Measurement exponent in use (10^exponent m per count).
    pub fn exponent(&self) -> i8 {
        self.exponent
    }

    /// The latest Measurement notification, if any arrived.
    pub fn live_measurement(&self) -> Option<LiveMeasurement> {
        self.live.lock().ok().and_then(|l| *l)
    }
}

async fn find(config: &BleConfig) -> Result<(Peripheral, String), SylvacError> {
    let manager = Manager::new().await.map_err(|e| ble_error("Bluetooth manager (D-Bus)", e))?;
    let adapter = manager
        .adapters()
        .await
        .map_err(|e| ble_error("listing Bluetooth adapters", e))?
        .into_iter()
        .next()
        .ok_or_else(|| SylvacError::Ble("no Bluetooth adapter".to_owned()))?;
    adapter.start_scan(ScanFilter::default()).await.map_err(|e| ble_error("starting the scan", e))?;
    let started = Instant::now();
    loop {
        let peripherals = adapter.peripherals().await.map_err(|e| ble_error("scanning", e))?;
        for p in peripherals {
            let props = p.properties().await.ok().flatten();
            let name = props.and_then(|p| p.local_name.or(p.advertisement_name));
            let address = p.address().to_string();
            let found = match &config.target {
                BleTarget::Name(n) => name.as_deref() == Some(n.as_str()),
                BleTarget::Address(a) => address.eq_ignore_ascii_case(a),
            };
            if found {
                let _ = adapter.stop_scan().await;
                return Ok((p, format!("{} {address}", name.unwrap_or_default()).trim().to_owned()));
            }
        }
        if started.elapsed() >= config.scan_timeout {
            let _ = adapter.stop_scan().await;
            return Err(LinkError::Timeout {
                waiting_for: format!("a BLE gauge {}", config.target),
                after: config.scan_timeout,
            }
            .into());
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

type Notifications = std::pin::Pin<Box<dyn futures::Stream<Item = btleplug::api::ValueNotification> + Send>>;

async fn open(
    p: &Peripheral,
    timeout: Duration,
) -> Result<(Characteristic, Notifications, Uuid, Uuid, i8), SylvacError> {
    let timed_out = || {
        SylvacError::from(LinkError::Timeout { waiting_for: "the BLE connection".to_owned(), after: timeout })
    };
    tokio::time::timeout(timeout, p.connect())
        .await
        .map_err(|_| timed_out())?
        .map_err(|e| ble_error("connecting", e))?;
    tokio::time::timeout(timeout, p.discover_services())
        .await
        .map_err(|_| timed_out())?
        .map_err(|e| ble_error("discovering services", e))?;
    let (request_uuid, response_uuid, measurement_uuid) =
        (uuid(REMOTE_REQUEST_UUID)?, uuid(REMOTE_RESPONSE_UUID)?, uuid(MEASUREMENT_UUID)?);
    let characteristics = p.characteristics();
    let find = |u: Uuid| characteristics.iter().find(|c| c.uuid == u).cloned();
    let missing = |what: &str| {
        SylvacError::Ble(format!("no {what} characteristic: not a Sylvac Smart gauge in SIMPLE mode?"))
    };
    let request = find(request_uuid).ok_or_else(|| missing("RemoteRequest"))?;
    let response = find(response_uuid).ok_or_else(|| missing("RemoteResponse"))?;
    let measurement = find(measurement_uuid);
    let descriptor_uuid = btleplug::api::bleuuid::uuid_from_u16(PRESENTATION_FORMAT_DESCRIPTOR);
    let mut exponent = DEFAULT_EXPONENT;
    if let Some(d) =
        measurement.as_ref().and_then(|m| m.descriptors.iter().find(|d| d.uuid == descriptor_uuid))
        && let Ok(bytes) = p.read_descriptor(d).await
    {
        exponent = presentation_format_exponent(&bytes);
    }
    // take the stream before subscribing, so that no notification is missed
    let stream = p.notifications().await.map_err(|e| ble_error("notification stream", e))?;
    p.subscribe(&response).await.map_err(|e| ble_error("subscribing to RemoteResponse", e))?;
    if let Some(m) = &measurement {
        p.subscribe(m).await.map_err(|e| ble_error("subscribing to Measurement", e))?;
    }
    Ok((request, stream, response_uuid, measurement_uuid, exponent))
}

impl Transport for BleTransport {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        for chunk in bytes.chunks(MAX_NOTIFICATION_LEN) {
            self.runtime
                .block_on(self.peripheral.write(&self.request, chunk, WriteType::WithoutResponse))
                .map_err(io_error)?;
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if self.pending.is_empty() {
            match self.responses.recv_timeout(timeout) {
                Ok(n) => self.pending = n,
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    return Err(io::Error::new(io::ErrorKind::TimedOut, "no RemoteResponse notification"));
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => return Ok(0),
            }
        }
        let n = self.pending.len().min(buf.len());
        buf[..n].copy_from_slice(&self.pending[..n]);
        self.pending.drain(..n);
        Ok(n)
    }
}

impl Drop for BleTransport {
    fn drop(&mut self) {
        let _ = self.runtime.block_on(self.peripheral.disconnect());
    }
}

impl SylvacGauge<BleTransport> {
    /// Scans for the gauge, connects over BLE and identifies it like
    /// [`SylvacGauge::new`]. Errors name it `<config.name> at BLE <name> <address>`.
    pub fn connect_ble(ble: &BleConfig, config: SylvacConfig) -> Result<Self, SylvacError> {
        let transport = BleTransport::connect(ble)?;
        let label = format!("{} at BLE {}", config.name, transport.label());
        let mut gauge = Self::new(transport, config)?;
        gauge.set_label(label);
        Ok(gauge)
    }

    /// The latest value the gauge pushed on its Measurement characteristic.
    pub fn live_measurement(&self) -> Option<LiveMeasurement> {
        self.transport().live_measurement()
    }
}
