//! The table every reader parses first: the header's columns found by name, the rows with their
//! lines, the model's context columns checked, and the per-row field lookups (numbers, ids,
//! the context columns) that name the line and column of a bad value.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use rayon::prelude::*;
use vatcal_core::{MAX_JOINTS, MeasurementContext};
use vatcal_kinematics::Model;

use crate::columns::{OFFSET_COLUMNS, dir_columns, joint_columns, span};
use crate::error::{IoError, csv_error};
use crate::options::{ReadOptions, ReadWarning};
use crate::row_lines::{parallel_rows, record_lines, sequential_rows, table_reader};

/// A parsed CSV table with a name → index header map.
pub(crate) struct Table {
    pub(crate) path: PathBuf,
    pub(crate) headers: csv::StringRecord,
    /// `(column name, field index)`, first occurrence of each name; searched linearly (a few
    /// columns: cheaper than hashing the name at every field lookup of every row)
    pub(crate) index: Vec<(String, usize)>,
    pub(crate) rows: Vec<(u64, csv::StringRecord)>,
    /// field indices of the columns every row reads, resolved once from the header
    pub(crate) cols: RowColumns,
    /// units, limit tolerance, unit checks ([`ReadOptions::strict`] for the readers without
    /// options)
    pub(crate) opts: ReadOptions,
    /// warnings met while converting rows (any order; sorted by line when returned)
    pub(crate) warnings: Mutex<Vec<ReadWarning>>,
    /// 1-based line of the header
    pub(crate) header_line: u64,
}

/// Field indices of the columns read on every row, so that a row costs no name lookups.
pub(crate) struct RowColumns {
    /// `(name, field)` of `q1..qN` of the model (empty when the table has no joint columns;
    /// the field is None when the header lacks it)
    pub(crate) joints: Vec<(String, Option<usize>)>,
    /// `(joint, name, field)` of the `dir{i}` columns the file has
    pub(crate) dirs: Vec<(usize, String, usize)>,
    pub(crate) time_s: Option<usize>,
    pub(crate) temperature_c: Option<usize>,
    pub(crate) offsets: [Option<usize>; 3],
}

/// The model's TCP and calibration-position ids, looked up once per file (every row's `tcp`
/// and `position` is checked against them).
pub(crate) struct RowIds {
    pub(crate) tcps: Vec<u32>,
    pub(crate) positions: Vec<u32>,
}

impl RowIds {
    pub(crate) fn of(model: &Model) -> Self {
        Self { tcps: model.tcp_ids(), positions: model.position_ids() }
    }
}

/// Fails unless the joint columns `q{k}` of the header are exactly `q1..qN` of an `n`-joint
/// model ([`IoError::JointColumns`] naming the header line).
fn check_joint_columns(
    path: &Path,
    headers: &csv::StringRecord,
    header_line: u64,
    n: usize,
) -> Result<(), IoError> {
    let mut found: Vec<usize> =
        headers.iter().filter_map(|h| h.strip_prefix('q').and_then(|k| k.parse::<usize>().ok())).collect();
    found.sort_unstable();
    if found == (1..=n).collect::<Vec<_>>() {
        return Ok(());
    }
    let found = found.iter().map(|k| format!("q{k}")).collect::<Vec<_>>().join(",");
    Err(IoError::JointColumns {
        path: path.into(),
        line: header_line,
        joints: n,
        expected: span(&joint_columns(n)),
        found: if found.is_empty() { "none".into() } else { found },
    })
}

impl RowColumns {
    /// The fields of the model's joint columns (when `joint_columns_of_model`), its `dir{i}`
    /// columns the header has, and the context and offset columns, from the header's `index`.
    fn of(index: &[(String, usize)], model: &Model, joint_columns_of_model: bool) -> Self {
        let column = |c: &str| index.iter().find(|(name, _)| name == c).map(|(_, i)| *i);
        let joint_names =
            if joint_columns_of_model { joint_columns(model.joint_count()) } else { Vec::new() };
        RowColumns {
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
        }
    }
}

impl Table {
    /// Reads a table whose joint columns must be exactly `q1..qN` of `model`.
    pub(crate) fn read_for(path: &Path, model: &Model, required: &[String]) -> Result<Table, IoError> {
        Self::read_for_with(path, model, required, ReadOptions::strict())
    }

    /// [`Self::read_for`] with reader options.
    pub(crate) fn read_for_with(
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

    /// Reads a table of `model`'s rows: the columns `prefix`, the model's joint columns, then
    /// `suffix` required ([`crate::columns::required_columns`]), read with `opts` and checked
    /// against the model's joints ([`Table::check_model_columns`]) — the start of every reader
    /// of joint rows.
    pub(crate) fn read_model_rows(
        path: &Path,
        model: &Model,
        prefix: &[&str],
        suffix: &[&str],
        opts: ReadOptions,
    ) -> Result<Table, IoError> {
        let t =
            Self::read_for_with(path, model, &crate::columns::required_columns(prefix, model, suffix), opts)?;
        t.check_model_columns(model)?;
        Ok(t)
    }

    /// Reads a table of `model`'s rows without joint columns of its own (pose requests: the
    /// caller checks its `q` columns).
    pub(crate) fn read(path: &Path, model: &Model, required: &[&str]) -> Result<Table, IoError> {
        Self::read_checked(path, required, model, false)
    }

    /// Reads the file: its header (the first line neither blank nor a comment; its joint
    /// columns exactly the model's `q1..qN` when `joint_columns_of_model`, every `required`
    /// column present) and its data rows with their lines.
    pub(crate) fn read_checked(
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
            check_joint_columns(path, &headers, header_line, model.joint_count())?;
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
        let cols = RowColumns::of(&index, model, joint_columns_of_model);
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
    pub(crate) fn check_model_columns(&self, model: &Model) -> Result<(), IoError> {
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

    pub(crate) fn has(&self, col: &str) -> bool {
        self.column(col).is_some()
    }

    pub(crate) fn column(&self, col: &str) -> Option<usize> {
        self.index.iter().find(|(name, _)| name == col).map(|(_, i)| *i)
    }

    pub(crate) fn field<'a>(&self, rec: &'a csv::StringRecord, col: &str) -> Option<&'a str> {
        self.column(col).and_then(|i| rec.get(i))
    }

    /// Converts every row with `f`, in parallel; the rows keep their order and an error is the
    /// one of the first bad row (as a sequential pass would report).
    pub(crate) fn convert<T: Send>(
        &self,
        f: impl Fn(u64, &csv::StringRecord) -> Result<T, IoError> + Sync,
    ) -> Result<Vec<T>, IoError> {
        let results: Vec<Result<T, IoError>> =
            self.rows.par_iter().with_min_len(256).map(|(line, rec)| f(*line, rec)).collect();
        results.into_iter().collect()
    }

    pub(crate) fn err(&self, line: u64, column: &str, reason: impl Into<String>) -> IoError {
        IoError::Row { path: self.path.clone(), line, column: column.into(), reason: reason.into() }
    }

    pub(crate) fn float(&self, line: u64, rec: &csv::StringRecord, col: &str) -> Result<f64, IoError> {
        self.float_at(line, rec, col, self.column(col))
    }

    /// [`Self::float`] of column `col` at the already resolved field `index`.
    pub(crate) fn float_at(
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
    pub(crate) fn optional_float_at(
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

    pub(crate) fn id(
        &self,
        line: u64,
        rec: &csv::StringRecord,
        col: &str,
        known: &[u32],
    ) -> Result<u32, IoError> {
        let v = self.any_id(line, rec, col)?;
        let free_point = col == "position" && self.opts.any_position_id;
        let free_tcp = col == "tcp" && self.opts.any_tcp_id;
        if !(known.contains(&v) || free_point || free_tcp) {
            return Err(self.err(line, col, format!("unknown {col} id {v} (the model has {known:?})")));
        }
        Ok(v)
    }

    /// A non-negative integer id in column `col`, not checked against the model (e.g. a
    /// contact plane's: planes the cell file lacks are identified).
    pub(crate) fn any_id(&self, line: u64, rec: &csv::StringRecord, col: &str) -> Result<u32, IoError> {
        let s = self.field(rec, col).unwrap_or("");
        s.parse().map_err(|_| self.err(line, col, format!("`{s}` is not a non-negative integer id")))
    }

    pub(crate) fn warn(&self, line: u64, column: &str, message: String) {
        let w = ReadWarning { path: self.path.clone(), line, column: column.into(), message };
        match self.warnings.lock() {
            Ok(mut v) => v.push(w),
            Err(poisoned) => poisoned.into_inner().push(w),
        }
    }

    /// The warnings met, in line order.
    pub(crate) fn take_warnings(&self) -> Vec<ReadWarning> {
        let mut w = match self.warnings.lock() {
            Ok(mut v) => std::mem::take(&mut *v),
            Err(poisoned) => std::mem::take(&mut *poisoned.into_inner()),
        };
        w.sort_by(|a, b| (a.line, &a.column).cmp(&(b.line, &b.column)));
        w
    }

    pub(crate) fn context(&self, line: u64, rec: &csv::StringRecord) -> Result<MeasurementContext, IoError> {
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
}
