//! # vatcal-io
//!
//! Reading and writing the CSV files of `docs/formats.md`:
//!
//! | file | columns | reader | writer |
//! |---|---|---|---|
//! | joint rows | `tcp,q1..q7` | [`read_joint_rows`] | [`write_joint_rows`] |
//! | probe measurements | `position,tcp,q1..q7` (+ `time_s`, `temperature_c`, `dir2..dir7`, `offset_x_mm,offset_y_mm,offset_z_mm`) | [`read_probe_measurements`] | [`write_measurements`] |
//! | tracker measurements | `tcp,q1..q7,x,y,z` | [`read_tracker_measurements`] | [`write_measurements`] |
//! | candidate poses | `position,tcp,q1..q7` | [`read_candidates`] | [`CandidateTable::write_subset`] |
//! | pose requests | `tcp,q1,x,y,z,alpha,beta,gamma` (+ `time_s`, `temperature_c`, `dir2..dir7`) | [`read_pose_rows`] | (`vatcal compensate`) |
//!
//! Rules: a header line, columns found by name in any order, unknown columns ignored, `#`
//! comment lines and blank lines skipped, `q1` in mm and `q2..q7` in degrees. A bad row is an
//! error naming the file, the line, the column and the reason ([`IoError::Row`]); nothing is
//! silently dropped. Numbers are written with Rust's shortest round-trip formatting.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use vatcal_core::{JointVector, Measurement, MeasurementContext, Target};
use vatcal_kinematics::Model;

/// Errors of the CSV layer.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened, read or written.
    #[error("{path}: {cause}")]
    File {
        /// file
        path: PathBuf,
        /// cause (kept out of the error chain: the message already states it)
        cause: std::io::Error,
    },
    /// The CSV structure is broken (e.g. a row with the wrong number of fields).
    #[error("{path}:{line}: malformed CSV: {message}")]
    Csv {
        /// file
        path: PathBuf,
        /// 1-based line
        line: u64,
        /// csv's message
        message: String,
    },
    /// A required column is missing from the header.
    #[error("{path}: missing column `{column}` in the header (required columns: {required})")]
    MissingColumn {
        /// file
        path: PathBuf,
        /// the missing column
        column: String,
        /// all required columns
        required: String,
    },
    /// A field of a row is invalid.
    #[error("{path}:{line}: column `{column}`: {reason}")]
    Row {
        /// file
        path: PathBuf,
        /// 1-based line number
        line: u64,
        /// column name
        column: String,
        /// what is wrong
        reason: String,
    },
    /// The model has an effect that depends on a context column the file does not have.
    #[error("{path}: the model's {effect} needs the column(s) {columns}, which the file does not have")]
    ModelNeedsColumn {
        /// file
        path: PathBuf,
        /// the missing column(s), e.g. `dir2..dir7`
        columns: String,
        /// the effect that needs them, e.g. `joint-backlash (joint 3)`
        effect: String,
    },
    /// The file has a header but no data rows.
    #[error("{path}: no data rows")]
    Empty {
        /// file
        path: PathBuf,
    },
}

/// One row of a joint-row file.
#[derive(Debug, Clone, PartialEq)]
pub struct JointRow {
    /// 1-based line number in the file
    pub line: u64,
    /// TCP id
    pub tcp: u32,
    /// joints (internal units)
    pub q: JointVector,
    /// the optional `time_s`, `temperature_c`, `dir2..dir7` columns of the row
    pub context: MeasurementContext,
}

const JOINT_COLUMNS: [&str; 7] = ["q1", "q2", "q3", "q4", "q5", "q6", "q7"];

/// A parsed CSV table with a name → index header map.
struct Table {
    path: PathBuf,
    headers: csv::StringRecord,
    index: HashMap<String, usize>,
    rows: Vec<(u64, csv::StringRecord)>,
}

impl Table {
    fn read(path: &Path, required: &[&str]) -> Result<Table, IoError> {
        let file =
            std::fs::File::open(path).map_err(|source| IoError::File { path: path.into(), cause: source })?;
        let mut rdr = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .flexible(false)
            .from_reader(file);
        let headers = rdr.headers().map_err(|e| csv_error(path, &e))?.clone();
        let index: HashMap<String, usize> =
            headers.iter().enumerate().map(|(i, h)| (h.to_string(), i)).collect();
        for col in required {
            if !index.contains_key(*col) {
                return Err(IoError::MissingColumn {
                    path: path.into(),
                    column: (*col).to_string(),
                    required: required.join(","),
                });
            }
        }
        let mut rows = Vec::new();
        for rec in rdr.records() {
            let rec = rec.map_err(|e| csv_error(path, &e))?;
            if rec.iter().all(|f| f.is_empty()) {
                continue;
            }
            let line = rec.position().map_or(0, |p| p.line());
            rows.push((line, rec));
        }
        if rows.is_empty() {
            return Err(IoError::Empty { path: path.into() });
        }
        Ok(Table { path: path.into(), headers, index, rows })
    }

    /// Fails when an effect of `model` depends on a context column (`dir2..dir7`, `time_s`,
    /// `temperature_c`) that the file lacks, or that is empty on some row: predictions there
    /// would silently use 0.
    fn check_model_columns(&self, model: &Model) -> Result<(), IoError> {
        for spec in model.effects() {
            let columns = vatcal_kinematics::effects::context_columns(spec);
            if columns.is_empty() {
                continue;
            }
            let missing = columns.iter().any(|c| !self.has(c));
            if missing {
                let columns = if columns.len() > 1 {
                    format!("{}..{}", columns[0], columns[columns.len() - 1])
                } else {
                    columns[0].to_string()
                };
                return Err(IoError::ModelNeedsColumn {
                    path: self.path.clone(),
                    columns,
                    effect: spec.label(),
                });
            }
            for (line, rec) in &self.rows {
                if let Some(col) = columns.iter().find(|c| self.field(rec, c).is_none_or(str::is_empty)) {
                    return Err(self.err(
                        *line,
                        col,
                        format!("empty, but the model's {} needs it", spec.label()),
                    ));
                }
            }
        }
        Ok(())
    }

    fn has(&self, col: &str) -> bool {
        self.index.contains_key(col)
    }

    fn field<'a>(&self, rec: &'a csv::StringRecord, col: &str) -> Option<&'a str> {
        self.index.get(col).and_then(|i| rec.get(*i))
    }

    fn err(&self, line: u64, column: &str, reason: impl Into<String>) -> IoError {
        IoError::Row { path: self.path.clone(), line, column: column.into(), reason: reason.into() }
    }

    fn float(&self, line: u64, rec: &csv::StringRecord, col: &str) -> Result<f64, IoError> {
        let s = self.field(rec, col).unwrap_or("");
        if s.is_empty() {
            return Err(self.err(line, col, "empty field"));
        }
        let v: f64 = s.parse().map_err(|_| self.err(line, col, format!("`{s}` is not a number")))?;
        if !v.is_finite() {
            return Err(self.err(line, col, format!("`{s}` is not finite")));
        }
        Ok(v)
    }

    fn optional_float(&self, line: u64, rec: &csv::StringRecord, col: &str) -> Result<Option<f64>, IoError> {
        match self.field(rec, col) {
            None | Some("") => Ok(None),
            Some(_) => self.float(line, rec, col).map(Some),
        }
    }

    fn id(&self, line: u64, rec: &csv::StringRecord, col: &str, known: &[u32]) -> Result<u32, IoError> {
        let s = self.field(rec, col).unwrap_or("");
        let v: u32 =
            s.parse().map_err(|_| self.err(line, col, format!("`{s}` is not a non-negative integer id")))?;
        if !known.contains(&v) {
            return Err(self.err(line, col, format!("unknown {col} id {v} (the model has {known:?})")));
        }
        Ok(v)
    }

    fn joints(&self, line: u64, rec: &csv::StringRecord, model: &Model) -> Result<JointVector, IoError> {
        let mut arm = [0.0; 6];
        let q1 = self.float(line, rec, "q1")?;
        for (k, col) in JOINT_COLUMNS[1..].iter().enumerate() {
            arm[k] = self.float(line, rec, col)?;
        }
        let q = JointVector::from_mm_deg(q1, arm);
        if let Some((joint, _, lo, hi)) = model.limit_violation(&q) {
            let file_units = q.to_mm_deg();
            let (lo, hi) = if joint == 1 { (lo, hi) } else { (lo.to_degrees(), hi.to_degrees()) };
            let unit = if joint == 1 { "mm" } else { "deg" };
            return Err(self.err(
                line,
                JOINT_COLUMNS[joint - 1],
                format!("{} {unit} is outside the joint limits [{lo}, {hi}] {unit}", file_units[joint - 1]),
            ));
        }
        Ok(q)
    }

    fn context(&self, line: u64, rec: &csv::StringRecord) -> Result<MeasurementContext, IoError> {
        let time_s = self.optional_float(line, rec, "time_s")?;
        let temperature_c = self.optional_float(line, rec, "temperature_c")?;
        let dir_cols = ["dir2", "dir3", "dir4", "dir5", "dir6", "dir7"];
        let dir = if dir_cols.iter().all(|c| self.has(c)) {
            let mut d = [0i8; 6];
            for (k, col) in dir_cols.iter().enumerate() {
                let v = self.float(line, rec, col)?;
                d[k] = match v {
                    1.0 => 1,
                    -1.0 => -1,
                    0.0 => 0,
                    _ => return Err(self.err(line, col, format!("direction must be +1, -1 or 0, got {v}"))),
                };
            }
            Some(d)
        } else {
            None
        };
        Ok(MeasurementContext { dir, time_s, temperature_c })
    }

    /// The optional final centring offset `offset_x_mm,offset_y_mm,offset_z_mm` (world axes) of
    /// a probe row: all three present or all three empty/absent.
    fn probe_offset(&self, line: u64, rec: &csv::StringRecord) -> Result<Option<Vector3<f64>>, IoError> {
        let v: Vec<Option<f64>> =
            OFFSET_COLUMNS.iter().map(|c| self.optional_float(line, rec, c)).collect::<Result<_, _>>()?;
        match (v[0], v[1], v[2]) {
            (Some(x), Some(y), Some(z)) => Ok(Some(Vector3::new(x, y, z))),
            (None, None, None) => Ok(None),
            _ => {
                let k = v.iter().position(Option::is_none).unwrap_or(0);
                Err(self.err(
                    line,
                    OFFSET_COLUMNS[k],
                    "the centring offset needs all three of offset_x_mm, offset_y_mm, offset_z_mm",
                ))
            }
        }
    }
}

/// The optional per-row centring offset columns of probe measurements (world axes, mm).
pub const OFFSET_COLUMNS: [&str; 3] = ["offset_x_mm", "offset_y_mm", "offset_z_mm"];

fn csv_error(path: &Path, e: &csv::Error) -> IoError {
    let line = e.position().map_or(0, |p| p.line());
    IoError::Csv { path: path.into(), line, message: e.to_string() }
}

/// Reads `tcp,q1..q7` rows (input of `vatcal fk` / `vatcal torque`) with the optional
/// `time_s`, `temperature_c`, `dir2..dir7` columns; TCP ids are checked against the model,
/// joints against its limits, and the context columns its effects need must be present
/// ([`IoError::ModelNeedsColumn`]).
///
/// # Examples
/// ```
/// use vatcal_core::CellFile;
/// use vatcal_io::read_joint_rows;
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// let rows = read_joint_rows(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/joints-example.csv"), &model)?;
/// assert_eq!(rows.len(), 3);
/// // file units (q1 mm, q2..q7 deg) become internal units (mm, rad)
/// assert_eq!((rows[1].line, rows[1].tcp), (4, 2));
/// assert!((rows[1].q.get(2) - 10f64.to_radians()).abs() < 1e-15);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`IoError::File`] (cannot read), [`IoError::Csv`] (broken CSV), [`IoError::MissingColumn`],
/// [`IoError::Empty`] (no data rows), [`IoError::Row`] naming the line and column of a bad value
/// (not a number, an unknown TCP id, a joint outside its limits, a bad context value), and
/// [`IoError::ModelNeedsColumn`] when the model's effects need context columns the file lacks.
pub fn read_joint_rows(path: impl AsRef<Path>, model: &Model) -> Result<Vec<JointRow>, IoError> {
    let path = path.as_ref();
    let required = ["tcp", "q1", "q2", "q3", "q4", "q5", "q6", "q7"];
    let t = Table::read(path, &required)?;
    t.check_model_columns(model)?;
    let tcps = model.tcp_ids();
    t.rows
        .iter()
        .map(|(line, rec)| {
            Ok(JointRow {
                line: *line,
                tcp: t.id(*line, rec, "tcp", &tcps)?,
                q: t.joints(*line, rec, model)?,
                context: t.context(*line, rec)?,
            })
        })
        .collect()
}

/// Reads probe measurements `position,tcp,q1..q7` with the optional `time_s`,
/// `temperature_c`, `dir2..dir7` columns.
///
/// # Errors
/// As [`read_joint_rows`]; the `position` id is checked against the model too.
pub fn read_probe_measurements(path: impl AsRef<Path>, model: &Model) -> Result<Vec<Measurement>, IoError> {
    let path = path.as_ref();
    let required = ["position", "tcp", "q1", "q2", "q3", "q4", "q5", "q6", "q7"];
    let t = Table::read(path, &required)?;
    t.check_model_columns(model)?;
    let (tcps, positions) = (model.tcp_ids(), model.position_ids());
    t.rows
        .iter()
        .map(|(line, rec)| {
            let position = t.id(*line, rec, "position", &positions)?;
            Ok(Measurement {
                tcp: t.id(*line, rec, "tcp", &tcps)?,
                q: t.joints(*line, rec, model)?,
                target: Target::Probe { position },
                context: t.context(*line, rec)?,
                probe_offset_mm: t.probe_offset(*line, rec)?,
            })
        })
        .collect()
}

/// Reads tracker measurements `tcp,q1..q7,x,y,z` (world, mm), with the same optional columns.
///
/// # Errors
/// As [`read_joint_rows`]; `x,y,z` must be finite numbers.
pub fn read_tracker_measurements(path: impl AsRef<Path>, model: &Model) -> Result<Vec<Measurement>, IoError> {
    let path = path.as_ref();
    let required = ["tcp", "q1", "q2", "q3", "q4", "q5", "q6", "q7", "x", "y", "z"];
    let t = Table::read(path, &required)?;
    t.check_model_columns(model)?;
    let tcps = model.tcp_ids();
    t.rows
        .iter()
        .map(|(line, rec)| {
            let xyz =
                Vector3::new(t.float(*line, rec, "x")?, t.float(*line, rec, "y")?, t.float(*line, rec, "z")?);
            Ok(Measurement {
                tcp: t.id(*line, rec, "tcp", &tcps)?,
                q: t.joints(*line, rec, model)?,
                target: Target::Tracker { xyz_mm: xyz },
                context: t.context(*line, rec)?,
                probe_offset_mm: None,
            })
        })
        .collect()
}

/// Reads a file that may hold probe rows (`position` column) or tracker rows (`x,y,z`), or
/// both kinds mixed (a row with an empty `position` and filled `x,y,z` is a tracker row).
pub fn read_measurements(path: impl AsRef<Path>, model: &Model) -> Result<Vec<Measurement>, IoError> {
    let path = path.as_ref();
    let t = Table::read(path, &["tcp", "q1", "q2", "q3", "q4", "q5", "q6", "q7"])?;
    t.check_model_columns(model)?;
    let (tcps, positions) = (model.tcp_ids(), model.position_ids());
    let has_xyz = t.has("x") && t.has("y") && t.has("z");
    if !t.has("position") && !has_xyz {
        return Err(IoError::MissingColumn {
            path: path.into(),
            column: "position (probe rows) or x,y,z (tracker rows)".into(),
            required: "tcp,q1..q7 and position or x,y,z".into(),
        });
    }
    t.rows
        .iter()
        .map(|(line, rec)| {
            let has_pos = t.field(rec, "position").is_some_and(|s| !s.is_empty());
            let target = if has_pos {
                Target::Probe { position: t.id(*line, rec, "position", &positions)? }
            } else {
                Target::Tracker {
                    xyz_mm: Vector3::new(
                        t.float(*line, rec, "x")?,
                        t.float(*line, rec, "y")?,
                        t.float(*line, rec, "z")?,
                    ),
                }
            };
            let probe_offset_mm = if has_pos { t.probe_offset(*line, rec)? } else { None };
            Ok(Measurement {
                tcp: t.id(*line, rec, "tcp", &tcps)?,
                q: t.joints(*line, rec, model)?,
                target,
                context: t.context(*line, rec)?,
                probe_offset_mm,
            })
        })
        .collect()
}

/// A candidate-pose table: the parsed measurements plus the raw rows, so a selection can be
/// written back with exactly the input's columns.
#[derive(Debug, Clone)]
pub struct CandidateTable {
    /// the header of the input
    pub headers: csv::StringRecord,
    /// the raw rows, in input order
    pub records: Vec<csv::StringRecord>,
    /// 1-based line numbers of the rows
    pub lines: Vec<u64>,
    /// the candidates as probe measurements (the target is the calibration position)
    pub measurements: Vec<Measurement>,
}

/// Reads candidate poses `position,tcp,q1..q7` (other columns kept verbatim).
pub fn read_candidates(path: impl AsRef<Path>, model: &Model) -> Result<CandidateTable, IoError> {
    let path = path.as_ref();
    let required = ["position", "tcp", "q1", "q2", "q3", "q4", "q5", "q6", "q7"];
    let t = Table::read(path, &required)?;
    let (tcps, positions) = (model.tcp_ids(), model.position_ids());
    let mut measurements = Vec::with_capacity(t.rows.len());
    for (line, rec) in &t.rows {
        let position = t.id(*line, rec, "position", &positions)?;
        measurements.push(Measurement {
            tcp: t.id(*line, rec, "tcp", &tcps)?,
            q: t.joints(*line, rec, model)?,
            target: Target::Probe { position },
            context: t.context(*line, rec)?,
            probe_offset_mm: t.probe_offset(*line, rec)?,
        });
    }
    Ok(CandidateTable {
        headers: t.headers.clone(),
        lines: t.rows.iter().map(|r| r.0).collect(),
        records: t.rows.into_iter().map(|r| r.1).collect(),
        measurements,
    })
}

impl CandidateTable {
    /// Writes the rows at `indices` (in that order) with the input's header and columns.
    pub fn write_subset(&self, path: impl AsRef<Path>, indices: &[usize]) -> Result<(), IoError> {
        let path = path.as_ref();
        let mut w = writer(path)?;
        w.write_record(&self.headers).map_err(|e| csv_error(path, &e))?;
        for &i in indices {
            if let Some(rec) = self.records.get(i) {
                w.write_record(rec).map_err(|e| csv_error(path, &e))?;
            }
        }
        w.flush().map_err(|source| IoError::File { path: path.into(), cause: source })
    }
}

fn writer(path: &Path) -> Result<csv::Writer<std::fs::File>, IoError> {
    let f =
        std::fs::File::create(path).map_err(|source| IoError::File { path: path.into(), cause: source })?;
    Ok(csv::Writer::from_writer(f))
}

fn joint_fields(q: &JointVector) -> Vec<String> {
    q.to_mm_deg().iter().map(|v| v.to_string()).collect()
}

/// Writes `tcp,q1..q7` rows.
pub fn write_joint_rows(path: impl AsRef<Path>, rows: &[(u32, JointVector)]) -> Result<(), IoError> {
    let path = path.as_ref();
    let mut w = writer(path)?;
    let mut header = vec!["tcp".to_string()];
    header.extend(JOINT_COLUMNS.iter().map(|s| s.to_string()));
    w.write_record(&header).map_err(|e| csv_error(path, &e))?;
    for (tcp, q) in rows {
        let mut rec = vec![tcp.to_string()];
        rec.extend(joint_fields(q));
        w.write_record(&rec).map_err(|e| csv_error(path, &e))?;
    }
    w.flush().map_err(|source| IoError::File { path: path.into(), cause: source })
}

/// Renders measurements as CSV text (see [`write_measurements`]).
pub fn measurements_to_csv(measurements: &[Measurement]) -> String {
    let any_probe = measurements.iter().any(|m| matches!(m.target, Target::Probe { .. }));
    let any_tracker = measurements.iter().any(|m| matches!(m.target, Target::Tracker { .. }));
    let time = measurements.iter().any(|m| m.context.time_s.is_some());
    let temp = measurements.iter().any(|m| m.context.temperature_c.is_some());
    let dir = measurements.iter().any(|m| m.context.dir.is_some());
    let offset = measurements.iter().any(|m| m.probe_offset_mm.is_some());
    let mut header: Vec<&str> = Vec::new();
    if any_probe {
        header.push("position");
    }
    header.push("tcp");
    header.extend(JOINT_COLUMNS);
    if any_tracker {
        header.extend(["x", "y", "z"]);
    }
    if time {
        header.push("time_s");
    }
    if temp {
        header.push("temperature_c");
    }
    if dir {
        header.extend(["dir2", "dir3", "dir4", "dir5", "dir6", "dir7"]);
    }
    if offset {
        header.extend(OFFSET_COLUMNS);
    }
    let mut out = header.join(",");
    out.push('\n');
    for m in measurements {
        let mut rec: Vec<String> = Vec::with_capacity(header.len());
        if any_probe {
            rec.push(m.position().map(|p| p.to_string()).unwrap_or_default());
        }
        rec.push(m.tcp.to_string());
        rec.extend(joint_fields(&m.q));
        if any_tracker {
            match m.target {
                Target::Tracker { xyz_mm } => rec.extend(xyz_mm.iter().map(|v| v.to_string())),
                Target::Probe { .. } => rec.extend([String::new(), String::new(), String::new()]),
            }
        }
        if time {
            rec.push(m.context.time_s.map(|v| v.to_string()).unwrap_or_default());
        }
        if temp {
            rec.push(m.context.temperature_c.map(|v| v.to_string()).unwrap_or_default());
        }
        if dir {
            match m.context.dir {
                Some(d) => rec.extend(d.iter().map(|v| v.to_string())),
                None => rec.extend(std::iter::repeat_n(String::new(), 6)),
            }
        }
        if offset {
            match m.probe_offset_mm {
                Some(o) => rec.extend(o.iter().map(|v| v.to_string())),
                None => rec.extend(std::iter::repeat_n(String::new(), 3)),
            }
        }
        out.push_str(&rec.join(","));
        out.push('\n');
    }
    out
}

/// Writes probe and/or tracker measurements with every column they use: `position` (probe),
/// `tcp`, `q1..q7` (mm/deg), `x,y,z` (tracker), `time_s`, `temperature_c`, `dir2..dir7`.
///
/// # Examples
/// A measurement written and read back is bit-identical (shortest round-trip formatting):
/// ```
/// use vatcal_core::{CellFile, JointVector, Measurement};
/// use vatcal_io::{read_tracker_measurements, write_measurements};
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
/// let m = Measurement::tracker(1, q, model.tcp_position(&q, 1)?);
/// let path = std::env::temp_dir().join(format!("vatcal-io-doctest-{}.csv", std::process::id()));
/// write_measurements(&path, &[m])?;
/// assert_eq!(read_tracker_measurements(&path, &model)?, vec![m]);
/// std::fs::remove_file(&path)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`IoError::File`] when the file cannot be written.
pub fn write_measurements(path: impl AsRef<Path>, measurements: &[Measurement]) -> Result<(), IoError> {
    let path = path.as_ref();
    std::fs::write(path, measurements_to_csv(measurements))
        .map_err(|source| IoError::File { path: path.into(), cause: source })
}

/// One row of a pose-request file (`vatcal compensate`): the TCP `tcp` must reach the world
/// point `x,y,z` \[mm\] with the tool-changer frame at Mecademic Euler angles
/// `alpha,beta,gamma` \[deg\] (intrinsic X-Y-Z), the guide at `q1` \[mm\].
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRow {
    /// 1-based line number in the file
    pub line: u64,
    /// TCP id
    pub tcp: u32,
    /// guide position \[mm\]
    pub q1_mm: f64,
    /// TCP point in the world \[mm\]
    pub xyz_mm: [f64; 3],
    /// tool-changer frame orientation, intrinsic X-Y-Z Euler angles \[deg\]
    pub abc_deg: [f64; 3],
    /// optional `time_s`, `temperature_c`, `dir2..dir7`
    pub context: MeasurementContext,
}

/// Reads pose requests `tcp,q1,x,y,z,alpha,beta,gamma` with the optional `time_s`,
/// `temperature_c`, `dir2..dir7` columns; TCP ids are checked against the model and `q1`
/// against the guide limits.
pub fn read_pose_rows(path: impl AsRef<Path>, model: &Model) -> Result<Vec<PoseRow>, IoError> {
    let path = path.as_ref();
    let required = ["tcp", "q1", "x", "y", "z", "alpha", "beta", "gamma"];
    let t = Table::read(path, &required)?;
    let tcps = model.tcp_ids();
    let (lo, hi) = model.joint_limits()[0];
    t.rows
        .iter()
        .map(|(line, rec)| {
            let line = *line;
            let tcp = t.id(line, rec, "tcp", &tcps)?;
            let q1_mm = t.float(line, rec, "q1")?;
            if !(lo..=hi).contains(&q1_mm) {
                return Err(t.err(
                    line,
                    "q1",
                    format!("{q1_mm} mm is outside the guide limits [{lo}, {hi}] mm"),
                ));
            }
            let f = |c: &str| t.float(line, rec, c);
            Ok(PoseRow {
                line,
                tcp,
                q1_mm,
                xyz_mm: [f("x")?, f("y")?, f("z")?],
                abc_deg: [f("alpha")?, f("beta")?, f("gamma")?],
                context: t.context(line, rec)?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;
    use vatcal_core::CellFile;

    fn model() -> Model {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
            .expect("fixture");
        Model::from_cell(&cell).expect("model")
    }

    fn file(text: &str) -> tempfile::NamedTempFile {
        let mut f = tempfile::NamedTempFile::new().expect("tmp");
        f.write_all(text.as_bytes()).expect("write");
        f
    }

    #[test]
    fn reads_columns_by_name_skips_comments_and_round_trips() {
        let m = model();
        let f = file(
            "# comment\nq1,tcp,q2,q3,q4,q5,q6,q7,extra,position,time_s\n\n100,2,10,20,-30,40,50,60,zzz,3,1.5\n",
        );
        let ms = read_probe_measurements(f.path(), &m).expect("ok");
        assert_eq!(ms.len(), 1);
        assert_eq!(ms[0].tcp, 2);
        assert_eq!(ms[0].position(), Some(3));
        assert_eq!(ms[0].context.time_s, Some(1.5));
        assert!((ms[0].q.get(4).to_degrees() - (-30.0)).abs() < 1e-12);
        let out = tempfile::NamedTempFile::new().expect("tmp");
        write_measurements(out.path(), &ms).expect("write");
        let back = read_probe_measurements(out.path(), &m).expect("reread");
        assert_eq!(back, ms);
    }

    #[test]
    fn pose_rows_read_by_name_with_context_and_named_errors() {
        let m = model();
        let f = file("# poses\ngamma,beta,alpha,z,y,x,q1,tcp,time_s\n3,2,180,40,-40,60,100,2,7.5\n");
        let rows = read_pose_rows(f.path(), &m).expect("ok");
        assert_eq!(rows.len(), 1);
        let r = &rows[0];
        assert_eq!((r.line, r.tcp, r.q1_mm), (3, 2, 100.0));
        assert_eq!((r.xyz_mm, r.abc_deg), ([60.0, -40.0, 40.0], [180.0, 2.0, 3.0]));
        assert_eq!(r.context.time_s, Some(7.5));
        let cases = [
            ("tcp,q1,x,y,z,alpha,beta,gamma\n2,400,0,0,0,0,0,0\n", "q1", "guide limits"),
            ("tcp,q1,x,y,z,alpha,beta,gamma\n2,100,0,0,0,0,nan,0\n", "beta", "not finite"),
            ("tcp,q1,x,y,z,alpha,beta,gamma\n7,100,0,0,0,0,0,0\n", "tcp", "unknown tcp id 7"),
            ("tcp,q1,x,y,z,alpha,beta\n2,100,0,0,0,0,0\n", "gamma", "missing column"),
        ];
        for (text, column, reason) in cases {
            let f = file(text);
            let e = read_pose_rows(f.path(), &m).expect_err("bad").to_string();
            assert!(e.contains(&format!("`{column}`")) && e.contains(reason), "{e}");
        }
    }

    #[test]
    fn centring_offsets_are_read_written_and_checked() {
        let m = model();
        let f = file(
            "position,tcp,q1,q2,q3,q4,q5,q6,q7,offset_x_mm,offset_y_mm,offset_z_mm\n\
             1,1,100,0,0,0,0,0,0,0.001,-0.002,0.0035\n\
             2,1,100,0,0,0,0,0,0,,,\n",
        );
        let ms = read_probe_measurements(f.path(), &m).expect("ok");
        assert_eq!(ms[0].probe_offset_mm, Some(Vector3::new(0.001, -0.002, 0.0035)));
        assert_eq!(ms[0].target_offset_mm(), Vector3::new(0.001, -0.002, 0.0035));
        assert_eq!(ms[1].probe_offset_mm, None);
        let out = tempfile::NamedTempFile::new().expect("tmp");
        write_measurements(out.path(), &ms).expect("write");
        assert!(
            std::fs::read_to_string(out.path())
                .expect("read")
                .contains("offset_x_mm,offset_y_mm,offset_z_mm")
        );
        assert_eq!(read_measurements(out.path(), &m).expect("reread"), ms);
        // without the columns nothing changes
        let plain = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,0,0,0,0\n");
        assert_eq!(read_probe_measurements(plain.path(), &m).expect("ok")[0].probe_offset_mm, None);
        // a partial triple is an error naming the missing column
        let bad = file(
            "position,tcp,q1,q2,q3,q4,q5,q6,q7,offset_x_mm,offset_y_mm,offset_z_mm\n1,1,100,0,0,0,0,0,0,0.001,,0.002\n",
        );
        let e = read_probe_measurements(bad.path(), &m).expect_err("must fail").to_string();
        assert!(e.contains(":2:") && e.contains("offset_y_mm") && e.contains("all three"), "{e}");
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let m = model();
        let cases = [
            ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,0,0,abc,0\n", "q6", "not a number"),
            ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,9,100,0,0,0,0,0,0\n", "tcp", "unknown tcp id 9"),
            ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n4,1,100,0,0,0,0,0,0\n", "position", "unknown position id 4"),
            ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,95,0,0,0,0\n", "q3", "outside the joint limits"),
            ("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,NaN,0,0,0\n", "q4", "not finite"),
        ];
        for (text, col, reason) in cases {
            let f = file(text);
            let e = read_probe_measurements(f.path(), &m).expect_err("must fail").to_string();
            assert!(e.contains(":2:"), "{e}");
            assert!(e.contains(col) && e.contains(reason), "{e}");
        }
        let f = file("position,tcp,q1,q2,q3,q4,q5,q6\n1,1,100,0,0,0,0,0\n");
        let e = read_probe_measurements(f.path(), &m).expect_err("must fail").to_string();
        assert!(e.contains("missing column `q7`"), "{e}");
        let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,0,0,0\n");
        let e = read_probe_measurements(f.path(), &m).expect_err("must fail").to_string();
        assert!(e.contains("malformed CSV"), "{e}");
    }

    #[test]
    fn tracker_and_candidates() {
        let m = model();
        let f = file("tcp,q1,q2,q3,q4,q5,q6,q7,x,y,z\n1,0,0,0,0,0,0,0,1.5,2.5,3.5\n");
        let t = read_tracker_measurements(f.path(), &m).expect("ok");
        assert!(matches!(t[0].target, Target::Tracker { xyz_mm } if xyz_mm == Vector3::new(1.5, 2.5, 3.5)));
        let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7,note\n1,1,0,0,0,0,0,0,0,a\n2,2,10,0,0,0,0,0,0,b\n");
        let c = read_candidates(f.path(), &m).expect("ok");
        assert_eq!(c.measurements.len(), 2);
        let out = tempfile::NamedTempFile::new().expect("tmp");
        c.write_subset(out.path(), &[1]).expect("write");
        let text = std::fs::read_to_string(out.path()).expect("read");
        assert_eq!(text, "position,tcp,q1,q2,q3,q4,q5,q6,q7,note\n2,2,10,0,0,0,0,0,0,b\n");
    }
}
