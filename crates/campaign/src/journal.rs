//! Crash-safe, append-only campaign journal.
//!
//! One record per line: `<fnv1a64 of the JSON, 16 hex digits> <JSON>\n`. The first record is
//! the [`JournalHeader`]; every later one a [`StepRecord`] for one completed plan step, written
//! with a single `write` and `fsync`ed before the campaign goes on. A record therefore either
//! exists completely or is the torn tail of a crash.
//!
//! On opening, every record is validated (checksum, JSON, step order). A torn **last** record
//! (no newline, bad checksum or unparsable) is dropped and the file truncated to the last good
//! record, so nothing half-written survives; a bad record anywhere else is corruption and an
//! error naming the line — never silently skipped.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use vatcal_core::{JointVector, MAX_JOINTS, Measurement, MeasurementContext, Target};

use crate::checksum::fnv1a64;

/// `format` of the header.
pub const JOURNAL_FORMAT: &str = "vatcal-campaign-journal";
/// `version` of the header.
pub const JOURNAL_VERSION: u32 = 1;

/// First record of a journal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JournalHeader {
    /// always [`JOURNAL_FORMAT`]
    pub format: String,
    /// always [`JOURNAL_VERSION`]
    pub version: u32,
    /// [`crate::CampaignPlan::fingerprint`] of the plan being executed
    pub plan_fingerprint: u64,
    /// number of steps of that plan
    pub plan_steps: usize,
    /// clock time of the campaign start [s since the clock's epoch]; `time_s` counts from it
    pub start_clock_s: f64,
    /// free text (cell, operator, seed, ...)
    pub note: String,
}

impl JournalHeader {
    /// A header for a plan with `plan_steps` steps and fingerprint `plan_fingerprint`.
    pub fn new(
        plan_fingerprint: u64,
        plan_steps: usize,
        start_clock_s: f64,
        note: impl Into<String>,
    ) -> Self {
        Self {
            format: JOURNAL_FORMAT.into(),
            version: JOURNAL_VERSION,
            plan_fingerprint,
            plan_steps,
            start_clock_s,
            note: note.into(),
        }
    }
}

/// The state of the cell when a step completed: enough to put the cell back exactly there.
///
/// Any serial chain: `joints` are the cell's joints q1..qN, `arm_from` and `dir` the arm's
/// joints (those of `vatcal_hardware_traits::JointLayout`: q2..q7 on the canonical cell, all
/// joints of a chain without a guide). On the canonical cell the JSON is that of the 7-joint
/// journals written before (`arm_from` and `dir` six values, `guide_from_mm` a number).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellState {
    /// joints reported at the end of the step (internal units: mm for prismatic, rad for
    /// revolute joints; canonical cell: q1 mm, q2..q7 rad)
    pub joints: JointVector,
    /// arm joints (internal units) before the last arm motion (the motion that reached
    /// `joints`)
    pub arm_from: JointVector,
    /// guide position \[mm\] before the last guide motion (`None`: the cell has no guide)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guide_from_mm: Option<f64>,
    /// sign of the last motion of each arm joint (0 = not moved since homing)
    pub dir: Vec<i8>,
    /// calibration position where the probe plate is
    pub placement: Option<u32>,
}

impl CellState {
    /// Motion directions per cell joint (index `i - 1` = joint i; the guide and unused entries
    /// 0): the arm's `dir` placed after the guide, if `joints` has one more value than the arm.
    pub fn cell_dirs(&self) -> [i8; MAX_JOINTS] {
        let offset = self.joints.len().saturating_sub(self.dir.len());
        let mut d = [0; MAX_JOINTS];
        for (slot, v) in d.iter_mut().skip(offset).zip(&self.dir) {
            *slot = *v;
        }
        d
    }
}

/// What a step produced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum StepOutcome {
    /// a move ended
    Moved,
    /// the plate was placed
    ProbePlaced {
        /// calibration position
        position: u32,
    },
    /// the probe was zeroed with the master ball
    ProbeZeroed {
        /// calibration position
        position: u32,
    },
    /// auto-centering converged; the joints in the state are the measurement
    Measured {
        /// calibration position
        position: u32,
        /// TCP id
        tcp: u32,
        /// final gauge readings \[mm\]
        readings_mm: [f64; 3],
        /// final offset in the probe frame (nominal axes) \[mm\]
        offset_mm: [f64; 3],
        /// the same offset in world axes (through the nominal placement) \[mm\]; the
        /// measurement's target is the calibration position plus this (absent in old journals)
        #[serde(default, skip_serializing_if = "Option::is_none")]
        offset_world_mm: Option<[f64; 3]>,
        /// corrective moves made
        iterations: usize,
        /// composite error after each reading \[mm\]
        composite_history_mm: Vec<f64>,
    },
    /// the tracker measured target `tcp`
    Tracked {
        /// TCP / SMR id
        tcp: u32,
        /// measured world position \[mm\]
        xyz_mm: [f64; 3],
    },
    /// the measurement was skipped (auto-centering refused) and the campaign went on
    Skipped {
        /// why
        reason: String,
    },
}

/// One completed plan step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepRecord {
    /// plan step index (0-based)
    pub step: usize,
    /// seconds since the campaign start when the step completed
    pub time_s: f64,
    /// cell temperature read by the thermometer when the step completed \[°C\] (measuring steps
    /// of a cell with a thermometer; absent in journals written without one)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_c: Option<f64>,
    /// cell state after the step
    pub state: CellState,
    /// what the step produced
    pub outcome: StepOutcome,
    /// the first step of a resumed run: the time since the previous record includes the stop,
    /// the recovery to the last recorded state and the restart, so it is not the step's own
    /// duration (timing models leave it out; absent = false)
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub resumed: bool,
}

impl StepRecord {
    /// The measurement this record holds, if any (probe or tracker), with `dir`, `time_s` and
    /// `temperature_c` (when recorded).
    pub fn measurement(&self) -> Option<Measurement> {
        let context = MeasurementContext {
            dir: Some(self.state.cell_dirs()),
            time_s: Some(self.time_s),
            temperature_c: self.temperature_c,
        };
        let (tcp, target) = match &self.outcome {
            StepOutcome::Measured { position, tcp, .. } => (*tcp, Target::Probe { position: *position }),
            StepOutcome::Tracked { tcp, xyz_mm } => (*tcp, Target::Tracker { xyz_mm: (*xyz_mm).into() }),
            _ => return None,
        };
        let probe_offset_mm = match &self.outcome {
            StepOutcome::Measured { offset_world_mm: Some(o), .. } => Some((*o).into()),
            _ => None,
        };
        Some(Measurement { tcp, q: self.state.joints, target, context, probe_offset_mm })
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "record", rename_all = "snake_case")]
enum Line {
    Header(JournalHeader),
    /// boxed: a step record is much larger than the header (12-joint vectors)
    Step(Box<StepRecord>),
}

/// Errors of the journal.
#[derive(Debug, thiserror::Error)]
pub enum JournalError {
    /// The file could not be read, written or synced.
    #[error("journal {path}: {source}")]
    Io {
        /// journal file
        path: PathBuf,
        /// cause
        source: std::io::Error,
    },
    /// A record before the last one is damaged, or the records are out of order.
    #[error(
        "journal {path}:{line}: corrupt record: {reason} (only a torn last record is dropped automatically)"
    )]
    Corrupt {
        /// journal file
        path: PathBuf,
        /// 1-based line
        line: usize,
        /// what is wrong
        reason: String,
    },
    /// The first record is not a journal header of this format/version.
    #[error("journal {path}: {reason}")]
    BadHeader {
        /// journal file
        path: PathBuf,
        /// what is wrong
        reason: String,
    },
    /// [`Journal::create`] on a file that already holds records.
    #[error("journal {path} already exists and is not empty (resume it, or choose another path)")]
    Exists {
        /// journal file
        path: PathBuf,
    },
    /// [`Journal::open`] on a file without a valid header.
    #[error("journal {path} has no header record")]
    NoHeader {
        /// journal file
        path: PathBuf,
    },
}

/// An open journal: its validated records and an append handle.
#[derive(Debug)]
pub struct Journal {
    path: PathBuf,
    file: File,
    header: JournalHeader,
    records: Vec<StepRecord>,
    torn_bytes_dropped: usize,
    /// `fsync` every appended record (the default); see [`Journal::set_sync_each_record`]
    sync_each_record: bool,
}

/// Encodes one line: checksum, space, JSON, newline.
fn encode(line: &Line) -> String {
    let json = serde_json::to_string(line).unwrap_or_default();
    format!("{:016x} {json}\n", fnv1a64(json.as_bytes()))
}

/// Decodes one line (without its newline).
fn decode(text: &str) -> Result<Line, String> {
    let (sum, json) = text.split_once(' ').ok_or("no checksum field")?;
    let sum = u64::from_str_radix(sum, 16).map_err(|_| format!("checksum `{sum}` is not hexadecimal"))?;
    let actual = fnv1a64(json.as_bytes());
    if sum != actual {
        return Err(format!("checksum mismatch (stored {sum:016x}, computed {actual:016x})"));
    }
    serde_json::from_str(json).map_err(|e| format!("invalid record: {e}"))
}

/// Valid lines of a journal file and the byte length they occupy.
struct Scan {
    lines: Vec<Line>,
    good_len: usize,
    torn_bytes: usize,
}

fn scan(path: &Path, bytes: &[u8]) -> Result<Scan, JournalError> {
    let mut lines = Vec::new();
    let mut pos = 0;
    let complete: Vec<&[u8]> = bytes.split_inclusive(|b| *b == b'\n').collect();
    let n = complete.len();
    for (i, raw) in complete.iter().enumerate() {
        let is_last = i + 1 == n;
        let terminated = raw.last() == Some(&b'\n');
        let parsed = if terminated {
            std::str::from_utf8(&raw[..raw.len() - 1]).map_err(|_| "not UTF-8".to_string()).and_then(decode)
        } else {
            Err("no newline (torn write)".to_string())
        };
        match parsed {
            Ok(line) => {
                lines.push(line);
                pos += raw.len();
            }
            Err(_) if is_last => break,
            Err(reason) => return Err(JournalError::Corrupt { path: path.into(), line: i + 1, reason }),
        }
    }
    Ok(Scan { lines, good_len: pos, torn_bytes: bytes.len() - pos })
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> JournalError + '_ {
    move |source| JournalError::Io { path: path.into(), source }
}

/// Makes a newly created file's directory entry durable.
fn sync_parent_dir(path: &Path) {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
        && let Ok(d) = File::open(dir)
    {
        let _ = d.sync_all();
    }
}

impl Journal {
    /// Creates a journal at `path` with `header` (an existing empty file is reused; one with
    /// content is [`JournalError::Exists`]).
    pub fn create(path: impl AsRef<Path>, header: JournalHeader) -> Result<Self, JournalError> {
        let path = path.as_ref();
        if std::fs::metadata(path).is_ok_and(|m| m.len() > 0) {
            return Err(JournalError::Exists { path: path.into() });
        }
        let mut file = OpenOptions::new().create(true).append(true).open(path).map_err(io(path))?;
        let line = encode(&Line::Header(header.clone()));
        file.write_all(line.as_bytes()).map_err(io(path))?;
        file.sync_all().map_err(io(path))?;
        sync_parent_dir(path);
        Ok(Self {
            path: path.into(),
            file,
            header,
            records: Vec::new(),
            torn_bytes_dropped: 0,
            sync_each_record: true,
        })
    }

    /// Opens an existing journal: validates every record, drops a torn last record (truncating
    /// the file), and checks the header and the step order.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, JournalError> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(io(path))?;
        let scan = scan(path, &bytes)?;
        let mut lines = scan.lines.into_iter();
        let header = match lines.next() {
            Some(Line::Header(h)) => h,
            Some(Line::Step(_)) => {
                return Err(JournalError::BadHeader {
                    path: path.into(),
                    reason: "line 1 is not a header record".into(),
                });
            }
            None => return Err(JournalError::NoHeader { path: path.into() }),
        };
        if header.format != JOURNAL_FORMAT || header.version != JOURNAL_VERSION {
            return Err(JournalError::BadHeader {
                path: path.into(),
                reason: format!(
                    "format `{}` version {} (expected `{JOURNAL_FORMAT}` version {JOURNAL_VERSION})",
                    header.format, header.version
                ),
            });
        }
        let mut records: Vec<StepRecord> = Vec::new();
        for (k, line) in lines.enumerate() {
            let line_no = k + 2;
            let Line::Step(r) = line else {
                return Err(JournalError::Corrupt {
                    path: path.into(),
                    line: line_no,
                    reason: "a second header".into(),
                });
            };
            if let Some(prev) = records.last()
                && r.step <= prev.step
            {
                return Err(JournalError::Corrupt {
                    path: path.into(),
                    line: line_no,
                    reason: format!("step {} after step {} (steps must increase)", r.step, prev.step),
                });
            }
            if r.step >= header.plan_steps {
                return Err(JournalError::Corrupt {
                    path: path.into(),
                    line: line_no,
                    reason: format!("step {} beyond the plan's {} steps", r.step, header.plan_steps),
                });
            }
            records.push(*r);
        }
        let file = OpenOptions::new().append(true).open(path).map_err(io(path))?;
        if scan.torn_bytes > 0 {
            file.set_len(scan.good_len as u64).map_err(io(path))?;
            file.sync_all().map_err(io(path))?;
        }
        Ok(Self {
            path: path.into(),
            file,
            header,
            records,
            torn_bytes_dropped: scan.torn_bytes,
            sync_each_record: true,
        })
    }

    /// Opens `path` if it holds a journal, otherwise creates it with `header` (a missing file,
    /// an empty one, or one whose only content is a torn header). Returns the journal and
    /// whether it was resumed.
    pub fn open_or_create(
        path: impl AsRef<Path>,
        header: JournalHeader,
    ) -> Result<(Self, bool), JournalError> {
        let path = path.as_ref();
        if !path.exists() {
            return Ok((Self::create(path, header)?, false));
        }
        match Self::open(path) {
            Ok(j) => Ok((j, true)),
            Err(JournalError::NoHeader { .. }) => {
                // only a torn header: nothing was recorded
                std::fs::write(path, b"").map_err(io(path))?;
                Ok((Self::create(path, header)?, false))
            }
            Err(e) => Err(e),
        }
    }

    /// Whether [`Journal::append`] `fsync`s every record (default `true`). Turning it off is
    /// meant for simulations only, where a record per few milliseconds makes the `fsync`s the
    /// dominant cost: records are still written with one `write` each (a killed process loses
    /// nothing, the operating system has them), but a power cut may lose the last ones. Call
    /// [`Journal::sync`] at the end.
    pub fn set_sync_each_record(&mut self, sync: bool) {
        self.sync_each_record = sync;
    }

    /// `fsync`s the journal file.
    pub fn sync(&mut self) -> Result<(), JournalError> {
        self.file.sync_data().map_err(io(&self.path))
    }

    /// Appends one record and `fsync`s it (unless turned off with
    /// [`Journal::set_sync_each_record`]).
    pub fn append(&mut self, record: StepRecord) -> Result<(), JournalError> {
        if let Some(prev) = self.records.last()
            && record.step <= prev.step
        {
            return Err(JournalError::Corrupt {
                path: self.path.clone(),
                line: self.records.len() + 2,
                reason: format!("refusing to append step {} after step {}", record.step, prev.step),
            });
        }
        let line = encode(&Line::Step(Box::new(record.clone())));
        self.file.write_all(line.as_bytes()).map_err(io(&self.path))?;
        if self.sync_each_record {
            self.file.sync_data().map_err(io(&self.path))?;
        }
        self.records.push(record);
        Ok(())
    }

    /// The header.
    pub fn header(&self) -> &JournalHeader {
        &self.header
    }

    /// The completed steps, in order.
    pub fn records(&self) -> &[StepRecord] {
        &self.records
    }

    /// The journal file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Bytes of a torn last record dropped when opening (0 if none).
    pub fn torn_bytes_dropped(&self) -> usize {
        self.torn_bytes_dropped
    }

    /// The plan step to execute next.
    pub fn next_step(&self) -> usize {
        self.records.last().map_or(0, |r| r.step + 1)
    }

    /// Every measurement recorded so far, in order.
    pub fn measurements(&self) -> Vec<Measurement> {
        self.records.iter().filter_map(StepRecord::measurement).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn record(step: usize, x: f64) -> StepRecord {
        StepRecord {
            step,
            time_s: 1.5 * step as f64,
            temperature_c: step.is_multiple_of(2).then_some(20.0 + 0.01 * step as f64),
            state: CellState {
                joints: JointVector::new([x, 0.1, -0.2, x / 3.0, 0.4, 1e-300, -0.6]),
                arm_from: JointVector::new([x; 6]),
                guide_from_mm: Some(x * 7.0),
                dir: vec![1, -1, 0, 1, 1, -1],
                placement: Some(2),
            },
            outcome: StepOutcome::Measured {
                position: 2,
                tcp: 3,
                readings_mm: [0.001, -0.002, x],
                offset_mm: [0.1, 0.2, 0.3],
                offset_world_mm: Some([0.3, -0.1, 0.2]),
                iterations: 3,
                composite_history_mm: vec![1.0, 0.05, 0.002],
            },
            resumed: step == 5,
        }
    }

    fn header() -> JournalHeader {
        JournalHeader::new(0xdead_beef_0123_4567, 100, 12.25, "test")
    }

    proptest! {
        // every case creates and fsyncs a file: few cases keep the suite fast
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// Records come back bit for bit (floats included).
        #[test]
        fn records_round_trip_exactly(xs in proptest::collection::vec(-1e6..1e6f64, 1..8)) {
            let dir = tempfile::tempdir().expect("tmp");
            let path = dir.path().join("j.log");
            let mut j = Journal::create(&path, header()).expect("create");
            let recs: Vec<StepRecord> = xs.iter().enumerate().map(|(i, x)| record(i * 2, *x / 3.0)).collect();
            for r in &recs {
                j.append(r.clone()).expect("append");
            }
            drop(j);
            let back = Journal::open(&path).expect("open");
            prop_assert_eq!(back.header(), &header());
            prop_assert_eq!(back.records(), &recs[..]);
            for (a, b) in back.records().iter().zip(&recs) {
                for (u, v) in a.state.joints.as_slice().iter().zip(b.state.joints.as_slice().iter()) {
                    prop_assert_eq!(u.to_bits(), v.to_bits());
                }
            }
        }
    }

    #[test]
    fn torn_last_record_is_dropped_and_truncated() {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("j.log");
        let mut j = Journal::create(&path, header()).expect("create");
        for i in 0..3 {
            j.append(record(i, 0.5)).expect("append");
        }
        drop(j);
        let full = std::fs::read(&path).expect("read");
        // every possible tear inside the last record
        let last_start = full[..full.len() - 1].iter().rposition(|b| *b == b'\n').expect("nl") + 1;
        for cut in last_start + 1..full.len() {
            std::fs::write(&path, &full[..cut]).expect("write");
            let mut j = Journal::open(&path).expect("open torn");
            assert_eq!(j.records().len(), 2, "cut at {cut}");
            assert_eq!(j.next_step(), 2);
            assert_eq!(j.torn_bytes_dropped(), cut - last_start);
            // appending continues on a clean line
            j.append(record(2, 0.75)).expect("append");
            drop(j);
            let j = Journal::open(&path).expect("reopen");
            assert_eq!(j.records().len(), 3);
            assert_eq!(j.torn_bytes_dropped(), 0);
            assert_eq!(j.records()[2], record(2, 0.75));
        }
    }

    #[test]
    fn corrupted_last_record_with_newline_is_dropped() {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("j.log");
        let mut j = Journal::create(&path, header()).expect("create");
        j.append(record(0, 0.5)).expect("append");
        j.append(record(1, 0.5)).expect("append");
        drop(j);
        let mut text = std::fs::read_to_string(&path).expect("read");
        let n = text.len();
        text.replace_range(n - 10..n - 9, "X");
        std::fs::write(&path, text).expect("write");
        assert_eq!(Journal::open(&path).expect("open").records().len(), 1);
    }

    #[test]
    fn corruption_before_the_end_is_an_error_naming_the_line() {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("j.log");
        let mut j = Journal::create(&path, header()).expect("create");
        for i in 0..3 {
            j.append(record(i, 0.5)).expect("append");
        }
        drop(j);
        let text = std::fs::read_to_string(&path).expect("read");
        let damaged = text.replacen("\"tcp\":3", "\"tcp\":4", 1);
        std::fs::write(&path, damaged).expect("write");
        let e = Journal::open(&path).expect_err("corrupt");
        assert!(matches!(e, JournalError::Corrupt { line: 2, .. }), "{e}");
        assert!(e.to_string().contains(":2:") && e.to_string().contains("checksum"), "{e}");
    }

    #[test]
    fn out_of_order_steps_and_bad_headers_are_refused() {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("j.log");
        let mut j = Journal::create(&path, header()).expect("create");
        j.append(record(5, 0.5)).expect("append");
        assert!(j.append(record(5, 0.5)).is_err(), "duplicate step");
        assert!(matches!(Journal::create(&path, header()), Err(JournalError::Exists { .. })));
        let other = dir.path().join("other.log");
        std::fs::write(&other, encode(&Line::Step(Box::new(record(0, 0.1))))).expect("write");
        assert!(matches!(Journal::open(&other), Err(JournalError::BadHeader { .. })));
        // a header torn at creation: nothing recorded, open_or_create starts afresh
        let torn = dir.path().join("torn.log");
        std::fs::write(&torn, &encode(&Line::Header(header()))[..20]).expect("write");
        let (j, resumed) = Journal::open_or_create(&torn, header()).expect("recreate");
        assert!(!resumed && j.records().is_empty());
    }

    #[test]
    fn unsynced_records_are_written_one_by_one_and_read_back() {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("j.log");
        let mut j = Journal::create(&path, header()).expect("create");
        j.set_sync_each_record(false);
        for i in 0..3 {
            j.append(record(i, 0.25 * i as f64)).expect("append");
            // already in the file (one write per record), before any sync
            let lines = std::fs::read_to_string(&path).expect("read").lines().count();
            assert_eq!(lines, 2 + i);
        }
        j.sync().expect("sync");
        let written = j.records().to_vec();
        drop(j);
        assert_eq!(Journal::open(&path).expect("open").records(), written.as_slice());
    }

    #[test]
    fn measurements_carry_joints_dir_and_time() {
        let r = record(4, 0.5);
        let m = r.measurement().expect("measurement");
        assert_eq!(m.position(), Some(2));
        assert_eq!(m.tcp, 3);
        assert_eq!(
            m.context.dir,
            Some(vatcal_core::measurement::dirs_from_meca500_arm([1, -1, 0, 1, 1, -1]))
        );
        assert_eq!(m.context.time_s, Some(6.0));
        assert_eq!(m.context.temperature_c, Some(20.04));
        assert_eq!(record(3, 0.5).measurement().expect("measurement").context.temperature_c, None);
        let moved = StepRecord { outcome: StepOutcome::Moved, ..r };
        assert!(moved.measurement().is_none());
    }

    #[test]
    fn journals_without_a_temperature_still_read() {
        // a record written before the thermometer existed: no `temperature_c` key
        let mut r = record(1, 0.5);
        r.temperature_c = None;
        let json = serde_json::to_string(&Line::Step(Box::new(r.clone()))).expect("json");
        assert!(!json.contains("temperature_c"), "{json}");
        let back: Line = serde_json::from_str(&json).expect("read");
        assert_eq!(back, Line::Step(Box::new(r)));
    }

    #[test]
    fn canonical_state_json_is_unchanged_and_other_chains_have_no_guide() {
        // the JSON of a canonical record as the 7-joint journals wrote it
        let r = record(1, 0.5);
        let json = serde_json::to_string(&r.state).expect("json");
        assert_eq!(
            json,
            "{\"joints\":[0.5,0.1,-0.2,0.16666666666666666,0.4,1e-300,-0.6],\"arm_from\":[0.5,0.5,0.5,0.5,0.5,0.5],\
             \"guide_from_mm\":3.5,\"dir\":[1,-1,0,1,1,-1],\"placement\":2}"
        );
        assert_eq!(
            r.state.cell_dirs(),
            vatcal_core::measurement::dirs_from_meca500_arm([1, -1, 0, 1, 1, -1])
        );
        // a six-joint arm without a guide: dir1..dir6, no guide field
        let state = CellState {
            joints: JointVector::new([0.1, 0.2, 0.3, 0.4, 0.5, 0.6]),
            arm_from: JointVector::new([0.0; 6]),
            guide_from_mm: None,
            dir: vec![1, -1, 1, -1, 1, -1],
            placement: None,
        };
        let json = serde_json::to_string(&state).expect("json");
        assert!(!json.contains("guide_from_mm"), "{json}");
        assert_eq!(serde_json::from_str::<CellState>(&json).expect("back"), state);
        assert_eq!(state.cell_dirs()[..7], [1, -1, 1, -1, 1, -1, 0]);
    }
}
