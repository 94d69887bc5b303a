//! Joint rows `tcp,q1..qN` (input of `vatcal fk` / `vatcal torque`).

use std::path::Path;

use vatcal_core::{JointVector, MeasurementContext};
use vatcal_kinematics::Model;

use crate::error::IoError;
use crate::options::{ReadOptions, ReadOutcome};
use crate::table::Table;

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
    let t = Table::read_model_rows(path, model, &["tcp"], &[], *options)?;
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
