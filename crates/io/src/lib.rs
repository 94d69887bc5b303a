#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Reading and writing the CSV files of `docs/formats.md`:
//!
//! | file | columns | reader | writer |
//! |---|---|---|---|
//! | joint rows | `tcp,q1..qN` | [`read_joint_rows`] | [`write_joint_rows_for`] |
//! | probe measurements | `position,tcp,q1..qN` (+ `time_s`, `temperature_c`, `dir{i}`, `offset_x_mm,offset_y_mm,offset_z_mm`) | [`read_probe_measurements`] | [`write_measurements_for`] |
//! | tracker measurements | `tcp,q1..qN,x,y,z` | [`read_tracker_measurements`] | [`write_measurements_for`] |
//! | candidate poses | `position,tcp,q1..qN` | [`read_candidates`] | [`CandidateTable::write_subset`] |
//! | pose requests | `tcp`, the given joints' `q{i}` (`q1` on the canonical cell, none on a six-joint arm), `x,y,z,alpha,beta,gamma` (+ `time_s`, `temperature_c`, `dir{i}`) | [`read_pose_requests`] | (`vatcal compensate`) |
//!
//! Rules: a header line, columns found by name in any order, unknown columns ignored, `#`
//! comment lines and blank lines skipped (a `# vatcal-noise:` metadata line is read by
//! [`metadata::read_metadata`], written by [`write_measurements_with_noise`]). An N-joint model reads and writes the joint columns
//! `q1..qN`, in mm for prismatic and degrees for revolute joints (the canonical cell: `q1` in
//! mm, `q2..q7` in degrees), and the context columns `dir{i}` of its revolute joints i
//! (`dir2..dir7` on the canonical cell). A file whose q-columns do not match the model's joint
//! count is an error naming the file, the header line and the expected columns
//! ([`IoError::JointColumns`]). A bad row is an error naming the file, the line, the column and
//! the reason ([`IoError::Row`]); nothing is silently dropped. Numbers are written with Rust's
//! shortest round-trip formatting.

pub mod metadata;

use std::path::{Path, PathBuf};
use std::sync::Mutex;

mod options;
pub use options::{
    AngleUnit, DIR_DEADBAND_DEG, LengthUnit, LimitTolerance, ReadOptions, ReadOutcome, ReadWarning,
    RowSource, dirs_from_row_order,
};

use nalgebra::Vector3;
use rayon::prelude::*;
use vatcal_core::{JointKind, JointVector, MAX_JOINTS, Measurement, MeasurementContext, Target};
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
    /// The file kind needs another chain than the model's.
    #[error("{path}: {reason}")]
    UnsupportedChain {
        /// file
        path: PathBuf,
        /// why
        reason: String,
    },
    /// The reader options do not fit the file (e.g. directions derived from the row order of a
    /// file that has `dir` columns of its own).
    #[error("{path}: {reason}")]
    Options {
        /// file
        path: PathBuf,
        /// why
        reason: String,
    },
    /// The joint columns of the header do not match the model's joint count.
    #[error(
        "{path}:{line}: the model has {joints} joints: expected the joint columns {expected}, the header has {found}"
    )]
    JointColumns {
        /// file
        path: PathBuf,
        /// 1-based line of the header
        line: u64,
        /// joints of the model
        joints: usize,
        /// the expected columns, e.g. `q1..q6`
        expected: String,
        /// the joint columns found
        found: String,
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
    /// the optional `time_s`, `temperature_c`, `dir{i}` columns of the row
    pub context: MeasurementContext,
}

pub use vatcal_core::MECA500_ON_GUIDE_KINDS;

/// The joint columns `q1..qN` of an N-joint chain.
pub fn joint_columns(n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("q{i}")).collect()
}

/// The direction columns `dir{i}` of the revolute joints i of a chain with joints `kinds`.
pub fn dir_columns(kinds: &[JointKind]) -> Vec<(usize, String)> {
    kinds
        .iter()
        .enumerate()
        .filter(|(_, k)| k.is_revolute())
        .map(|(k, _)| (k + 1, format!("dir{}", k + 1)))
        .collect()
}

/// `first..last` (or the single name) for messages.
fn span(columns: &[String]) -> String {
    match columns {
        [] => String::new(),
        [one] => one.clone(),
        [first, .., last] => format!("{first}..{last}"),
    }
}

/// The column names a reader needs: `prefix`, then `q1..qN`, then `suffix`.
fn required_columns(prefix: &[&str], model: &Model, suffix: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = prefix.iter().map(|s| s.to_string()).collect();
    v.extend(joint_columns(model.joint_count()));
    v.extend(suffix.iter().map(|s| s.to_string()));
    v
}

/// A parsed CSV table with a name → index header map.
struct Table {
    path: PathBuf,
    headers: csv::StringRecord,
    /// `(column name, field index)`, first occurrence of each name; searched linearly (a few
    /// columns: cheaper than hashing the name at every field lookup of every row)
    index: Vec<(String, usize)>,
    rows: Vec<(u64, csv::StringRecord)>,
    /// field indices of the columns every row reads, resolved once from the header
    cols: RowColumns,
    /// units, limit tolerance, unit checks ([`ReadOptions::strict`] for the readers without
    /// options)
    opts: ReadOptions,
    /// warnings met while converting rows (any order; sorted by line when returned)
    warnings: Mutex<Vec<ReadWarning>>,
    /// 1-based line of the header
    header_line: u64,
}

/// Field indices of the columns read on every row, so that a row costs no name lookups.
struct RowColumns {
    /// `(name, field)` of `q1..qN` of the model (empty when the table has no joint columns;
    /// the field is None when the header lacks it)
    joints: Vec<(String, Option<usize>)>,
    /// `(joint, name, field)` of the `dir{i}` columns the file has
    dirs: Vec<(usize, String, usize)>,
    time_s: Option<usize>,
    temperature_c: Option<usize>,
    offsets: [Option<usize>; 3],
}

/// The model's TCP and calibration-position ids, looked up once per file (every row's `tcp`
/// and `position` is checked against them).
struct RowIds {
    tcps: Vec<u32>,
    positions: Vec<u32>,
}

impl RowIds {
    fn of(model: &Model) -> Self {
        Self { tcps: model.tcp_ids(), positions: model.position_ids() }
    }
}

impl Table {
    /// Reads a table whose joint columns must be exactly `q1..qN` of `model`.
    fn read_for(path: &Path, model: &Model, required: &[String]) -> Result<Table, IoError> {
        Self::read_for_with(path, model, required, ReadOptions::strict())
    }

    /// [`Self::read_for`] with reader options.
    fn read_for_with(
        path: &Path,
        model: &Model,
        required: &[String],
        opts: ReadOptions,
    ) -> Result<Table, IoError> {
        let refs: Vec<&str> = required.iter().map(String::as_str).collect();
        let mut t = Self::read_checked(path, &refs, model, true)?;
        t.opts = opts;
        Ok(t)
    }

    /// Reads a table of `model`'s rows without joint columns of its own (pose requests: the
    /// caller checks its `q` columns).
    fn read(path: &Path, model: &Model, required: &[&str]) -> Result<Table, IoError> {
        Self::read_checked(path, required, model, false)
    }

    fn read_checked(
        path: &Path,
        required: &[&str],
        model: &Model,
        joint_columns_of_model: bool,
    ) -> Result<Table, IoError> {
        let text =
            std::fs::read(path).map_err(|source| IoError::File { path: path.into(), cause: source })?;
        // the header is the first line that is neither blank nor a comment
        let header_line = text
            .split(|b| *b == b'\n')
            .position(|l| {
                let l = l.trim_ascii();
                !l.is_empty() && !l.starts_with(b"#")
            })
            .map_or(1, |k| k as u64 + 1);
        let mut rdr = table_reader(&text);
        let headers = rdr.headers().map_err(|e| csv_error(path, &e))?.clone();
        let mut index: Vec<(String, usize)> = Vec::with_capacity(headers.len());
        for (i, h) in headers.iter().enumerate() {
            if !index.iter().any(|(name, _)| name == h) {
                index.push((h.to_string(), i));
            }
        }
        if joint_columns_of_model {
            let n = model.joint_count();
            let mut found: Vec<usize> = headers
                .iter()
                .filter_map(|h| h.strip_prefix('q').and_then(|k| k.parse::<usize>().ok()))
                .collect();
            found.sort_unstable();
            if found != (1..=n).collect::<Vec<_>>() {
                let found = found.iter().map(|k| format!("q{k}")).collect::<Vec<_>>().join(",");
                return Err(IoError::JointColumns {
                    path: path.into(),
                    line: header_line,
                    joints: n,
                    expected: span(&joint_columns(n)),
                    found: if found.is_empty() { "none".into() } else { found },
                });
            }
        }
        for col in required {
            if !index.iter().any(|(name, _)| name == col) {
                return Err(IoError::MissingColumn {
                    path: path.into(),
                    column: (*col).to_string(),
                    required: required.join(","),
                });
            }
        }
        let rows = match parallel_rows(&text, rdr.position(), headers.len()) {
            Some(rows) => rows,
            // anything unusual (quotes, CR line ends, a bad row): the sequential reader, which
            // also words the error
            None => sequential_rows(&mut rdr, path)?,
        };
        let mut rows = rows;
        record_lines(&text, &mut rows);
        if rows.is_empty() {
            return Err(IoError::Empty { path: path.into() });
        }
        let column = |c: &str| index.iter().find(|(name, _)| name == c).map(|(_, i)| *i);
        let joint_names =
            if joint_columns_of_model { joint_columns(model.joint_count()) } else { Vec::new() };
        let cols = RowColumns {
            joints: joint_names
                .into_iter()
                .map(|name| {
                    let field = column(&name);
                    (name, field)
                })
                .collect(),
            dirs: dir_columns(model.joint_kinds())
                .into_iter()
                .filter_map(|(joint, name)| column(&name).map(|i| (joint, name, i)))
                .collect(),
            time_s: column("time_s"),
            temperature_c: column("temperature_c"),
            offsets: OFFSET_COLUMNS.map(column),
        };
        Ok(Table {
            path: path.into(),
            headers,
            index,
            rows,
            cols,
            opts: ReadOptions::strict(),
            warnings: Mutex::new(Vec::new()),
            header_line,
        })
    }

    /// Fails when an effect of `model` depends on a context column (`dir{i}` of every revolute
    /// joint, `time_s`, `temperature_c`) that the file lacks, or that is empty on some row:
    /// predictions there would silently use 0.
    fn check_model_columns(&self, model: &Model) -> Result<(), IoError> {
        for spec in model.effects() {
            // with directions derived from the row order, the file needs no `dir` column
            let columns: Vec<String> = vatcal_kinematics::effects::context_columns(spec)
                .iter()
                .map(|c| c.to_string())
                .filter(|c| !(self.opts.dir_from_row_order && c.starts_with("dir")))
                .collect();
            if columns.is_empty() {
                continue;
            }
            let missing = columns.iter().any(|c| !self.has(c));
            if missing {
                let columns = span(&columns);
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
        self.column(col).is_some()
    }

    fn column(&self, col: &str) -> Option<usize> {
        self.index.iter().find(|(name, _)| name == col).map(|(_, i)| *i)
    }

    fn field<'a>(&self, rec: &'a csv::StringRecord, col: &str) -> Option<&'a str> {
        self.column(col).and_then(|i| rec.get(i))
    }

    /// Converts every row with `f`, in parallel; the rows keep their order and an error is the
    /// one of the first bad row (as a sequential pass would report).
    fn convert<T: Send>(
        &self,
        f: impl Fn(u64, &csv::StringRecord) -> Result<T, IoError> + Sync,
    ) -> Result<Vec<T>, IoError> {
        let results: Vec<Result<T, IoError>> =
            self.rows.par_iter().with_min_len(256).map(|(line, rec)| f(*line, rec)).collect();
        results.into_iter().collect()
    }

    fn err(&self, line: u64, column: &str, reason: impl Into<String>) -> IoError {
        IoError::Row { path: self.path.clone(), line, column: column.into(), reason: reason.into() }
    }

    fn float(&self, line: u64, rec: &csv::StringRecord, col: &str) -> Result<f64, IoError> {
        self.float_at(line, rec, col, self.column(col))
    }

    /// [`Self::float`] of column `col` at the already resolved field `index`.
    fn float_at(
        &self,
        line: u64,
        rec: &csv::StringRecord,
        col: &str,
        index: Option<usize>,
    ) -> Result<f64, IoError> {
        let s = index.and_then(|i| rec.get(i)).unwrap_or("");
        if s.is_empty() {
            return Err(self.err(line, col, "empty field"));
        }
        let v: f64 = s.parse().map_err(|_| self.err(line, col, format!("`{s}` is not a number")))?;
        if !v.is_finite() {
            return Err(self.err(line, col, format!("`{s}` is not finite")));
        }
        Ok(v)
    }

    /// The value of column `col` (resolved to field `index`), None when absent or empty.
    fn optional_float_at(
        &self,
        line: u64,
        rec: &csv::StringRecord,
        col: &str,
        index: Option<usize>,
    ) -> Result<Option<f64>, IoError> {
        match index.and_then(|i| rec.get(i)) {
            None | Some("") => Ok(None),
            Some(_) => self.float_at(line, rec, col, index).map(Some),
        }
    }

    fn id(&self, line: u64, rec: &csv::StringRecord, col: &str, known: &[u32]) -> Result<u32, IoError> {
        let s = self.field(rec, col).unwrap_or("");
        let v: u32 =
            s.parse().map_err(|_| self.err(line, col, format!("`{s}` is not a non-negative integer id")))?;
        let free_point = col == "position" && self.opts.any_position_id;
        let free_tcp = col == "tcp" && self.opts.any_tcp_id;
        if !(known.contains(&v) || free_point || free_tcp) {
            return Err(self.err(line, col, format!("unknown {col} id {v} (the model has {known:?})")));
        }
        Ok(v)
    }

    /// The joints `q1..qN` of a row (file units → internal units), checked against the
    /// model's limits.
    fn joints(&self, line: u64, rec: &csv::StringRecord, model: &Model) -> Result<JointVector, IoError> {
        let kinds = model.joint_kinds();
        let mut values = [0.0; MAX_JOINTS];
        let joints = &self.cols.joints;
        for (k, v) in values.iter_mut().enumerate().take(kinds.len()) {
            *v = match joints.get(k) {
                Some((name, index)) => self.float_at(line, rec, name, *index)?,
                None => self.float(line, rec, &format!("q{}", k + 1))?,
            };
        }
        let opts = &self.opts;
        if *opts == ReadOptions::strict() {
            let q = JointVector::from_file_units(&values[..kinds.len()], kinds)
                .map_err(|e| self.err(line, "q1", e.to_string()))?;
            if let Some((joint, _, lo, hi)) = model.limit_violation(&q) {
                let kind = kinds[joint - 1];
                let (lo, hi) = (kind.to_file_unit(lo), kind.to_file_unit(hi));
                let unit = kind.file_unit();
                return Err(self.err(
                    line,
                    &format!("q{joint}"),
                    format!("{} {unit} is outside the joint limits [{lo}, {hi}] {unit}", values[joint - 1]),
                ));
            }
            return Ok(q);
        }
        // file units -> internal units (mm, rad), then the limits with their tolerance
        let mut internal = [0.0; MAX_JOINTS];
        for (k, kind) in kinds.iter().enumerate() {
            let (scale, unit) = self.joint_unit(*kind);
            let v = values[k];
            if opts.check_units {
                self.check_joint_unit(line, k + 1, *kind, v)?;
            }
            internal[k] = v * scale;
            let Some((lo, hi)) = model.joint_limit(k + 1) else { continue };
            let x = internal[k];
            if (lo..=hi).contains(&x) {
                continue;
            }
            // the excess in the user's units of tolerance (deg / mm)
            let excess = kind.to_file_unit(if x < lo { lo - x } else { x - hi });
            let (tolerance, tol_unit) = match kind {
                JointKind::Revolute => (opts.limit_tolerance.revolute_deg, "deg"),
                JointKind::Prismatic => (opts.limit_tolerance.prismatic_mm, "mm"),
            };
            let limits = format!("[{}, {}] {unit}", lo / scale, hi / scale);
            let column = format!("q{}", k + 1);
            if excess <= tolerance {
                self.warn(
                    line,
                    &column,
                    format!(
                        "{v} {unit} is beyond the joint limits {limits} by {excess:.4} {tol_unit} (within the \
                         tolerance of {tolerance} {tol_unit}: read as measured)"
                    ),
                );
            } else {
                return Err(self.err(
                    line,
                    &column,
                    format!(
                        "{v} {unit} is outside the joint limits {limits} (by {excess:.4} {tol_unit}, more than \
                         the tolerance of {tolerance} {tol_unit}){}",
                        if self.fits_other_unit(*kind, v, lo, hi) { self.unit_hint(*kind) } else { "" }
                    ),
                ));
            }
        }
        JointVector::from_slice(&internal[..kinds.len()]).map_err(|e| self.err(line, "q1", e.to_string()))
    }

    /// Internal units per file unit of a joint of `kind`, and the file unit's label.
    fn joint_unit(&self, kind: JointKind) -> (f64, &'static str) {
        match kind {
            JointKind::Revolute => (self.opts.angle_unit.to_rad(), self.opts.angle_unit.label()),
            JointKind::Prismatic => (self.opts.length_unit.to_mm(), self.opts.length_unit.label()),
        }
    }

    /// Whether the file value `v` of a joint of `kind` would lie within the limits `[lo, hi]`
    /// (internal units) if it were in the other unit (degrees for radians — only beyond a turn,
    /// as a smaller value is a plausible angle in radians —, metres for mm, and back).
    fn fits_other_unit(&self, kind: JointKind, v: f64, lo: f64, hi: f64) -> bool {
        let other = match kind {
            JointKind::Revolute => match self.opts.angle_unit {
                AngleUnit::Deg => v,
                // a value within a turn is a plausible angle in radians: no hint at degrees
                AngleUnit::Rad if v.abs() <= std::f64::consts::TAU => return false,
                AngleUnit::Rad => v.to_radians(),
            },
            JointKind::Prismatic => match self.opts.length_unit {
                LengthUnit::Mm => v * 1000.0,
                LengthUnit::M => v,
            },
        };
        (lo..=hi).contains(&other)
    }

    /// A hint at the other unit (for an error on a value that fits it).
    fn unit_hint(&self, kind: JointKind) -> &'static str {
        match (kind, self.opts.angle_unit, self.opts.length_unit) {
            (JointKind::Revolute, AngleUnit::Deg, _) => " (radians? use --angle-unit rad)",
            (JointKind::Revolute, AngleUnit::Rad, _) => " (degrees? use --angle-unit deg)",
            (JointKind::Prismatic, _, LengthUnit::Mm) => " (metres? use --length-unit m)",
            (JointKind::Prismatic, _, LengthUnit::M) => " (millimetres? use --length-unit mm)",
        }
    }

    /// Refuses a joint value that cannot be in the stated unit: more than two turns in radians
    /// (degrees?) or more than 20 m in metres (millimetres?).
    fn check_joint_unit(&self, line: u64, joint: usize, kind: JointKind, v: f64) -> Result<(), IoError> {
        let bad = match kind {
            JointKind::Revolute => {
                self.opts.angle_unit == AngleUnit::Rad && v.abs() > 4.0 * std::f64::consts::PI
            }
            JointKind::Prismatic => self.opts.length_unit == LengthUnit::M && v.abs() > 20.0,
        };
        if bad {
            let (_, unit) = self.joint_unit(kind);
            return Err(self.err(
                line,
                &format!("q{joint}"),
                format!("{v} {unit} is implausible for a joint{}", self.unit_hint(kind)),
            ));
        }
        Ok(())
    }

    /// A length column (`x,y,z`) in mm, from the file's length unit.
    fn length_mm(&self, line: u64, rec: &csv::StringRecord, col: &str) -> Result<f64, IoError> {
        let v = self.float(line, rec, col)?;
        if self.opts.check_units && self.opts.length_unit == LengthUnit::M && v.abs() > 100.0 {
            return Err(self.err(
                line,
                col,
                format!(
                    "{v} m is more than 100 m from the instrument's origin (millimetres? use --length-unit mm)"
                ),
            ));
        }
        Ok(v * self.opts.length_unit.to_mm())
    }

    fn warn(&self, line: u64, column: &str, message: String) {
        let w = ReadWarning { path: self.path.clone(), line, column: column.into(), message };
        match self.warnings.lock() {
            Ok(mut v) => v.push(w),
            Err(poisoned) => poisoned.into_inner().push(w),
        }
    }

    /// The warnings met, in line order.
    fn take_warnings(&self) -> Vec<ReadWarning> {
        let mut w = match self.warnings.lock() {
            Ok(mut v) => std::mem::take(&mut *v),
            Err(poisoned) => std::mem::take(&mut *poisoned.into_inner()),
        };
        w.sort_by(|a, b| (a.line, &a.column).cmp(&(b.line, &b.column)));
        w
    }

    fn context(&self, line: u64, rec: &csv::StringRecord) -> Result<MeasurementContext, IoError> {
        let cols = &self.cols;
        let time_s = self.optional_float_at(line, rec, "time_s", cols.time_s)?;
        let temperature_c = self.optional_float_at(line, rec, "temperature_c", cols.temperature_c)?;
        // every `dir{i}` column of a revolute joint i the file has; a joint without one is 0
        // (unknown); no direction data when the file has none of them
        let dir = if cols.dirs.is_empty() {
            None
        } else {
            let mut d = [0i8; MAX_JOINTS];
            for (joint, col, index) in &cols.dirs {
                let v = self.float_at(line, rec, col, Some(*index))?;
                d[joint - 1] = match v {
                    1.0 => 1,
                    -1.0 => -1,
                    0.0 => 0,
                    _ => return Err(self.err(line, col, format!("direction must be +1, -1 or 0, got {v}"))),
                };
            }
            Some(d)
        };
        Ok(MeasurementContext { dir, time_s, temperature_c })
    }

    /// A probe row's measurement: `position`, `tcp`, the joints, the context columns and the
    /// optional probe offset.
    fn probe_measurement(
        &self,
        line: u64,
        rec: &csv::StringRecord,
        model: &Model,
        ids: &RowIds,
    ) -> Result<Measurement, IoError> {
        let position = self.id(line, rec, "position", &ids.positions)?;
        let mut m = self.measurement(line, rec, model, ids, Target::Probe { position })?;
        m.probe_offset_mm = self.probe_offset(line, rec)?;
        Ok(m)
    }

    /// A tracker row's measurement: `tcp`, the joints, the context columns and `x,y,z` in the
    /// table's length unit.
    fn tracker_measurement(
        &self,
        line: u64,
        rec: &csv::StringRecord,
        model: &Model,
        ids: &RowIds,
    ) -> Result<Measurement, IoError> {
        let xyz_mm = Vector3::new(
            self.length_mm(line, rec, "x")?,
            self.length_mm(line, rec, "y")?,
            self.length_mm(line, rec, "z")?,
        );
        self.measurement(line, rec, model, ids, Target::Tracker { xyz_mm })
    }

    /// The columns every measurement row has (`tcp`, the joints, the context) around `target`.
    fn measurement(
        &self,
        line: u64,
        rec: &csv::StringRecord,
        model: &Model,
        ids: &RowIds,
        target: Target,
    ) -> Result<Measurement, IoError> {
        Ok(Measurement {
            tcp: self.id(line, rec, "tcp", &ids.tcps)?,
            q: self.joints(line, rec, model)?,
            target,
            context: self.context(line, rec)?,
            probe_offset_mm: None,
        })
    }

    /// The optional final centring offset `offset_x_mm,offset_y_mm,offset_z_mm` (world axes) of
    /// a probe row: all three present or all three empty/absent.
    fn probe_offset(&self, line: u64, rec: &csv::StringRecord) -> Result<Option<Vector3<f64>>, IoError> {
        let mut v = [None; 3];
        for ((value, c), index) in v.iter_mut().zip(OFFSET_COLUMNS).zip(self.cols.offsets) {
            *value = self.optional_float_at(line, rec, c, index)?;
        }
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

/// The CSV reader of every table: `#` comments, fields trimmed, one field count.
fn table_reader(text: &[u8]) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new().comment(Some(b'#')).trim(csv::Trim::All).flexible(false).from_reader(text)
}

/// The data rows of `rdr` (its header already read) with their line numbers, all-empty rows
/// skipped.
fn sequential_rows(
    rdr: &mut csv::Reader<&[u8]>,
    path: &Path,
) -> Result<Vec<(u64, csv::StringRecord)>, IoError> {
    let mut rows = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| csv_error(path, &e))?;
        if rec.iter().all(|f| f.is_empty()) {
            continue;
        }
        let line = rec.position().map_or(0, |p| p.line());
        rows.push((line, rec));
    }
    Ok(rows)
}

/// Moves every row's line to the line its record is on. The csv crate reports the line where
/// its reader started reading the record, before the empty and comment lines it skipped, so a
/// row after a blank line or a `#` line was named by the skipped line (one line early per
/// skipped line): each row goes to the first line at or after the reported one that is neither
/// empty nor a comment.
fn record_lines(text: &[u8], rows: &mut [(u64, csv::StringRecord)]) {
    let starts: Vec<usize> = std::iter::once(0)
        .chain(text.iter().enumerate().filter(|(_, b)| **b == b'\n').map(|(i, _)| i + 1))
        .collect();
    let line_text = |line: u64| -> Option<&[u8]> {
        let k = usize::try_from(line).ok()?.checked_sub(1)?;
        let start = *starts.get(k)?;
        let end = starts.get(k + 1).map_or(text.len(), |e| e - 1);
        text.get(start..end)
    };
    for (line, _) in rows.iter_mut() {
        while let Some(t) = line_text(*line) {
            let t = t.strip_suffix(b"\r").unwrap_or(t);
            if t.is_empty() || t.starts_with(b"#") {
                *line += 1;
            } else {
                break;
            }
        }
    }
}

/// Bytes of CSV text per task of [`parallel_rows`] (fixed, so the work split does not depend
/// on the number of threads; the result never does).
const PARSE_CHUNK: usize = 1 << 17;

/// The data rows after the header (`after_header`: the reader's position after it), parsed
/// in parallel over line-aligned chunks of `text` with the reader settings of
/// [`Table::read_checked`]: the same `(line, record)` rows, in order, as its sequential loop.
/// `None` (use the sequential reader) when the text has a quote or a carriage return (a
/// record could then span lines or line ends differ) or when any row is not well-formed
/// (unequal field count, invalid UTF-8): the sequential reader reports those exactly as
/// before.
fn parallel_rows(
    text: &[u8],
    after_header: &csv::Position,
    fields: usize,
) -> Option<Vec<(u64, csv::StringRecord)>> {
    let rest = text.get(usize::try_from(after_header.byte()).ok()?..)?;
    // line-aligned chunks: each ends just after a '\n' (the last one at the end of the text)
    let mut chunks = Vec::with_capacity(rest.len() / PARSE_CHUNK + 1);
    let mut start = 0;
    while start < rest.len() {
        let end = match rest.get(start + PARSE_CHUNK..).and_then(|t| t.iter().position(|b| *b == b'\n')) {
            Some(k) => start + PARSE_CHUNK + k + 1,
            None => rest.len(),
        };
        chunks.push((start, &rest[start..end]));
        start = end;
    }
    // per chunk: its rows with chunk-local positions, its records (incl. all-empty ones) and
    // its line ends
    type Part = (Vec<csv::StringRecord>, u64, u64);
    let parts: Vec<Option<Part>> = chunks
        .par_iter()
        .map(|(_, chunk)| {
            // one branch-free pass (vectorised): line ends, quotes or carriage returns, and the
            // other whitespace a field could be trimmed of
            let (line_ends, unusual, blanks) = chunk.iter().fold((0u64, 0u64, 0u64), |(n, u, w), b| {
                (
                    n + u64::from(*b == b'\n'),
                    u + u64::from(*b == b'"' || *b == b'\r'),
                    w + u64::from(*b == b' ' || *b == b'\t' || *b == b'\x0c'),
                )
            });
            if unusual > 0 {
                return None;
            }
            // without whitespace in the chunk trimming changes nothing: skip its per-record cost
            let trim = if blanks > 0 { csv::Trim::All } else { csv::Trim::None };
            let mut rdr = csv::ReaderBuilder::new()
                .has_headers(false)
                .comment(Some(b'#'))
                .trim(trim)
                .flexible(true)
                .from_reader(*chunk);
            let (mut rows, mut records) = (Vec::with_capacity(line_ends as usize + 1), 0);
            for rec in rdr.records() {
                let rec = rec.ok()?;
                if rec.len() != fields {
                    return None;
                }
                records += 1;
                if !rec.iter().all(|f| f.is_empty()) {
                    rows.push(rec);
                }
            }
            Some((rows, records, line_ends))
        })
        .collect();
    // chunk-local positions -> file positions (as the sequential reader would report them)
    let mut rows = Vec::with_capacity(parts.iter().flatten().map(|p| p.0.len()).sum());
    let (mut line, mut record) = (after_header.line(), after_header.record());
    for ((offset, _), part) in chunks.iter().zip(parts) {
        let (part_rows, records, line_ends) = part?;
        for mut rec in part_rows {
            let local = rec.position().cloned().unwrap_or_else(csv::Position::new);
            let mut pos = csv::Position::new();
            pos.set_byte(after_header.byte() + *offset as u64 + local.byte())
                .set_line(line + local.line() - 1)
                .set_record(record + local.record());
            rec.set_position(Some(pos.clone()));
            rows.push((pos.line(), rec));
        }
        line += line_ends;
        record += records;
    }
    Some(rows)
}

/// The optional per-row centring offset columns of probe measurements (world axes, mm).
pub const OFFSET_COLUMNS: [&str; 3] = ["offset_x_mm", "offset_y_mm", "offset_z_mm"];

fn csv_error(path: &Path, e: &csv::Error) -> IoError {
    let line = e.position().map_or(0, |p| p.line());
    IoError::Csv { path: path.into(), line, message: e.to_string() }
}

/// Reads `tcp,q1..qN` rows (input of `vatcal fk` / `vatcal torque`) with the optional
/// `time_s`, `temperature_c`, `dir{i}` columns; TCP ids are checked against the model,
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
/// [`IoError::JointColumns`] (the `q` columns do not match the model's joint count),
/// [`IoError::Empty`] (no data rows), [`IoError::Row`] naming the line and column of a bad value
/// (not a number, an unknown TCP id, a joint outside its limits, a bad context value), and
/// [`IoError::ModelNeedsColumn`] when the model's effects need context columns the file lacks.
pub fn read_joint_rows(path: impl AsRef<Path>, model: &Model) -> Result<Vec<JointRow>, IoError> {
    read_joint_rows_with(path, model, &ReadOptions::strict()).map(|r| r.rows)
}

/// Reads probe measurements `position,tcp,q1..qN` with the optional `time_s`,
/// `temperature_c`, `dir{i}` columns.
///
/// # Examples
/// Probe rows of the UR5e fixture (six revolute joints in degrees), with the direction of
/// joint 4 only:
/// ```
/// use vatcal_core::{CellFile, Target};
/// use vatcal_io::read_probe_measurements;
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))?)?;
/// let path = std::env::temp_dir().join(format!("vatcal-doc-probe-{}.csv", std::process::id()));
/// std::fs::write(&path, "position,tcp,q1,q2,q3,q4,q5,q6,dir4\n1,1,10,-80,90,-100,-90,0,-1\n")?;
/// let ms = read_probe_measurements(&path, &model);
/// std::fs::remove_file(&path)?;
/// let ms = ms?;
/// assert_eq!(ms[0].target, Target::Probe { position: 1 });
/// assert!((ms[0].q.get(2) - (-80f64).to_radians()).abs() < 1e-15);
/// assert_eq!((ms[0].context.dir_of(4), ms[0].context.dir_of(5)), (-1, 0)); // 0: unknown
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`read_joint_rows`]; the `position` id is checked against the model too.
pub fn read_probe_measurements(path: impl AsRef<Path>, model: &Model) -> Result<Vec<Measurement>, IoError> {
    read_probe_measurements_with(path, model, &ReadOptions::strict()).map(|r| r.rows)
}

/// Reads tracker measurements `tcp,q1..qN,x,y,z` (world, mm), with the same optional columns.
///
/// # Examples
/// A row whose `y` is not a number is refused with the file, line and column:
/// ```
/// use vatcal_core::CellFile;
/// use vatcal_io::read_tracker_measurements;
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-table.toml"))?)?;
/// let path = std::env::temp_dir().join(format!("vatcal-doc-tracker-{}.csv", std::process::id()));
/// std::fs::write(&path, "tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,0,0,0,0,0,0,100,2.5,300\n1,0,0,0,0,0,0,100,n/a,300\n")?;
/// let e = read_tracker_measurements(&path, &model).expect_err("bad y");
/// std::fs::remove_file(&path)?;
/// assert!(e.to_string().contains(":3: column `y`: `n/a` is not a number"), "{e}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`read_joint_rows`]; `x,y,z` must be finite numbers.
pub fn read_tracker_measurements(path: impl AsRef<Path>, model: &Model) -> Result<Vec<Measurement>, IoError> {
    read_tracker_measurements_with(path, model, &ReadOptions::strict()).map(|r| r.rows)
}

/// Reads a file that may hold probe rows (`position` column) or tracker rows (`x,y,z`), or
/// both kinds mixed (a row with an empty `position` and filled `x,y,z` is a tracker row).
///
/// # Examples
/// ```
/// use vatcal_core::{CellFile, Target};
/// use vatcal_io::read_measurements;
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// let path = std::env::temp_dir().join(format!("vatcal-doc-mixed-{}.csv", std::process::id()));
/// std::fs::write(
///     &path,
///     "position,tcp,q1,q2,q3,q4,q5,q6,q7,x,y,z\n2,1,100,0,0,0,0,0,0,,,\n,3,100,0,0,0,0,0,0,1,2,3\n",
/// )?;
/// let ms = read_measurements(&path, &model);
/// std::fs::remove_file(&path)?;
/// let ms = ms?;
/// assert_eq!(ms[0].target, Target::Probe { position: 2 });
/// assert!(matches!(ms[1].target, Target::Tracker { .. }));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`read_probe_measurements`] and [`read_tracker_measurements`], and [`IoError::Row`]
/// naming the header line when the file has neither `position` nor `x,y,z`, or the line of a
/// row that has neither a `position` nor `x`.
pub fn read_measurements(path: impl AsRef<Path>, model: &Model) -> Result<Vec<Measurement>, IoError> {
    read_measurements_with(path, model, &ReadOptions::strict()).map(|r| r.rows)
}

/// Below this largest |x|, |y|, |z| \[mm\] over every tracker row of a file (3 rows or more),
/// the coordinates are taken for metres read as millimetres: an instrument that saw a robot
/// move, with every point within 10 mm of its origin, is implausible.
const TRACKER_METRES_AS_MM_BOUND_MM: f64 = 10.0;

impl Table {
    /// Refuses tracker coordinates that are plainly metres read as millimetres (every
    /// coordinate of 3+ tracker rows within ±10 mm of the instrument's origin), naming the line
    /// and column of the largest.
    fn check_tracker_length_unit(&self, rows: &[Measurement]) -> Result<(), IoError> {
        if !self.opts.check_units || self.opts.length_unit != LengthUnit::Mm {
            return Ok(());
        }
        let mut largest: Option<(f64, usize, usize)> = None; // (|mm|, row, axis)
        let mut tracker_rows = 0;
        for (r, m) in rows.iter().enumerate() {
            if let Target::Tracker { xyz_mm } = m.target {
                tracker_rows += 1;
                for a in 0..3 {
                    if largest.is_none_or(|(v, ..)| xyz_mm[a].abs() > v) {
                        largest = Some((xyz_mm[a].abs(), r, a));
                    }
                }
            }
        }
        match largest {
            Some((v, r, a)) if tracker_rows >= 3 && v > 0.0 && v < TRACKER_METRES_AS_MM_BOUND_MM => {
                Err(self.err(
                    self.rows[r].0,
                    ["x", "y", "z"][a],
                    format!(
                        "every tracker coordinate of the file is within ±{TRACKER_METRES_AS_MM_BOUND_MM} mm of \
                         the instrument's origin (the largest, {v}, is here): these are metres (use \
                         --length-unit m)"
                    ),
                ))
            }
            _ => Ok(()),
        }
    }

    /// The file-level steps of a read with options: the unit plausibility of the whole file,
    /// the directions derived from the row order, the warnings in line order.
    fn finish<T>(
        &self,
        model: &Model,
        mut rows: Vec<T>,
        q_of: impl Fn(&T) -> &JointVector,
        context_of: impl Fn(&mut T) -> &mut MeasurementContext,
    ) -> Result<ReadOutcome<T>, IoError> {
        let kinds = model.joint_kinds();
        if self.opts.check_units && self.opts.angle_unit == AngleUnit::Deg && rows.len() >= 3 {
            // every revolute value within ±2π "degrees": the file is in radians
            let mut largest: Option<(f64, usize, usize)> = None; // (|deg|, row, joint)
            for (r, row) in rows.iter().enumerate() {
                let q = q_of(row);
                for (k, kind) in kinds.iter().enumerate() {
                    if kind.is_revolute() {
                        let v = q[k].to_degrees().abs();
                        if largest.is_none_or(|(m, ..)| v > m) {
                            largest = Some((v, r, k));
                        }
                    }
                }
            }
            if let Some((v, r, k)) = largest
                && v > 0.0
                && v <= std::f64::consts::TAU
            {
                return Err(self.err(
                    self.rows[r].0,
                    &format!("q{}", k + 1),
                    format!(
                        "every revolute joint value of the file is within ±{:.4} deg (the largest, {v}, is \
                         here): these are radians (use --angle-unit rad)",
                        std::f64::consts::TAU
                    ),
                ));
            }
        }
        if self.opts.dir_from_row_order {
            if let Some((_, col, _)) = self.cols.dirs.first() {
                return Err(IoError::Options {
                    path: self.path.clone(),
                    reason: format!(
                        "the file has its own direction column `{col}`: directions derived from the row \
                         order would replace it (drop the option or the columns)"
                    ),
                });
            }
            let revolute: Vec<bool> = kinds.iter().map(|k| k.is_revolute()).collect();
            let qs: Vec<&[f64]> = rows.iter().map(|r| q_of(r).as_slice()).collect();
            let dirs = dirs_from_row_order(&qs, &revolute);
            for (row, d) in rows.iter_mut().zip(dirs) {
                let mut dir = [0i8; MAX_JOINTS];
                dir[..d.len()].copy_from_slice(&d);
                context_of(row).dir = Some(dir);
            }
        }
        let lines = self.rows.iter().map(|(line, _)| *line).collect();
        Ok(ReadOutcome { rows, warnings: self.take_warnings(), lines, path: self.path.clone() })
    }
}

/// [`read_joint_rows`] with reader options: units, limit tolerance (warnings instead of errors
/// within it), directions from the row order.
///
/// # Examples
/// Joint rows in radians, one of them 0.1 deg beyond the upper limit of the Meca500's joint 2
/// (90 deg): read, with a warning naming the line and column; directions from the row order:
/// ```
/// use vatcal_core::CellFile;
/// use vatcal_io::{AngleUnit, ReadOptions, read_joint_rows_with};
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-table.toml"))?)?;
/// let path = std::env::temp_dir().join(format!("vatcal-doc-rad-{}.csv", std::process::id()));
/// let beyond = 90.1f64.to_radians();
/// std::fs::write(&path, format!("tcp,q1,q2,q3,q4,q5,q6\n1,0.5,{beyond},0,0,0,0\n1,0.25,0.5,0,0,0,0\n"))?;
/// let options = ReadOptions { angle_unit: AngleUnit::Rad, dir_from_row_order: true, ..ReadOptions::default() };
/// let read = read_joint_rows_with(&path, &model, &options);
/// std::fs::remove_file(&path)?;
/// let read = read?;
/// assert!((read.rows[0].q[0] - 0.5).abs() < 1e-15);
/// assert_eq!(read.warnings.len(), 1);
/// assert!(read.warnings[0].to_string().contains(":2: column `q2`:"), "{}", read.warnings[0]);
/// assert_eq!((read.rows[1].context.dir_of(1), read.rows[1].context.dir_of(2)), (-1, -1));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`read_joint_rows`]; a joint beyond its limit by more than the tolerance, a value that
/// cannot be in the stated unit (with a hint at the other one), and [`IoError::Options`] for
/// derived directions on a file with `dir` columns.
pub fn read_joint_rows_with(
    path: impl AsRef<Path>,
    model: &Model,
    options: &ReadOptions,
) -> Result<ReadOutcome<JointRow>, IoError> {
    let path = path.as_ref();
    let t = Table::read_for_with(path, model, &required_columns(&["tcp"], model, &[]), *options)?;
    t.check_model_columns(model)?;
    let tcps = model.tcp_ids();
    let rows = t.convert(|line, rec| {
        Ok(JointRow {
            line,
            tcp: t.id(line, rec, "tcp", &tcps)?,
            q: t.joints(line, rec, model)?,
            context: t.context(line, rec)?,
        })
    })?;
    t.finish(model, rows, |r| &r.q, |r| &mut r.context)
}

/// [`read_probe_measurements`] with reader options (see [`read_joint_rows_with`]).
///
/// # Errors
/// As [`read_probe_measurements`] and [`read_joint_rows_with`].
pub fn read_probe_measurements_with(
    path: impl AsRef<Path>,
    model: &Model,
    options: &ReadOptions,
) -> Result<ReadOutcome<Measurement>, IoError> {
    let path = path.as_ref();
    let t = Table::read_for_with(path, model, &required_columns(&["position", "tcp"], model, &[]), *options)?;
    t.check_model_columns(model)?;
    let ids = RowIds::of(model);
    let rows = t.convert(|line, rec| t.probe_measurement(line, rec, model, &ids))?;
    t.finish(model, rows, |m| &m.q, |m| &mut m.context)
}

/// [`read_tracker_measurements`] with reader options (see [`read_joint_rows_with`]); `x,y,z`
/// are in the options' length unit.
///
/// # Errors
/// As [`read_tracker_measurements`] and [`read_joint_rows_with`].
pub fn read_tracker_measurements_with(
    path: impl AsRef<Path>,
    model: &Model,
    options: &ReadOptions,
) -> Result<ReadOutcome<Measurement>, IoError> {
    let path = path.as_ref();
    let t =
        Table::read_for_with(path, model, &required_columns(&["tcp"], model, &["x", "y", "z"]), *options)?;
    t.check_model_columns(model)?;
    let ids = RowIds::of(model);
    let rows = t.convert(|line, rec| t.tracker_measurement(line, rec, model, &ids))?;
    t.check_tracker_length_unit(&rows)?;
    t.finish(model, rows, |m| &m.q, |m| &mut m.context)
}

/// [`read_measurements`] (probe and/or tracker rows) with reader options (see
/// [`read_joint_rows_with`]); tracker `x,y,z` are in the options' length unit.
///
/// # Errors
/// As [`read_measurements`] and [`read_joint_rows_with`].
pub fn read_measurements_with(
    path: impl AsRef<Path>,
    model: &Model,
    options: &ReadOptions,
) -> Result<ReadOutcome<Measurement>, IoError> {
    let path = path.as_ref();
    let t = Table::read_for_with(path, model, &required_columns(&["tcp"], model, &[]), *options)?;
    t.check_model_columns(model)?;
    let has_xyz = t.has("x") && t.has("y") && t.has("z");
    if !t.has("position") && !has_xyz {
        return Err(t.err(
            t.header_line,
            "position / x,y,z",
            format!(
                "the header has neither probe rows' `position` nor tracker rows' `x,y,z` (probe rows: position,tcp,{q}; tracker rows: tcp,{q},x,y,z)",
                q = span(&joint_columns(model.joint_count()))
            ),
        ));
    }
    let ids = RowIds::of(model);
    let rows = t.convert(|line, rec| {
        let has_pos = t.field(rec, "position").is_some_and(|s| !s.is_empty());
        if !has_pos && t.field(rec, "x").is_none_or(str::is_empty) {
            let column = if t.has("position") { "position" } else { "x" };
            return Err(t.err(
                line,
                column,
                "empty: a probe row needs `position`, a tracker row `x,y,z` (this row has neither)",
            ));
        }
        if has_pos {
            t.probe_measurement(line, rec, model, &ids)
        } else {
            t.tracker_measurement(line, rec, model, &ids)
        }
    })?;
    t.check_tracker_length_unit(&rows)?;
    t.finish(model, rows, |m| &m.q, |m| &mut m.context)
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

/// Reads candidate poses `position,tcp,q1..qN` (other columns kept verbatim).
///
/// # Examples
/// Read candidates, keep two and write them back with the input's columns:
/// ```
/// use vatcal_core::CellFile;
/// use vatcal_io::read_candidates;
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-table.toml"))?)?;
/// let dir = std::env::temp_dir();
/// let (input, output) = (dir.join(format!("vatcal-doc-cand-{}.csv", std::process::id())), dir.join(format!("vatcal-doc-sel-{}.csv", std::process::id())));
/// std::fs::write(&input, "position,tcp,q1,q2,q3,q4,q5,q6,note\n1,1,0,0,0,0,0,0,a\n1,2,10,0,0,0,0,0,b\n1,3,20,0,0,0,0,0,c\n")?;
/// let table = read_candidates(&input, &model)?;
/// table.write_subset(&output, &[2, 0])?;
/// let text = std::fs::read_to_string(&output)?;
/// std::fs::remove_file(&input)?;
/// std::fs::remove_file(&output)?;
/// assert_eq!(table.measurements.len(), 3);
/// assert_eq!(text, "position,tcp,q1,q2,q3,q4,q5,q6,note\n1,3,20,0,0,0,0,0,c\n1,1,0,0,0,0,0,0,a\n");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`read_probe_measurements`] (without the check of the effects' context columns).
pub fn read_candidates(path: impl AsRef<Path>, model: &Model) -> Result<CandidateTable, IoError> {
    let path = path.as_ref();
    let t = Table::read_for(path, model, &required_columns(&["position", "tcp"], model, &[]))?;
    let ids = RowIds::of(model);
    let measurements = t.convert(|line, rec| t.probe_measurement(line, rec, model, &ids))?;
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

/// The joint values of `q` in file units, `kinds.len()` fields (a missing value is empty).
fn joint_fields(q: &JointVector, kinds: &[JointKind]) -> Vec<String> {
    let file = q.to_file_units(kinds);
    (0..kinds.len()).map(|k| file.get(k).map(|v| v.to_string()).unwrap_or_default()).collect()
}

/// Writes `tcp,q1..q7` rows of the canonical 7-joint Meca500-on-guide cell (q1 in mm, q2..q7
/// in degrees); [`write_joint_rows_for`] writes any chain.
///
/// # Errors
/// As [`write_joint_rows_for`].
pub fn write_joint_rows(path: impl AsRef<Path>, rows: &[(u32, JointVector)]) -> Result<(), IoError> {
    write_joint_rows_for(path, rows, &MECA500_ON_GUIDE_KINDS)
}

/// Writes `tcp,q1..qN` rows of a chain with joints `kinds` (mm for prismatic, degrees for
/// revolute joints).
///
/// # Examples
/// ```
/// use vatcal_core::{CellFile, JointVector};
/// use vatcal_io::{read_joint_rows, write_joint_rows_for};
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))?)?;
/// let q = JointVector::from_file_units(&[10.0, -80.0, 90.0, -100.0, -90.0, 0.0], model.joint_kinds())?;
/// let path = std::env::temp_dir().join(format!("vatcal-doc-rows-{}.csv", std::process::id()));
/// write_joint_rows_for(&path, &[(1, q)], model.joint_kinds())?;
/// let text = std::fs::read_to_string(&path)?;
/// let back = read_joint_rows(&path, &model);
/// std::fs::remove_file(&path)?;
/// assert!(text.starts_with("tcp,q1,q2,q3,q4,q5,q6\n1,10,-80,90,-100,-90,0"), "{text}");
/// assert_eq!(back?[0].q, q);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`IoError::File`] when the file cannot be created or written, [`IoError::Csv`] for a CSV
/// writer error.
pub fn write_joint_rows_for(
    path: impl AsRef<Path>,
    rows: &[(u32, JointVector)],
    kinds: &[JointKind],
) -> Result<(), IoError> {
    let path = path.as_ref();
    let mut w = writer(path)?;
    let mut header = vec!["tcp".to_string()];
    header.extend(joint_columns(kinds.len()));
    w.write_record(&header).map_err(|e| csv_error(path, &e))?;
    for (tcp, q) in rows {
        let mut rec = vec![tcp.to_string()];
        rec.extend(joint_fields(q, kinds));
        w.write_record(&rec).map_err(|e| csv_error(path, &e))?;
    }
    w.flush().map_err(|source| IoError::File { path: path.into(), cause: source })
}

/// Renders measurements of the canonical 7-joint Meca500-on-guide cell as CSV text (see
/// [`write_measurements`]); [`measurements_to_csv_for`] renders any chain.
pub fn measurements_to_csv(measurements: &[Measurement]) -> String {
    measurements_to_csv_for(measurements, &MECA500_ON_GUIDE_KINDS)
}

/// Renders measurements of a chain with joints `kinds` as CSV text: `q1..qN` in mm
/// (prismatic) / degrees (revolute), `dir{i}` for the revolute joints (see
/// [`write_measurements_for`]).
pub fn measurements_to_csv_for(measurements: &[Measurement], kinds: &[JointKind]) -> String {
    let joint_cols = joint_columns(kinds.len());
    let dir_cols = dir_columns(kinds);
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
    header.extend(joint_cols.iter().map(String::as_str));
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
        header.extend(dir_cols.iter().map(|(_, c)| c.as_str()));
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
        rec.extend(joint_fields(&m.q, kinds));
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
                Some(d) => rec.extend(dir_cols.iter().map(|(joint, _)| d[joint - 1].to_string())),
                None => rec.extend(std::iter::repeat_n(String::new(), dir_cols.len())),
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

/// Writes probe and/or tracker measurements of the canonical 7-joint Meca500-on-guide cell
/// with every column they use: `position` (probe), `tcp`, `q1..q7` (mm/deg), `x,y,z`
/// (tracker), `time_s`, `temperature_c`, `dir2..dir7`; [`write_measurements_for`] writes any
/// chain.
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
    write_measurements_for(path, measurements, &MECA500_ON_GUIDE_KINDS)
}

/// Writes probe and/or tracker measurements of a chain with joints `kinds` (e.g.
/// `model.joint_kinds()`): `position` (probe), `tcp`, `q1..qN` (mm for prismatic, degrees for
/// revolute joints), `x,y,z` (tracker), `time_s`, `temperature_c`, `dir{i}` of the revolute
/// joints, the centring offsets.
///
/// # Errors
/// [`IoError::File`] when the file cannot be written.
pub fn write_measurements_for(
    path: impl AsRef<Path>,
    measurements: &[Measurement],
    kinds: &[JointKind],
) -> Result<(), IoError> {
    let path = path.as_ref();
    std::fs::write(path, measurements_to_csv_for(measurements, kinds))
        .map_err(|source| IoError::File { path: path.into(), cause: source })
}

/// [`write_measurements_for`] with the instruments' noise recorded in a `# vatcal-noise:`
/// comment line before the header ([`metadata`]); without any sigma the file is the same as
/// [`write_measurements_for`]'s.
///
/// # Errors
/// [`IoError::File`] when the file cannot be written.
pub fn write_measurements_with_noise(
    path: impl AsRef<Path>,
    measurements: &[Measurement],
    kinds: &[JointKind],
    noise: &metadata::NoiseMetadata,
) -> Result<(), IoError> {
    let path = path.as_ref();
    let mut text = noise.header_line();
    text.push_str(&measurements_to_csv_for(measurements, kinds));
    std::fs::write(path, text).map_err(|source| IoError::File { path: path.into(), cause: source })
}

/// One row of a pose-request file of any chain (`vatcal compensate`): TCP `tcp` must reach the
/// world point `x,y,z` \[mm\] with the chain's last frame at Mecademic Euler angles
/// `alpha,beta,gamma` \[deg\] (intrinsic X-Y-Z), the given joints (e.g. the guide `q1`) at
/// their columns' values.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRequestRow {
    /// 1-based line number in the file
    pub line: u64,
    /// TCP id
    pub tcp: u32,
    /// one value per joint of the model (internal units): the given joints' columns, 0 for
    /// the joints the pose determines
    pub given: JointVector,
    /// TCP point in the world \[mm\]
    pub xyz_mm: [f64; 3],
    /// orientation of the last frame, intrinsic X-Y-Z Euler angles \[deg\]
    pub abc_deg: [f64; 3],
    /// optional `time_s`, `temperature_c`, `dir{i}` of the model's revolute joints
    pub context: MeasurementContext,
    /// the optional `branch` column (trimmed; `None` when absent or empty): the IK branch the
    /// row asks for, as `vatcal compensate` writes it (`0..7` on the canonical cell, `+`/`-`
    /// on another chain) — the caller parses it
    pub branch: Option<String>,
}

/// Reads pose requests of any chain: the columns `tcp`, `q{i}` for each joint `i` of `given`
/// (1-based; the joints the request fixes, e.g. `[1]` for the canonical cell's guide, none for
/// a six-joint arm), `x,y,z,alpha,beta,gamma`, the optional context columns `time_s`,
/// `temperature_c`, `dir{i}` of the model's revolute joints, and the optional `branch` column
/// (kept as text). TCP ids are checked against the
/// model, the given joints against their limits; a `q` column of a joint that is not given is
/// an error (the pose determines that joint); context columns the model's effects need must be
/// present ([`IoError::ModelNeedsColumn`]).
///
/// # Examples
/// ```
/// use vatcal_core::CellFile;
/// use vatcal_io::read_pose_requests;
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// // the canonical cell: the request gives the guide `q1` (mm), the pose determines q2..q7
/// let rows = read_pose_requests(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/compensate-poses.csv"), &model, &[1])?;
/// assert!(!rows.is_empty() && rows.iter().all(|r| model.tcp(r.tcp).is_some()));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`read_joint_rows`] (a given joint outside its limits is an [`IoError::Row`] naming
/// the column), with [`IoError::UnsupportedChain`] for a `q` column that is not one of the
/// given joints'.
pub fn read_pose_requests(
    path: impl AsRef<Path>,
    model: &Model,
    given: &[usize],
) -> Result<Vec<PoseRequestRow>, IoError> {
    let path = path.as_ref();
    let n = model.joint_count();
    let given_cols: Vec<String> = given.iter().map(|i| format!("q{i}")).collect();
    let mut required: Vec<&str> = vec!["tcp"];
    required.extend(given_cols.iter().map(String::as_str));
    required.extend(["x", "y", "z", "alpha", "beta", "gamma"]);
    let t = Table::read(path, model, &required)?;
    let stray: Vec<&str> = t
        .headers
        .iter()
        .filter(|h| h.strip_prefix('q').and_then(|k| k.parse::<usize>().ok()).is_some())
        .filter(|h| !given_cols.iter().any(|g| g == h))
        .collect();
    if !stray.is_empty() {
        return Err(IoError::UnsupportedChain {
            path: path.into(),
            reason: format!(
                "column(s) {} in the header: a pose request on this chain ({}) gives the joint columns {} \
                 and the pose determines the others",
                stray.join(","),
                model.describe_chain(),
                if given_cols.is_empty() { "none".to_string() } else { given_cols.join(",") }
            ),
        });
    }
    t.check_model_columns(model)?;
    let tcps = model.tcp_ids();
    let kinds = model.joint_kinds();
    t.convert(|line, rec| {
        let tcp = t.id(line, rec, "tcp", &tcps)?;
        let mut q = JointVector::zeros(n);
        for (i, col) in given.iter().zip(&given_cols) {
            let Some(kind) = kinds.get(i.wrapping_sub(1)) else {
                return Err(t.err(line, col, format!("the model has {n} joints")));
            };
            let v = t.float(line, rec, col)?;
            let internal = kind.from_file_unit(v);
            if let Some((lo, hi)) = model.joint_limit(*i)
                && !(lo..=hi).contains(&internal)
            {
                let unit = kind.file_unit();
                let (lo, hi) = (kind.to_file_unit(lo), kind.to_file_unit(hi));
                return Err(t.err(
                    line,
                    col,
                    format!("{v} {unit} is outside the joint limits [{lo}, {hi}] {unit}"),
                ));
            }
            q.set(*i, internal);
        }
        let f = |c: &str| t.float(line, rec, c);
        Ok(PoseRequestRow {
            line,
            tcp,
            given: q,
            xyz_mm: [f("x")?, f("y")?, f("z")?],
            abc_deg: [f("alpha")?, f("beta")?, f("gamma")?],
            context: t.context(line, rec)?,
            branch: t.field(rec, "branch").map(str::trim).filter(|b| !b.is_empty()).map(String::from),
        })
    })
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
    fn pose_requests_read_by_name_with_context_and_named_errors() {
        let m = model();
        let f = file("# poses\ngamma,beta,alpha,z,y,x,q1,tcp,time_s\n3,2,180,40,-40,60,100,2,7.5\n");
        let rows = read_pose_requests(f.path(), &m, &[1]).expect("ok");
        assert_eq!(rows.len(), 1);
        let r = &rows[0];
        assert_eq!((r.line, r.tcp, r.given.len(), r.given.get(1)), (3, 2, 7, 100.0));
        assert!((2..=7).all(|i| r.given.get(i) == 0.0), "{:?}", r.given);
        assert_eq!((r.xyz_mm, r.abc_deg), ([60.0, -40.0, 40.0], [180.0, 2.0, 3.0]));
        assert_eq!(r.context.time_s, Some(7.5));
        let cases = [
            (
                "tcp,q1,x,y,z,alpha,beta,gamma\n2,400,0,0,0,0,0,0\n",
                "q1",
                "400 mm is outside the joint limits [0, 300] mm",
            ),
            (
                "tcp,q1,x,y,z,alpha,beta,gamma,q3\n2,100,0,0,0,0,0,0,5\n",
                "q3",
                "the pose determines the others",
            ),
            ("tcp,q1,x,y,z,alpha,beta,gamma\n2,100,0,0,0,0,nan,0\n", "beta", "not finite"),
            ("tcp,q1,x,y,z,alpha,beta,gamma\n7,100,0,0,0,0,0,0\n", "tcp", "unknown tcp id 7"),
            ("tcp,q1,x,y,z,alpha,beta\n2,100,0,0,0,0,0\n", "gamma", "missing column"),
        ];
        for (text, column, reason) in cases {
            let f = file(text);
            let e = read_pose_requests(f.path(), &m, &[1]).expect_err("bad").to_string();
            assert!(e.contains(column) && e.contains(reason), "{e}");
            assert!(e.contains(&f.path().display().to_string()), "{e}");
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
        assert!(e.contains(":1: the model has 7 joints: expected the joint columns q1..q7"), "{e}");
        let f = file("position,q1,q2,q3,q4,q5,q6,q7\n1,100,0,0,0,0,0,0\n");
        let e = read_probe_measurements(f.path(), &m).expect_err("must fail").to_string();
        assert!(e.contains("missing column `tcp`"), "{e}");
        let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,0,0,0,0\n");
        let e = read_probe_measurements(f.path(), &m).expect_err("must fail").to_string();
        assert!(e.contains("malformed CSV"), "{e}");
    }

    fn fixture_model(name: &str) -> Model {
        let cell =
            CellFile::load(format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))).expect("fixture");
        Model::from_cell(&cell).expect("model")
    }

    #[test]
    fn n_joint_models_read_and_write_q1_to_qn_and_their_dir_columns() {
        let ur = fixture_model("ur5e.toml");
        let f = file(
            "tcp,q1,q2,q3,q4,q5,q6,dir1,dir2,dir3,dir4,dir5,dir6,x,y,z\n2,10,-20,30,-40,50,-60,1,-1,1,-1,1,-1,1,2,3\n",
        );
        let ms = read_tracker_measurements(f.path(), &ur).expect("ok");
        assert_eq!(ms[0].q.len(), 6);
        assert!((ms[0].q[5].to_degrees() + 60.0).abs() < 1e-12);
        assert_eq!(ms[0].context.dir_of(1), 1);
        assert_eq!(ms[0].context.dir_of(6), -1);
        let text = measurements_to_csv_for(&ms, ur.joint_kinds());
        assert!(text.starts_with("tcp,q1,q2,q3,q4,q5,q6,x,y,z,dir1,dir2,dir3,dir4,dir5,dir6\n"), "{text}");
        let out = tempfile::NamedTempFile::new().expect("tmp");
        write_measurements_for(out.path(), &ms, ur.joint_kinds()).expect("write");
        assert_eq!(read_tracker_measurements(out.path(), &ur).expect("reread"), ms);
        // the canonical cell's 7 columns on a 6-joint model: file, header line and the
        // expected columns are named
        let f = file("# seven\ntcp,q1,q2,q3,q4,q5,q6,q7\n1,0,0,0,0,0,0,0\n");
        let e = read_joint_rows(f.path(), &ur).expect_err("7 columns for 6 joints").to_string();
        assert!(
            e.contains(&format!(
                "{}:2: the model has 6 joints: expected the joint columns q1..q6",
                f.path().display()
            )),
            "{e}"
        );
        // and six columns on the 7-joint cell
        let f = file("tcp,q1,q2,q3,q4,q5,q6\n1,0,0,0,0,0,0\n");
        let e = read_joint_rows(f.path(), &model()).expect_err("6 columns for 7 joints").to_string();
        assert!(e.contains("expected the joint columns q1..q7, the header has q1,q2,q3,q4,q5,q6"), "{e}");
        // joint rows of any chain round-trip, in degrees for revolute joints
        let rows = vec![(3, ms[0].q)];
        let out = tempfile::NamedTempFile::new().expect("tmp");
        write_joint_rows_for(out.path(), &rows, ur.joint_kinds()).expect("write");
        let back = read_joint_rows(out.path(), &ur).expect("reread");
        assert_eq!((back[0].tcp, back[0].q), (3, ms[0].q));
        // limits of the Meca500 alone, in degrees
        let meca = fixture_model("meca500-table.toml");
        let f = file("tcp,q1,q2,q3,q4,q5,q6\n1,0,95,0,0,0,0\n");
        let e = read_joint_rows(f.path(), &meca).expect_err("J2 limit").to_string();
        assert!(e.contains(":2: column `q2`: 95 deg is outside the joint limits"), "{e}");
        // a canonical-cell pose request (with the guide `q1`) on a six-joint arm, where the
        // pose determines every joint: the stray column and the chain are named
        let f = file("tcp,q1,x,y,z,alpha,beta,gamma\n1,0,0,0,0,0,0,0\n");
        let e = read_pose_requests(f.path(), &ur, &[]).expect_err("no guide on the arm").to_string();
        assert!(
            e.contains("column(s) q1 in the header") && e.contains("gives the joint columns none"),
            "{e}"
        );
        // and the arm's own requests are read
        let f = file("tcp,x,y,z,alpha,beta,gamma\n1,400,100,300,180,0,0\n");
        let rows = read_pose_requests(f.path(), &ur, &[]).expect("six-joint request");
        assert_eq!((rows[0].given.len(), rows[0].xyz_mm), (6, [400.0, 100.0, 300.0]));
    }

    /// A backlash on joint i needs exactly the column `dir{i}`, on any chain: the error names
    /// that column, and a file with only that direction column is read (the other revolute
    /// joints' directions are then unknown, 0).
    #[test]
    fn a_backlash_needs_its_joints_dir_column_on_any_chain() {
        use vatcal_core::effects::EffectSpec;
        let mut ur = fixture_model("ur5e.toml");
        ur.enable_effect(EffectSpec::JointBacklash { joint: 4 }).expect("backlash on joint 4");
        let f = file("tcp,q1,q2,q3,q4,q5,q6,dir1,dir2,dir3,dir5,dir6\n1,10,-20,30,-40,50,-60,1,1,1,1,1\n");
        let e = read_joint_rows(f.path(), &ur).expect_err("no dir4").to_string();
        assert!(
            e.contains(&format!(
                "{}: the model's joint-backlash (joint 4) needs the column(s) dir4,",
                f.path().display()
            )),
            "{e}"
        );
        let f = file("tcp,q1,q2,q3,q4,q5,q6,dir4,x,y,z\n1,10,-20,30,-40,50,-60,-1,1,2,3\n");
        let ms = read_tracker_measurements(f.path(), &ur).expect("dir4 alone");
        assert_eq!((ms[0].context.dir_of(4), ms[0].context.dir_of(3)), (-1, 0));
        let f = file("tcp,q1,q2,q3,q4,q5,q6,dir4\n1,10,-20,30,-40,50,-60,\n");
        let e = read_joint_rows(f.path(), &ur).expect_err("empty dir4").to_string();
        assert!(
            e.contains(":2: column `dir4`: empty, but the model's joint-backlash (joint 4) needs it"),
            "{e}"
        );
        // a 12-joint chain: the column of joint 11
        let cell = twelve_joint_cell();
        let mut m = Model::from_cell(&cell).expect("12 joints");
        m.enable_effect(EffectSpec::JointBacklash { joint: 11 }).expect("backlash on joint 11");
        let header = (1..=12).map(|i| format!("q{i}")).collect::<Vec<_>>().join(",");
        let f = file(&format!("tcp,{header}\n1{}\n", ",0".repeat(12)));
        let e = read_joint_rows(f.path(), &m).expect_err("no dir11").to_string();
        assert!(e.contains("needs the column(s) dir11,"), "{e}");
        let f = file(&format!("tcp,{header},dir11\n1{},1\n", ",0".repeat(12)));
        let rows = read_joint_rows(f.path(), &m).expect("dir11");
        assert_eq!(rows[0].context.dir_of(11), 1);
    }

    /// The UR5e fixture with its six revolute rows repeated: 12 revolute joints.
    fn twelve_joint_cell() -> CellFile {
        let mut cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))
            .expect("fixture");
        let mut more = cell.joints.clone();
        for (k, j) in more.iter_mut().enumerate() {
            j.index = 7 + k as u8;
        }
        cell.joints.extend(more);
        cell
    }

    /// Rows are converted in parallel: the order is kept, and with several bad rows the error
    /// is the first one's, whichever thread meets it first.
    /// The parallel row parser gives the sequential reader's rows (fields, line numbers,
    /// positions) on a large file with comments, blank lines, all-empty rows and padded
    /// fields, and declines (so that the sequential reader words the error) on quotes,
    /// carriage returns and rows with the wrong field count.
    #[test]
    fn parallel_rows_equal_the_sequential_reader() {
        let mut text = String::from("# candidates\n\n a , b ,c\n");
        for k in 0..30_000 {
            match k % 997 {
                3 => text.push_str("# a comment line\n"),
                5 => text.push('\n'),
                7 => text.push_str(",,\n"),
                11 => text.push_str("  \t\n"),
                _ => {}
            }
            text.push_str(&format!("{k}, {} ,x{}\n", k as f64 * 0.25, k % 7));
        }
        text.push_str("last,1,2"); // no final line end
        let sequential = |t: &str| {
            let mut rdr = table_reader(t.as_bytes());
            rdr.headers().expect("header");
            sequential_rows(&mut rdr, Path::new("x.csv"))
        };
        let parallel = |t: &str| {
            let mut rdr = table_reader(t.as_bytes());
            let fields = rdr.headers().expect("header").len();
            parallel_rows(t.as_bytes(), rdr.position(), fields)
        };
        // a line of blanks is a one-field record: the sequential reader rejects it...
        assert!(sequential(&text).is_err());
        assert!(parallel(&text).is_none());
        let text = text.replace("  \t\n", "");
        let want = sequential(&text).expect("sequential");
        let got = parallel(&text).expect("parallel");
        assert!(text.len() > 3 * PARSE_CHUNK, "the file spans several chunks");
        assert_eq!(got.len(), want.len());
        for ((gl, gr), (wl, wr)) in got.iter().zip(&want) {
            assert_eq!((gl, gr), (wl, wr));
            assert_eq!(gr.position(), wr.position(), "line {wl}");
        }
        // quotes and carriage returns go to the sequential reader
        assert!(parallel(&text.replacen("x3", "\"x3\"", 1)).is_none());
        assert!(parallel(&text.replacen("x3\n", "x3\r\n", 1)).is_none());
        assert!(parallel(&text.replacen("x3\n", "x3,extra\n", 1)).is_none());
    }

    #[test]
    fn large_files_keep_row_order_and_report_the_first_bad_row() {
        let m = model();
        let mut text = String::from("position,tcp,q1,q2,q3,q4,q5,q6,q7\n");
        for i in 0..3000 {
            text.push_str(&format!("{},1,{},0,0,0,0,0,0\n", 1 + i % 3, f64::from(i) * 0.1));
        }
        let f = file(&text);
        let c = read_candidates(f.path(), &m).expect("ok");
        assert_eq!(c.measurements.len(), 3000);
        for (i, ms) in c.measurements.iter().enumerate() {
            assert_eq!(ms.position(), Some(1 + i as u32 % 3));
            assert_eq!(ms.q.to_mm_deg()[0], i as f64 * 0.1, "row {i}");
            assert_eq!(c.lines[i], i as u64 + 2);
        }
        // bad rows at data rows 2500 and 700 (file lines 2502 and 702): line 702 is named
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        lines[2501] = "1,1,0,0,0,0,0,x,0".into();
        lines[701] = "1,9,0,0,0,0,0,0,0".into();
        let f = file(&(lines.join("\n") + "\n"));
        for e in [
            read_candidates(f.path(), &m).expect_err("bad rows").to_string(),
            read_probe_measurements(f.path(), &m).expect_err("bad rows").to_string(),
        ] {
            assert!(e.contains(":702:") && e.contains("unknown tcp id 9"), "{e}");
        }
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

    /// Item 5 of issue 20: a measured joint slightly beyond its limit is a warning naming file,
    /// line and joint; further than the tolerance, an error; the readers without options (and
    /// so planning and compensation) keep the limits strict.
    #[test]
    fn limit_tolerance_warns_within_and_refuses_beyond() {
        let m = model(); // canonical cell: q1 guide [0, 300] mm, q3 = Meca500 J2 [-70, 90] deg
        let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,10,0,0,0,0\n1,1,300.2,0,90.3,0,0,0,0\n");
        let read = read_probe_measurements_with(f.path(), &m, &ReadOptions::default()).expect("within");
        assert_eq!(read.rows.len(), 2);
        let w: Vec<String> = read.warnings.iter().map(ToString::to_string).collect();
        assert_eq!(w.len(), 2, "{w:?}");
        let name = f.path().display().to_string();
        assert!(
            w[0].starts_with(&format!("{name}:3: column `q1`: 300.2 mm is beyond the joint limits")),
            "{w:?}"
        );
        assert!(w[1].starts_with(&format!("{name}:3: column `q3`: 90.3 deg is beyond")), "{w:?}");
        assert!(w[1].contains("by 0.3000 deg") && w[1].contains("tolerance of 0.5 deg"), "{w:?}");
        // the value is read as measured (not clamped)
        assert!((read.rows[1].q[2] - 90.3f64.to_radians()).abs() < 1e-12);
        // strict readers: an error, as before
        let e = read_probe_measurements(f.path(), &m).expect_err("strict").to_string();
        assert!(e.contains(":3: column `q1`") && e.contains("outside the joint limits"), "{e}");
        // beyond the tolerance: an error naming file, line, joint and the tolerance
        let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,10,0,0,0,0\n1,1,100,0,91,0,0,0,0\n");
        let e = read_probe_measurements_with(f.path(), &m, &ReadOptions::default())
            .expect_err("1 deg")
            .to_string();
        assert!(
            e.contains(":3: column `q3`: 91 deg is outside the joint limits [-70, 90] deg (by 1.0000 deg")
                && e.contains("tolerance of 0.5 deg"),
            "{e}"
        );
        assert!(!e.contains("--angle-unit"), "no unit hint for a value that fits no other unit: {e}");
        // a larger tolerance reads it
        let wide = ReadOptions {
            limit_tolerance: LimitTolerance { revolute_deg: 2.0, prismatic_mm: 0.5 },
            ..ReadOptions::default()
        };
        assert_eq!(read_probe_measurements_with(f.path(), &m, &wide).expect("2 deg").warnings.len(), 1);
    }

    /// Issue 29: every row read with options carries its line (comments and blank lines
    /// skipped), so a later step can name it `file:line`.
    #[test]
    fn rows_read_with_options_know_their_lines() {
        let m = model();
        let f = file(
            "# vatcal-noise: probe_sigma_mm=0.002\nposition,tcp,q1,q2,q3,q4,q5,q6,q7,x,y,z\n1,1,100,0,10,0,0,0,0,,,\n\n# a comment\n,1,120,0,12,0,0,0,0,1,2,3\n",
        );
        let read = read_measurements_with(f.path(), &m, &ReadOptions::default()).expect("read");
        assert_eq!(read.lines, vec![3, 6]);
        let sources = read.sources();
        assert_eq!(sources.len(), read.rows.len());
        assert_eq!(sources[1].to_string(), format!("{}:6", f.path().display()));
        // an error on a row after blank and comment lines names the row's own line
        let f = file(
            "position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,100,0,10,0,0,0,0\n\n# c\n# d\n1,1,100,0,x,0,0,0,0\n",
        );
        let e = read_probe_measurements(f.path(), &m).expect_err("bad q3").to_string();
        assert!(e.contains(":6: column `q3`"), "{e}");
    }

    /// Item 6: metres and radians are read as mm and radians; a file that does not look like
    /// the stated units is refused with a hint naming the other unit.
    #[test]
    fn units_are_options_and_mismatches_are_named() {
        let ur = fixture_model("ur5e.toml");
        let deg = file("tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,10,-80,90,-100,-90,30,400,-100.5,250\n");
        let (q, rad) = ([10.0f64, -80.0, 90.0, -100.0, -90.0, 30.0], "");
        let rad_row: Vec<String> = q.iter().map(|v| v.to_radians().to_string()).collect();
        let si =
            file(&format!("tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,{},0.4,-0.1005,0.25\n{rad}", rad_row.join(",")));
        let options =
            ReadOptions { length_unit: LengthUnit::M, angle_unit: AngleUnit::Rad, ..ReadOptions::default() };
        let a = read_tracker_measurements(deg.path(), &ur).expect("deg");
        let b = read_tracker_measurements_with(si.path(), &ur, &options).expect("SI");
        assert!(b.warnings.is_empty());
        for k in 0..6 {
            assert!((a[0].q[k] - b.rows[0].q[k]).abs() < 1e-12, "joint {k}");
        }
        let (Target::Tracker { xyz_mm: pa }, Target::Tracker { xyz_mm: pb }) =
            (a[0].target, b.rows[0].target)
        else {
            panic!("tracker rows");
        };
        assert!((pa - pb).norm() < 1e-9, "{pa} vs {pb}");
        // radians read as degrees: every angle within ±2π "degrees" on 3+ rows
        let text = format!(
            "tcp,q1,q2,q3,q4,q5,q6\n1,{}\n1,0.1,0.2,0.3,0.4,0.5,0.6\n1,0,0,0,0,0,0\n",
            rad_row.join(",")
        );
        let f = file(&text);
        let e =
            read_joint_rows_with(f.path(), &ur, &ReadOptions::default()).expect_err("radians").to_string();
        assert!(
            e.contains(":2: column `q4`: every revolute joint value") && e.contains("--angle-unit rad"),
            "{e}"
        );
        assert!(
            read_joint_rows_with(
                f.path(),
                &ur,
                &ReadOptions { angle_unit: AngleUnit::Rad, ..ReadOptions::default() }
            )
            .is_ok()
        );
        assert!(read_joint_rows(f.path(), &ur).is_ok(), "the readers without options have no heuristics");
        // degrees read as radians: more than two turns
        let f = file("tcp,q1,q2,q3,q4,q5,q6\n1,10,-80,90,-100,-90,30\n");
        let e = read_joint_rows_with(
            f.path(),
            &ur,
            &ReadOptions { angle_unit: AngleUnit::Rad, ..ReadOptions::default() },
        )
        .expect_err("degrees")
        .to_string();
        assert!(
            e.contains(":2: column `q1`: 10 rad is outside the joint limits")
                && e.contains("--angle-unit deg"),
            "{e}"
        );
        // more than two turns: the magnitude alone tells
        let f = file("tcp,q1,q2,q3,q4,q5,q6\n1,0.1,-80,0,0,0,0\n");
        let e = read_joint_rows_with(
            f.path(),
            &ur,
            &ReadOptions { angle_unit: AngleUnit::Rad, ..ReadOptions::default() },
        )
        .expect_err("degrees")
        .to_string();
        assert!(
            e.contains(":2: column `q2`: -80 rad is implausible") && e.contains("--angle-unit deg"),
            "{e}"
        );
        // millimetres read as metres
        let e = read_tracker_measurements_with(
            deg.path(),
            &ur,
            &ReadOptions { length_unit: LengthUnit::M, ..ReadOptions::default() },
        )
        .map(|_| ())
        .expect_err("mm as m");
        assert!(
            e.to_string().contains(":2: column `x`: 400 m is more than 100 m")
                && e.to_string().contains("--length-unit mm"),
            "{e}"
        );
        // metres read as millimetres: every tracker coordinate within ±10 mm
        let f = file(
            "tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,10,-80,90,-100,-90,30,0.4,0.1,0.3\n\
             1,12,-80,90,-100,-90,30,0.41,0.12,0.3\n1,14,-80,90,-100,-90,30,0.42,0.14,-0.52\n",
        );
        for read in [read_tracker_measurements_with, read_measurements_with] {
            let e =
                read(f.path(), &ur, &ReadOptions::default()).map(|_| ()).expect_err("m as mm").to_string();
            assert!(
                e.contains(":4: column `z`: every tracker coordinate") && e.contains("--length-unit m"),
                "{e}"
            );
            let ok =
                read(f.path(), &ur, &ReadOptions { length_unit: LengthUnit::M, ..ReadOptions::default() });
            assert!(ok.is_ok(), "read in metres");
        }
        // a guide in metres beyond its limit in mm hints at the unit
        let m = model();
        let f = file("position,tcp,q1,q2,q3,q4,q5,q6,q7\n1,1,150,0,10,0,0,0,0\n");
        let e = read_probe_measurements_with(
            f.path(),
            &m,
            &ReadOptions { length_unit: LengthUnit::M, ..ReadOptions::default() },
        )
        .expect_err("150 m")
        .to_string();
        assert!(e.contains(":2: column `q1`") && e.contains("--length-unit mm"), "{e}");
    }

    /// Item 6: the approach directions from the row order, on any chain; a file with its own
    /// `dir` columns is refused; a backlash model reads a file without `dir` columns then.
    #[test]
    fn directions_derived_from_the_row_order() {
        use vatcal_core::effects::EffectSpec;
        let mut ur = fixture_model("ur5e.toml");
        ur.enable_effect(EffectSpec::JointBacklash { joint: 4 }).expect("backlash on joint 4");
        let f = file(
            "tcp,q1,q2,q3,q4,q5,q6\n1,10,-80,90,-100,-90,30\n1,10,-80,90,-90,-90,30\n1,12,-80,90,-95,-90,30\n",
        );
        let e =
            read_joint_rows_with(f.path(), &ur, &ReadOptions::default()).expect_err("no dir4").to_string();
        assert!(e.contains("needs the column(s) dir4"), "{e}");
        let options = ReadOptions { dir_from_row_order: true, ..ReadOptions::default() };
        let rows = read_joint_rows_with(f.path(), &ur, &options).expect("derived").rows;
        let dirs: Vec<(i8, i8, i8)> =
            rows.iter().map(|r| (r.context.dir_of(1), r.context.dir_of(4), r.context.dir_of(6))).collect();
        assert_eq!(dirs, vec![(0, 0, 0), (0, 1, 0), (1, -1, 0)]);
        let f = file("tcp,q1,q2,q3,q4,q5,q6,dir4\n1,10,-80,90,-100,-90,30,1\n");
        let e = read_joint_rows_with(f.path(), &ur, &options).expect_err("own dir4").to_string();
        assert!(e.contains("has its own direction column `dir4`"), "{e}");
    }

    /// Issue 31: markers the model lacks are read with `any_tcp_id` (the caller adds them),
    /// refused without it; positions are still checked.
    #[test]
    fn any_tcp_id_reads_markers_the_model_lacks() {
        let ur = fixture_model("ur5e.toml");
        let f = file(
            "tcp,q1,q2,q3,q4,q5,q6,x,y,z\n1,10,-80,90,-100,-90,30,1,2,3\n7,10,-80,90,-100,-90,30,4,5,6\n",
        );
        let e =
            read_measurements_with(f.path(), &ur, &ReadOptions::default()).expect_err("tcp 7").to_string();
        assert!(e.contains(":3: column `tcp`: unknown tcp id 7 (the model has [1, 2, 3])"), "{e}");
        let options = ReadOptions { any_tcp_id: true, ..ReadOptions::default() };
        let rows = read_measurements_with(f.path(), &ur, &options).expect("any tcp").rows;
        assert_eq!(rows.iter().map(|m| m.tcp).collect::<Vec<_>>(), [1, 7]);
        let f = file("position,tcp,q1,q2,q3,q4,q5,q6\n7,7,10,-80,90,-100,-90,30\n");
        let e = read_measurements_with(f.path(), &ur, &options).expect_err("position 7").to_string();
        assert!(e.contains("unknown position id 7"), "{e}");
    }
}
