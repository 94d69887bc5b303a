//! Probe measurements `position,tcp,q1..qN` and tracker measurements `tcp,q1..qN,x,y,z`, apart
//! or mixed in one file.

use std::path::Path;

use nalgebra::Vector3;
use vatcal_core::{Measurement, Target};
use vatcal_kinematics::Model;

use crate::columns::{OFFSET_COLUMNS, joint_columns, span};
use crate::error::IoError;
use crate::options::{ReadOptions, ReadOutcome};
use crate::table::{RowIds, Table};

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
/// As [`read_joint_rows`](crate::read_joint_rows); the `position` id is checked against the model too.
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
/// As [`read_joint_rows`](crate::read_joint_rows); `x,y,z` must be finite numbers.
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

/// [`read_probe_measurements`] with reader options (see
/// [`read_joint_rows_with`](crate::read_joint_rows_with)).
///
/// # Errors
/// As [`read_probe_measurements`] and [`read_joint_rows_with`](crate::read_joint_rows_with).
pub fn read_probe_measurements_with(
    path: impl AsRef<Path>,
    model: &Model,
    options: &ReadOptions,
) -> Result<ReadOutcome<Measurement>, IoError> {
    let path = path.as_ref();
    let t = Table::read_model_rows(path, model, &["position", "tcp"], &[], *options)?;
    let ids = RowIds::of(model);
    let rows = t.convert(|line, rec| t.probe_measurement(line, rec, model, &ids))?;
    t.finish(model, rows, |m| &m.q, |m| &mut m.context)
}

/// [`read_tracker_measurements`] with reader options (see
/// [`read_joint_rows_with`](crate::read_joint_rows_with)); `x,y,z` are in the options' length unit.
///
/// # Errors
/// As [`read_tracker_measurements`] and [`read_joint_rows_with`](crate::read_joint_rows_with).
pub fn read_tracker_measurements_with(
    path: impl AsRef<Path>,
    model: &Model,
    options: &ReadOptions,
) -> Result<ReadOutcome<Measurement>, IoError> {
    let path = path.as_ref();
    let t = Table::read_model_rows(path, model, &["tcp"], &["x", "y", "z"], *options)?;
    let ids = RowIds::of(model);
    let rows = t.convert(|line, rec| t.tracker_measurement(line, rec, model, &ids))?;
    t.check_tracker_length_unit(&rows)?;
    t.finish(model, rows, |m| &m.q, |m| &mut m.context)
}

/// [`read_measurements`] (probe and/or tracker rows) with reader options (see
/// [`read_joint_rows_with`](crate::read_joint_rows_with)); tracker `x,y,z` are in the options' length
/// unit.
///
/// # Errors
/// As [`read_measurements`] and [`read_joint_rows_with`](crate::read_joint_rows_with).
pub fn read_measurements_with(
    path: impl AsRef<Path>,
    model: &Model,
    options: &ReadOptions,
) -> Result<ReadOutcome<Measurement>, IoError> {
    let path = path.as_ref();
    let t = Table::read_model_rows(path, model, &["tcp"], &[], *options)?;
    let has_xyz = t.has("x") && t.has("y") && t.has("z");
    let q = span(&joint_columns(model.joint_count()));
    if t.has("normal") && !t.has("plane") {
        return Err(t.err(
            t.header_line,
            "plane",
            format!("the header has `normal` but no `plane`: a plane row needs its plane's id (plane,tcp,{q}[,normal])"),
        ));
    }
    if !t.has("position") && !has_xyz && !t.has("plane") {
        return Err(t.err(
            t.header_line,
            "position / x,y,z / plane",
            format!(
                "the header has neither probe rows' `position`, tracker rows' `x,y,z` nor plane rows' `plane` (probe rows: position,tcp,{q}; tracker rows: tcp,{q},x,y,z; plane rows: plane,tcp,{q})"
            ),
        ));
    }
    let ids = RowIds::of(model);
    let rows = t.convert(|line, rec| {
        let filled = |c: &str| t.field(rec, c).is_some_and(|s| !s.is_empty());
        let (has_pos, has_plane) = (filled("position"), filled("plane"));
        if has_pos && has_plane {
            return Err(t.err(line, "plane", "a row is a probe row (`position`) or a plane row (`plane`), not both"));
        }
        if has_plane {
            return t.plane_measurement(line, rec, model, &ids);
        }
        if !has_pos && !filled("x") {
            let column = if filled("normal") || (t.has("plane") && !t.has("position") && !has_xyz) {
                "plane"
            } else if t.has("position") {
                "position"
            } else {
                "x"
            };
            return Err(t.err(
                line,
                column,
                "empty: a probe row needs `position`, a tracker row `x,y,z`, a plane row `plane` (this row has none)",
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

impl Table {
    /// A probe row's measurement: `position`, `tcp`, the joints, the context columns and the
    /// optional probe offset.
    pub(crate) fn probe_measurement(
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

    /// A plane row's measurement: `plane` (any id: planes the cell file lacks are identified),
    /// the optional `normal` (`1`/`true`: the tool axis was held normal to the plane; empty,
    /// `0`, `false`: not), `tcp`, the joints and the context columns.
    pub(crate) fn plane_measurement(
        &self,
        line: u64,
        rec: &csv::StringRecord,
        model: &Model,
        ids: &RowIds,
    ) -> Result<Measurement, IoError> {
        let plane = self.any_id(line, rec, "plane")?;
        let normal = match self.field(rec, "normal").map(str::trim).unwrap_or("") {
            "" | "0" | "false" => false,
            "1" | "true" => true,
            other => {
                return Err(self.err(
                    line,
                    "normal",
                    format!("`{other}` is not 1/true or 0/false (empty: 0)"),
                ));
            }
        };
        self.measurement(line, rec, model, ids, Target::Plane { plane, normal })
    }

    /// A tracker row's measurement: `tcp`, the joints, the context columns and `x,y,z` in the
    /// table's length unit.
    pub(crate) fn tracker_measurement(
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
    pub(crate) fn measurement(
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
    pub(crate) fn probe_offset(
        &self,
        line: u64,
        rec: &csv::StringRecord,
    ) -> Result<Option<Vector3<f64>>, IoError> {
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
