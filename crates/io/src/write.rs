//! The writers: joint rows and probe/tracker measurements of any chain, with the optional
//! context columns, centring offsets and the noise metadata line.

use std::path::Path;

use nalgebra::UnitQuaternion;
use vatcal_core::{JointKind, JointVector, MECA500_ON_GUIDE_KINDS, Measurement, Target};

use crate::columns::{OFFSET_COLUMNS, dir_columns, joint_columns};
use crate::error::{IoError, csv_error};
use crate::metadata;

pub(crate) fn writer(path: &Path) -> Result<csv::Writer<std::fs::File>, IoError> {
    let f =
        std::fs::File::create(path).map_err(|source| IoError::File { path: path.into(), cause: source })?;
    Ok(csv::Writer::from_writer(f))
}

/// The joint values of `q` in file units, `kinds.len()` fields (a missing value is empty).
pub(crate) fn joint_fields(q: &JointVector, kinds: &[JointKind]) -> Vec<String> {
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
/// [`write_measurements_for`]). A tracker measurement directly followed by an orientation
/// measurement of the same TCP, posture and context (as the pose reader returns a pose row) is
/// written as one pose row `x,y,z,qw,qx,qy,qz`: a file of pose rows reads back with
/// [`read_pose_measurements`](crate::read_pose_measurements).
pub fn measurements_to_csv_for(measurements: &[Measurement], kinds: &[JointKind]) -> String {
    let rows = pose_pairs(measurements);
    let columns = Columns::of(measurements, kinds);
    let mut out = columns.header().join(",");
    out.push('\n');
    for (m, rotation) in &rows {
        out.push_str(&columns.record(m, *rotation, kinds).join(","));
        out.push('\n');
    }
    out
}

/// The rows to write: each measurement with its rotation (an orientation measurement's own,
/// or the one of the orientation measurement that follows a tracker measurement of the same
/// TCP, posture and context, merged into its pose row).
fn pose_pairs(measurements: &[Measurement]) -> Vec<(Measurement, Option<UnitQuaternion<f64>>)> {
    let mut rows = Vec::with_capacity(measurements.len());
    let mut k = 0;
    while k < measurements.len() {
        let m = measurements[k];
        let next = measurements.get(k + 1).and_then(|n| match n.target {
            Target::Orientation { rotation } if matches!(m.target, Target::Tracker { .. }) => {
                (Measurement { target: m.target, ..*n } == m).then_some(rotation)
            }
            _ => None,
        });
        let own = match m.target {
            Target::Orientation { rotation } => Some(rotation),
            _ => None,
        };
        rows.push((m, next.or(own)));
        k += if next.is_some() { 2 } else { 1 };
    }
    rows
}

/// Which columns a set of measurements needs.
struct Columns {
    joints: Vec<String>,
    dirs: Vec<(usize, String)>,
    probe: bool,
    plane: bool,
    normal: bool,
    position: bool,
    rotation: bool,
    time: bool,
    temp: bool,
    dir: bool,
    offset: bool,
}

impl Columns {
    fn of(measurements: &[Measurement], kinds: &[JointKind]) -> Self {
        let any = |f: fn(&Measurement) -> bool| measurements.iter().any(f);
        Self {
            joints: joint_columns(kinds.len()),
            dirs: dir_columns(kinds),
            probe: any(|m| matches!(m.target, Target::Probe { .. })),
            plane: any(|m| m.target.is_plane()),
            normal: any(|m| matches!(m.target, Target::Plane { normal: true, .. })),
            position: any(|m| matches!(m.target, Target::Tracker { .. })),
            rotation: any(|m| m.target.is_orientation()),
            time: any(|m| m.context.time_s.is_some()),
            temp: any(|m| m.context.temperature_c.is_some()),
            dir: any(|m| m.context.dir.is_some()),
            offset: any(|m| m.probe_offset_mm.is_some()),
        }
    }

    fn header(&self) -> Vec<&str> {
        let mut header: Vec<&str> = Vec::new();
        if self.probe {
            header.push("position");
        }
        if self.plane {
            header.push("plane");
        }
        if self.normal {
            header.push("normal");
        }
        header.push("tcp");
        header.extend(self.joints.iter().map(String::as_str));
        if self.position {
            header.extend(["x", "y", "z"]);
        }
        if self.rotation {
            header.extend(["qw", "qx", "qy", "qz"]);
        }
        if self.time {
            header.push("time_s");
        }
        if self.temp {
            header.push("temperature_c");
        }
        if self.dir {
            header.extend(self.dirs.iter().map(|(_, c)| c.as_str()));
        }
        if self.offset {
            header.extend(OFFSET_COLUMNS);
        }
        header
    }

    /// One row: `m`'s fields, with `rotation` in the quaternion columns.
    fn record(
        &self,
        m: &Measurement,
        rotation: Option<UnitQuaternion<f64>>,
        kinds: &[JointKind],
    ) -> Vec<String> {
        let blanks = |n: usize| std::iter::repeat_n(String::new(), n);
        let mut rec: Vec<String> = Vec::new();
        if self.probe {
            rec.push(m.position().map(|p| p.to_string()).unwrap_or_default());
        }
        if self.plane {
            rec.push(m.plane_id().map(|p| p.to_string()).unwrap_or_default());
        }
        if self.normal {
            let normal = matches!(m.target, Target::Plane { normal: true, .. });
            rec.push(if m.target.is_plane() { u8::from(normal).to_string() } else { String::new() });
        }
        rec.push(m.tcp.to_string());
        rec.extend(joint_fields(&m.q, kinds));
        if self.position {
            match m.target {
                Target::Tracker { xyz_mm } => rec.extend(xyz_mm.iter().map(|v| v.to_string())),
                Target::Probe { .. } | Target::Orientation { .. } | Target::Plane { .. } => {
                    rec.extend(blanks(3))
                }
            }
        }
        if self.rotation {
            match rotation {
                Some(r) => {
                    let q = r.quaternion();
                    rec.extend([q.w, q.i, q.j, q.k].iter().map(|v| v.to_string()));
                }
                None => rec.extend(blanks(4)),
            }
        }
        if self.time {
            rec.push(m.context.time_s.map(|v| v.to_string()).unwrap_or_default());
        }
        if self.temp {
            rec.push(m.context.temperature_c.map(|v| v.to_string()).unwrap_or_default());
        }
        if self.dir {
            match m.context.dir {
                Some(d) => rec.extend(self.dirs.iter().map(|(joint, _)| d[joint - 1].to_string())),
                None => rec.extend(blanks(self.dirs.len())),
            }
        }
        if self.offset {
            match m.probe_offset_mm {
                Some(o) => rec.extend(o.iter().map(|v| v.to_string())),
                None => rec.extend(blanks(3)),
            }
        }
        rec
    }
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
/// revolute joints), `x,y,z` (tracker), `qw,qx,qy,qz` (orientation; a tracker measurement
/// and the orientation measurement after it of one posture share a pose row, see
/// [`measurements_to_csv_for`]), `time_s`, `temperature_c`, `dir{i}` of the revolute joints,
/// the centring offsets.
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
