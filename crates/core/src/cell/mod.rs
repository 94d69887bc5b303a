//! The cell model file.
//!
//! * Version 1 (`format = "meca500-zaber-cell"`, `version = 1`): the canonical Meca500 on its
//!   linear guide — exactly 7 `[[joints]]` rows, row 1 prismatic (the guide), rows 2..7
//!   revolute.
//! * Version 2 (`format = "serial-robot-cell"`, `version = 2`): any serial chain of
//!   1..=[`MAX_JOINTS`] rows, each `kind = "revolute" | "prismatic"` in any order, with optional
//!   limits on revolute rows (absent = continuous joint), an optional `[robot]` table, and the
//!   same other tables as version 1. Frame N (the last row) is the flange in which the TCPs are
//!   given.
//!
//! [`CellFile`] mirrors the TOML exactly, in **file units** (mm, degrees, kg, rad/(N·m), m/s²).
//! [`CellFile::from_toml_str`] parses *and validates*; every validation error names the file,
//! the line (when it can be found) and the field. Unknown tables are kept in
//! [`CellFile::extra`] and written back unchanged, so optional tables added by other tools
//! survive a round trip. Saving writes version 1 for a cell loaded as version 1 whose chain is
//! still the Meca500-on-guide shape, version 2 otherwise.
//!
//! Conversion to the internal model (radians, cached transforms) is done by
//! `vatcal_kinematics::Model::from_cell`.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::units::{JointKind, MAX_JOINTS};

/// The value of the `format` key of version 1 (the Meca500-on-guide cell).
pub const FORMAT_NAME: &str = "meca500-zaber-cell";
/// The version of [`FORMAT_NAME`].
pub const FORMAT_VERSION: i64 = 1;
/// The value of the `format` key of version 2 (any serial chain).
pub const FORMAT_NAME_V2: &str = "serial-robot-cell";
/// The version of [`FORMAT_NAME_V2`].
pub const FORMAT_VERSION_V2: i64 = 2;

/// Errors while reading or validating a cell file.
#[derive(Debug, thiserror::Error)]
pub enum CellError {
    /// The file could not be read.
    #[error("cannot read cell file {path}: {cause}")]
    Io {
        /// file path
        path: PathBuf,
        /// cause (kept out of the error chain: the message already states it)
        cause: std::io::Error,
    },
    /// TOML syntax error or a field of the wrong type / missing (the message carries the line).
    #[error("{origin}: {message}")]
    Parse {
        /// file path or `<string>`
        origin: String,
        /// toml's message, with line and column
        message: String,
    },
    /// A field has an invalid value.
    #[error("{origin}{}: field `{field}`: {reason}", .line.map(|l| format!(":{l}")).unwrap_or_default())]
    Invalid {
        /// file path or `<string>`
        origin: String,
        /// 1-based line of the field in the file, when it could be located
        line: Option<usize>,
        /// field path, e.g. `joints[index=3].q_min`
        field: String,
        /// what is wrong
        reason: String,
    },
    /// The file could not be serialised.
    #[error("cannot write cell file: {0}")]
    Write(String),
}

/// `[units]`: must be exactly the canonical units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Units {
    /// `"mm"`
    pub length: String,
    /// `"deg"`
    pub angle: String,
    /// `"kg"`
    pub mass: String,
    /// `"rad/(N*m)"`
    pub compliance: String,
    /// `"m/s^2"`
    pub gravity: String,
}

impl Default for Units {
    fn default() -> Self {
        Self {
            length: "mm".into(),
            angle: "deg".into(),
            mass: "kg".into(),
            compliance: "rad/(N*m)".into(),
            gravity: "m/s^2".into(),
        }
    }
}

/// `[robot]` (version 2, optional): informational.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RobotInfo {
    /// robot name, e.g. `"UR5e"`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// other keys, kept verbatim
    #[serde(flatten)]
    pub extra: toml::Table,
}

/// One `[[joints]]` row: MDH row `index` (transform from frame index-1 to frame index).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointRow {
    /// row / joint index 1..=N
    pub index: u8,
    /// joint name (e.g. `guide`, `J1`; required in version 1, optional in version 2)
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// `"prismatic"` or `"revolute"` (version 1: row 1 prismatic, rows 2..7 revolute)
    pub kind: String,
    /// alpha_{i-1} \[deg\]
    pub alpha_deg: f64,
    /// a_{i-1} \[mm\]
    pub a_mm: f64,
    /// Hayati beta_{i-1} \[deg\] (optional, default 0)
    #[serde(default)]
    pub beta_deg: f64,
    /// theta offset of joint i \[deg\]
    pub theta_deg: f64,
    /// d offset of joint i \[mm\]
    pub d_mm: f64,
    /// lower joint limit (mm for prismatic, deg for revolute joints); required except on
    /// revolute rows of version 2, where absent limits mean a continuous joint
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q_min: Option<f64>,
    /// upper joint limit (see `q_min`)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q_max: Option<f64>,
    /// joint compliance c_i \[rad/(N·m)\] (optional, default 0; must be 0 on prismatic rows of
    /// version 2, unused on the guide of version 1)
    #[serde(default)]
    pub compliance_rad_per_n_m: f64,
}

impl JointRow {
    /// The joint kind, `None` for an unknown `kind` string (rejected by validation).
    pub fn joint_kind(&self) -> Option<JointKind> {
        JointKind::from_name(&self.kind)
    }

    /// `(q_min, q_max)` in file units when both are given (`None` = continuous joint).
    pub fn limits(&self) -> Option<(f64, f64)> {
        self.q_min.zip(self.q_max)
    }
}

/// `[base_in_world]`: `H_0^W = T(x,y,z) Rx(alpha) Ry(beta) Rz(gamma)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BaseInWorld {
    /// x \[mm\]
    pub x_mm: f64,
    /// y \[mm\]
    pub y_mm: f64,
    /// z \[mm\]
    pub z_mm: f64,
    /// alpha \[deg\]
    pub alpha_deg: f64,
    /// beta \[deg\]
    pub beta_deg: f64,
    /// gamma \[deg\]
    pub gamma_deg: f64,
}

/// A `[[tcps]]` or `[[calibration_positions]]` entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointEntry {
    /// id
    pub id: u32,
    /// x \[mm\]
    pub x_mm: f64,
    /// y \[mm\]
    pub y_mm: f64,
    /// z \[mm\]
    pub z_mm: f64,
}

/// `[gravity]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gravity {
    /// gravity vector in the world frame \[m/s²\]
    pub vector_m_per_s2: [f64; 3],
}

/// `[[inertials.links]]`: mass and COM of link `frame` in its own MDH frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinkInertial {
    /// MDH frame: 2..=7 in version 1 (the Meca500 links), 1..=N in version 2
    pub frame: u8,
    /// informational URDF link name
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub urdf_link: Option<String>,
    /// mass \[kg\]
    pub mass_kg: f64,
    /// centre of mass in frame `frame` \[mm\]
    pub com_mm: [f64; 3],
}

/// `[inertials.tool]`: the tool (tool changer + end-effector), rigidly attached to the last
/// frame N (7 on the canonical cell).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ToolInertial {
    /// must be N, the last frame
    pub frame: u8,
    /// mass \[kg\]
    pub mass_kg: f64,
    /// COM in frame N \[mm\]
    pub com_mm: [f64; 3],
}

/// `[inertials]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Inertials {
    /// moving links (a link without an entry has no mass)
    pub links: Vec<LinkInertial>,
    /// tool
    pub tool: ToolInertial,
}

/// A vertical cylinder on the world z axis (or, for `trical`, below the active position).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CylinderObstacle {
    /// radius \[mm\]
    pub radius_mm: f64,
    /// bottom \[mm\]
    pub z_min_mm: f64,
    /// top \[mm\]
    pub z_max_mm: f64,
}

/// An axis-aligned box in frame-0 coordinates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoxObstacle {
    /// x min \[mm\]
    pub x_min_mm: f64,
    /// x max \[mm\]
    pub x_max_mm: f64,
    /// y min \[mm\]
    pub y_min_mm: f64,
    /// y max \[mm\]
    pub y_max_mm: f64,
    /// z min \[mm\]
    pub z_min_mm: f64,
    /// z max \[mm\]
    pub z_max_mm: f64,
}

/// A horizontal plane (world z).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaneObstacle {
    /// height \[mm\]
    pub z_mm: f64,
}

/// `[obstacles]`: the simple collision model used to screen candidate poses.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Obstacles {
    /// resin tank + kinematic plate
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tank: Option<CylinderObstacle>,
    /// TriCal body below the active calibration position
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trical: Option<CylinderObstacle>,
    /// guide body + carriage (frame 0)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guide: Option<BoxObstacle>,
    /// base plate
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor: Option<PlaneObstacle>,
    /// other obstacle tables, kept verbatim
    #[serde(flatten)]
    pub extra: toml::Table,
}

/// `[[effects]]`: an effect of the catalog switched on in this model, with its values.
///
/// `values` maps parameter names to values in file units: keys of angular parameters end in
/// `_deg`, of length parameters in `_mm`; other parameters use their bare name
/// (e.g. `cyclic4_h1_sin_deg = 0.012`, `tool_tx_mm = 0.03`, `guide_scale = 2e-5`).
/// Built-in effects (`joint-compliance`, `tcp-offset`, `position-offset`, `hayati-beta`) keep
/// their values in the ordinary fields and only mark that the effect belongs to the model.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EffectEntry {
    /// catalog name, e.g. `joint-cyclic`
    pub effect: String,
    /// cell joint (1..=7) for per-joint effects
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<u8>,
    /// harmonic for `joint-cyclic`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub harmonic: Option<u8>,
    /// highest polynomial order for `guide-angular` / `guide-straightness`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub order: Option<u8>,
    /// `time` or `temperature` for `thermal-drift`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub driver: Option<String>,
    /// reference temperature \[°C\] for a temperature-driven `thermal-drift` (default 20)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_temperature_c: Option<f64>,
    /// TCP id for `tcp-offset`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tcp: Option<u32>,
    /// calibration position id for `position-offset`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<u32>,
    /// MDH row for `hayati-beta`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub row: Option<u8>,
    /// which motion of the link frame for `link-out-of-plane`: `axial`, `tilt-x` or `tilt-y`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub component: Option<String>,
    /// the joint whose angle drives the error, for `joint-coupling`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub driving_joint: Option<u8>,
    /// parameter values in file units
    #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
    pub values: toml::Table,
}

/// `[motion]` (optional): speed limits used to estimate motion time when planning a tour.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotionLimits {
    /// maximum speed of the Meca500 joints J1..J6 \[deg/s\]
    pub joint_speed_deg_per_s: [f64; 6],
    /// maximum speed of the linear guide \[mm/s\]
    pub guide_speed_mm_per_s: f64,
    /// fraction of the maximum speed used for planned moves (0..1]
    #[serde(default = "default_speed_fraction")]
    pub speed_fraction: f64,
    /// time to settle + auto-centre at each measurement \[s\]
    #[serde(default = "default_measure_s")]
    pub measurement_s: f64,
    /// time for the operator to re-place the probe plate \[s\]
    #[serde(default = "default_replacement_s")]
    pub probe_replacement_s: f64,
}

fn default_speed_fraction() -> f64 {
    0.25
}
fn default_measure_s() -> f64 {
    20.0
}
fn default_replacement_s() -> f64 {
    60.0
}

impl Default for MotionLimits {
    /// Meca500 R3 maximum joint speeds (150, 150, 180, 300, 300, 500 deg/s) and a conservative
    /// 50 mm/s for the guide.
    fn default() -> Self {
        Self {
            joint_speed_deg_per_s: [150.0, 150.0, 180.0, 300.0, 300.0, 500.0],
            guide_speed_mm_per_s: 50.0,
            speed_fraction: default_speed_fraction(),
            measurement_s: default_measure_s(),
            probe_replacement_s: default_replacement_s(),
        }
    }
}

/// The whole cell file, in file units. See the module docs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellFile {
    /// `"meca500-zaber-cell"` (version 1) or `"serial-robot-cell"` (version 2)
    pub format: String,
    /// 1 or 2
    pub version: i64,
    /// unit declaration
    pub units: Units,
    /// version 2: informational robot description (optional)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotInfo>,
    /// the MDH rows 1..=N (7 in version 1)
    pub joints: Vec<JointRow>,
    /// base pose in the world
    pub base_in_world: BaseInWorld,
    /// calibration TCPs in the last frame N
    pub tcps: Vec<PointEntry>,
    /// calibration positions in the world
    pub calibration_positions: Vec<PointEntry>,
    /// gravity
    pub gravity: Gravity,
    /// link and tool inertials
    pub inertials: Inertials,
    /// collision screening model (optional)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub obstacles: Option<Obstacles>,
    /// motion limits for tour timing (optional; defaults in [`MotionLimits::default`])
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<MotionLimits>,
    /// catalog effects switched on in this model (optional)
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<EffectEntry>,
    /// the joint range the calibration was fitted on (optional; written by `vatcal identify`,
    /// read by `vatcal validate` and `vatcal compensate` to warn about extrapolation), file
    /// units
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training_range: Option<crate::training_range::TrainingRange>,
    /// any other table, kept verbatim (e.g. provenance written by `vatcal identify`)
    #[serde(flatten)]
    pub extra: toml::Table,
}

impl CellFile {
    /// Reads, parses and validates a cell file.
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::CellFile;
    ///
    /// let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?;
    /// assert_eq!(cell.joints.len(), 7);
    /// assert_eq!(cell.tcp_ids(), vec![1, 2, 3]);
    /// // a missing file is an error naming it
    /// let e = CellFile::load("no-such-cell.toml").expect_err("missing file");
    /// assert!(e.to_string().contains("no-such-cell.toml"));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`CellError::Io`] when the file cannot be read; otherwise as [`CellFile::from_toml_str`].
    pub fn load(path: impl AsRef<Path>) -> Result<Self, CellError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|source| CellError::Io { path: path.to_path_buf(), cause: source })?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// Parses and validates TOML text. `origin` names the source in error messages.
    ///
    /// # Examples
    /// A bad value is refused with the origin and the field:
    /// ```
    /// use vatcal_core::CellFile;
    ///
    /// let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?;
    /// assert!(CellFile::from_toml_str(&text, "cell.toml").is_ok());
    /// let bad = text.replacen("version = 1", "version = 99", 1);
    /// let e = CellFile::from_toml_str(&bad, "bad.toml").expect_err("unsupported version");
    /// let message = e.to_string(); // e.g. "bad.toml:30: field `version`: unsupported version 99 ..."
    /// assert!(message.starts_with("bad.toml:") && message.contains("field `version`"), "{message}");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`CellError::Parse`] for TOML syntax errors, missing fields or fields of the wrong type (the
    /// message carries line and column); [`CellError::Invalid`] for a value
    /// [`CellFile::validate`] refuses, naming the field.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, CellError> {
        let cell: CellFile = toml::from_str(text)
            .map_err(|e| CellError::Parse { origin: origin.to_string(), message: e.to_string() })?;
        cell.validate(origin).map_err(|e| match e {
            CellError::Invalid { origin, line: None, field, reason } => {
                CellError::Invalid { origin, line: locate_field(text, &field), field, reason }
            }
            other => other,
        })?;
        Ok(cell)
    }

    /// True when the chain has the shape of a version-1 file: 7 rows, row 1 prismatic with
    /// limits, rows 2..7 revolute with limits, links in frames 2..=7 and the tool on frame 7.
    pub fn is_meca500_on_guide_shape(&self) -> bool {
        self.joints.len() == 7
            && self.joints.iter().all(|j| {
                let want = if j.index == 1 { JointKind::Prismatic } else { JointKind::Revolute };
                (1..=7).contains(&j.index) && j.joint_kind() == Some(want) && j.limits().is_some()
            })
            && self.inertials.links.iter().all(|l| (2..=7).contains(&l.frame))
            && self.inertials.tool.frame == 7
    }

    /// The file as it will be written: version 1 stays version 1 while its chain has the
    /// Meca500-on-guide shape, anything else becomes version 2.
    fn for_writing(&self) -> std::borrow::Cow<'_, Self> {
        if self.version == FORMAT_VERSION && self.format == FORMAT_NAME && !self.is_meca500_on_guide_shape() {
            let mut c = self.clone();
            c.format = FORMAT_NAME_V2.to_string();
            c.version = FORMAT_VERSION_V2;
            std::borrow::Cow::Owned(c)
        } else {
            std::borrow::Cow::Borrowed(self)
        }
    }

    /// Serialises to TOML (file units). The output loads back to an equal `CellFile` (a
    /// version-1 file whose chain is no longer the Meca500-on-guide shape is written as
    /// version 2).
    pub fn to_toml_string(&self) -> Result<String, CellError> {
        let cell = self.for_writing();
        let body = toml::to_string_pretty(cell.as_ref()).map_err(|e| CellError::Write(e.to_string()))?;
        Ok(format!(
            "# vatcal cell model (format {} v{}).\n\
             # UNITS: mm, deg, kg, rad/(N*m), m/s^2. See docs/formats.md and docs/conventions.md.\n\n{body}",
            cell.format, cell.version
        ))
    }

    /// Writes the file (validating first).
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::CellFile;
    ///
    /// let mut cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))?;
    /// cell.joints[2].a_mm += 0.05; // e.g. a calibrated length
    /// let path = std::env::temp_dir().join(format!("vatcal-doc-save-{}.toml", std::process::id()));
    /// cell.save(&path)?;
    /// let back = CellFile::load(&path)?;
    /// std::fs::remove_file(&path)?;
    /// assert_eq!(back.joints[2].a_mm, cell.joints[2].a_mm);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`CellError::Invalid`] when [`CellFile::validate`] refuses a value (nothing is written),
    /// [`CellError::Write`] when the TOML cannot be produced, [`CellError::Io`] when the file
    /// cannot be written.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), CellError> {
        let path = path.as_ref();
        self.for_writing().validate(&path.display().to_string())?;
        let text = self.to_toml_string()?;
        std::fs::write(path, text).map_err(|source| CellError::Io { path: path.to_path_buf(), cause: source })
    }

    /// The row of joint `index` (1..=N). Valid files have all N.
    pub fn joint(&self, index: u8) -> Option<&JointRow> {
        self.joints.iter().find(|j| j.index == index)
    }

    /// Number of joints N.
    pub fn joint_count(&self) -> usize {
        self.joints.len()
    }

    /// Kinds of joints 1..=N in index order (valid files only; an unknown kind reads as
    /// revolute).
    pub fn joint_kinds(&self) -> Vec<JointKind> {
        let mut rows: Vec<&JointRow> = self.joints.iter().collect();
        rows.sort_by_key(|j| j.index);
        rows.iter().map(|j| j.joint_kind().unwrap_or(JointKind::Revolute)).collect()
    }

    /// True for a version-2 (`serial-robot-cell`) file.
    pub fn is_v2(&self) -> bool {
        self.version == FORMAT_VERSION_V2
    }

    /// TCP ids in file order.
    pub fn tcp_ids(&self) -> Vec<u32> {
        self.tcps.iter().map(|t| t.id).collect()
    }

    /// Calibration position ids in file order.
    pub fn position_ids(&self) -> Vec<u32> {
        self.calibration_positions.iter().map(|p| p.id).collect()
    }

    /// Motion limits (the file's `[motion]` or the defaults).
    pub fn motion_limits(&self) -> MotionLimits {
        self.motion.clone().unwrap_or_default()
    }

    /// Checks every field. Errors name the field.
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::CellFile;
    ///
    /// let mut cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-table.toml"))?;
    /// cell.joints[0].q_max = Some(-500.0); // below q_min
    /// let e = cell.validate("edited.toml").expect_err("empty joint range");
    /// assert!(e.to_string().starts_with("edited.toml"), "{e}");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`CellError::Invalid`] naming `origin` and the first field that is wrong (a wrong format
    /// or version, joint rows that are not 1..N, limits, TCP and position ids, inertials,
    /// effects that do not fit the chain, ...).
    pub fn validate(&self, origin: &str) -> Result<(), CellError> {
        let bad = |field: String, reason: String| CellError::Invalid {
            origin: origin.to_string(),
            line: None,
            field,
            reason,
        };
        let finite = |field: String, v: f64| -> Result<(), CellError> {
            if v.is_finite() { Ok(()) } else { Err(bad(field, format!("must be a finite number, got {v}"))) }
        };
        let v2 = match self.format.as_str() {
            FORMAT_NAME => false,
            FORMAT_NAME_V2 => true,
            other => {
                return Err(bad(
                    "format".into(),
                    format!(
                        "expected \"{FORMAT_NAME}\" (version 1) or \"{FORMAT_NAME_V2}\" (version 2), got \"{other}\""
                    ),
                ));
            }
        };
        let want_version = if v2 { FORMAT_VERSION_V2 } else { FORMAT_VERSION };
        if self.version != want_version {
            return Err(bad(
                "version".into(),
                format!(
                    "unsupported version {} for format \"{}\" (this vatcal reads \"{FORMAT_NAME}\" version {FORMAT_VERSION} and \"{FORMAT_NAME_V2}\" version {FORMAT_VERSION_V2})",
                    self.version, self.format
                ),
            ));
        }
        if !v2 && self.robot.is_some() {
            return Err(bad("robot".into(), "the [robot] table needs format version 2".into()));
        }
        let u = Units::default();
        for (name, got, want) in [
            ("units.length", &self.units.length, &u.length),
            ("units.angle", &self.units.angle, &u.angle),
            ("units.mass", &self.units.mass, &u.mass),
            ("units.compliance", &self.units.compliance, &u.compliance),
            ("units.gravity", &self.units.gravity, &u.gravity),
        ] {
            if got != want {
                return Err(bad(name.into(), format!("expected \"{want}\", got \"{got}\"")));
            }
        }
        // joints: indices 1..=N, each once (N = 7 in version 1, 1..=MAX_JOINTS in version 2)
        let n = self.joints.len();
        if v2 && !(1..=MAX_JOINTS).contains(&n) {
            return Err(bad(
                "joints".into(),
                format!("a serial chain has 1..={MAX_JOINTS} [[joints]] rows, got {n}"),
            ));
        }
        let n_expected = if v2 { n } else { 7 };
        let mut seen = BTreeSet::new();
        for (k, j) in self.joints.iter().enumerate() {
            if !(1..=n_expected).contains(&(j.index as usize)) {
                let why = if v2 {
                    format!("must be 1..={n} (rows are numbered contiguously from 1), got {}", j.index)
                } else {
                    format!("must be 1..=7, got {}", j.index)
                };
                return Err(bad(format!("joints[{k}].index"), why));
            }
            if !seen.insert(j.index) {
                return Err(bad(format!("joints[{k}].index"), format!("duplicate joint row {}", j.index)));
            }
        }
        for i in 1..=n_expected as u8 {
            if !seen.contains(&i) {
                return Err(bad("joints".into(), format!("missing [[joints]] row with index = {i}")));
            }
        }
        for j in &self.joints {
            let f = |name: &str| format!("joints[index={}].{name}", j.index);
            let Some(kind) = j.joint_kind() else {
                return Err(bad(
                    f("kind"),
                    format!("unknown joint kind \"{}\" (expected \"prismatic\" or \"revolute\")", j.kind),
                ));
            };
            if !v2 {
                let expected = if j.index == 1 { JointKind::Prismatic } else { JointKind::Revolute };
                if kind != expected {
                    return Err(bad(
                        f("kind"),
                        format!(
                            "joint {} must be {expected} in this cell (joint 1 is the linear guide, 2..7 the Meca500), got \"{}\"; use format \"{FORMAT_NAME_V2}\" version 2 for other chains",
                            j.index, j.kind
                        ),
                    ));
                }
                if j.name.is_empty() {
                    return Err(bad(f("name"), "missing joint name (required in version 1)".into()));
                }
            }
            for (name, v) in [
                ("alpha_deg", j.alpha_deg),
                ("a_mm", j.a_mm),
                ("beta_deg", j.beta_deg),
                ("theta_deg", j.theta_deg),
                ("d_mm", j.d_mm),
                ("q_min", j.q_min.unwrap_or(0.0)),
                ("q_max", j.q_max.unwrap_or(0.0)),
                ("compliance_rad_per_n_m", j.compliance_rad_per_n_m),
            ] {
                finite(f(name), v)?;
            }
            let limits_optional = v2 && kind == JointKind::Revolute;
            match (j.q_min, j.q_max) {
                (Some(lo), Some(hi)) if lo > hi => {
                    return Err(bad(f("q_min"), format!("q_min ({lo}) > q_max ({hi}): limits inverted")));
                }
                (Some(_), Some(_)) => {}
                (None, None) if limits_optional => {}
                (lo, _) => {
                    let missing = if lo.is_none() { "q_min" } else { "q_max" };
                    let why = if limits_optional {
                        "give both q_min and q_max, or neither for a continuous joint".to_string()
                    } else if v2 {
                        "a prismatic joint needs q_min and q_max (mm)".to_string()
                    } else {
                        "required in version 1".to_string()
                    };
                    return Err(bad(f(missing), format!("missing joint limit: {why}")));
                }
            }
            if v2 && kind == JointKind::Prismatic && j.compliance_rad_per_n_m != 0.0 {
                return Err(bad(
                    f("compliance_rad_per_n_m"),
                    format!(
                        "joint compliance applies to revolute joints only; prismatic joint {} has {}",
                        j.index, j.compliance_rad_per_n_m
                    ),
                ));
            }
        }
        let b = &self.base_in_world;
        for (name, v) in [
            ("x_mm", b.x_mm),
            ("y_mm", b.y_mm),
            ("z_mm", b.z_mm),
            ("alpha_deg", b.alpha_deg),
            ("beta_deg", b.beta_deg),
            ("gamma_deg", b.gamma_deg),
        ] {
            finite(format!("base_in_world.{name}"), v)?;
        }
        if (b.beta_deg.abs() - 90.0).abs() < 1.0 {
            return Err(bad(
                "base_in_world.beta_deg".into(),
                format!(
                    "{} is within 1 deg of the XYZ-angle singularity at +-90 deg; re-express the base pose",
                    b.beta_deg
                ),
            ));
        }
        for (table, list) in [("tcps", &self.tcps), ("calibration_positions", &self.calibration_positions)] {
            if list.is_empty() {
                return Err(bad(table.into(), "at least one entry is required".into()));
            }
            let mut ids = BTreeSet::new();
            for (k, p) in list.iter().enumerate() {
                if !ids.insert(p.id) {
                    return Err(bad(format!("{table}[{k}].id"), format!("duplicate id {}", p.id)));
                }
                for (name, v) in [("x_mm", p.x_mm), ("y_mm", p.y_mm), ("z_mm", p.z_mm)] {
                    finite(format!("{table}[id={}].{name}", p.id), v)?;
                }
            }
        }
        for (k, v) in self.gravity.vector_m_per_s2.iter().enumerate() {
            finite(format!("gravity.vector_m_per_s2[{k}]"), *v)?;
        }
        let mut frames = BTreeSet::new();
        for (k, l) in self.inertials.links.iter().enumerate() {
            if v2 && !(1..=n).contains(&(l.frame as usize)) {
                return Err(bad(
                    format!("inertials.links[{k}].frame"),
                    format!("must be a moving frame 1..={n} of this chain, got {}", l.frame),
                ));
            }
            if !v2 && !(2..=7).contains(&l.frame) {
                return Err(bad(
                    format!("inertials.links[{k}].frame"),
                    format!("must be 2..=7 (moving Meca500 links), got {}", l.frame),
                ));
            }
            if !frames.insert(l.frame) {
                return Err(bad(
                    format!("inertials.links[{k}].frame"),
                    format!("duplicate frame {}", l.frame),
                ));
            }
            finite(format!("inertials.links[frame={}].mass_kg", l.frame), l.mass_kg)?;
            if l.mass_kg < 0.0 {
                return Err(bad(
                    format!("inertials.links[frame={}].mass_kg", l.frame),
                    format!("negative mass {}", l.mass_kg),
                ));
            }
            for (c, v) in l.com_mm.iter().enumerate() {
                finite(format!("inertials.links[frame={}].com_mm[{c}]", l.frame), *v)?;
            }
        }
        let t = &self.inertials.tool;
        if t.frame as usize != n_expected {
            return Err(bad(
                "inertials.tool.frame".into(),
                format!("the tool is attached to the last frame {n_expected}, got {}", t.frame),
            ));
        }
        finite("inertials.tool.mass_kg".into(), t.mass_kg)?;
        if t.mass_kg < 0.0 {
            return Err(bad("inertials.tool.mass_kg".into(), format!("negative mass {}", t.mass_kg)));
        }
        for (c, v) in t.com_mm.iter().enumerate() {
            finite(format!("inertials.tool.com_mm[{c}]"), *v)?;
        }
        if let Some(m) = &self.motion {
            for (k, v) in m.joint_speed_deg_per_s.iter().enumerate() {
                if !(v.is_finite() && *v > 0.0) {
                    return Err(bad(
                        format!("motion.joint_speed_deg_per_s[{k}]"),
                        format!("must be > 0, got {v}"),
                    ));
                }
            }
            for (name, v) in [
                ("guide_speed_mm_per_s", m.guide_speed_mm_per_s),
                ("measurement_s", m.measurement_s + 1.0),
                ("probe_replacement_s", m.probe_replacement_s + 1.0),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(bad(format!("motion.{name}"), "must be a positive finite number".into()));
                }
            }
            if !(m.speed_fraction > 0.0 && m.speed_fraction <= 1.0) {
                return Err(bad(
                    "motion.speed_fraction".into(),
                    format!("must be in (0, 1], got {}", m.speed_fraction),
                ));
            }
        }
        for (k, e) in self.effects.iter().enumerate() {
            if crate::EffectKind::from_name(&e.effect).is_none() {
                let names: Vec<&str> = crate::EffectKind::ALL.iter().map(|k| k.name()).collect();
                return Err(bad(
                    format!("effects[{k}].effect"),
                    format!("unknown effect \"{}\" (known: {})", e.effect, names.join(", ")),
                ));
            }
            for (key, v) in &e.values {
                match v.as_float().or_else(|| v.as_integer().map(|i| i as f64)) {
                    Some(x) if x.is_finite() => {}
                    _ => {
                        return Err(bad(
                            format!("effects[{k}].values.{key}"),
                            "must be a finite number".into(),
                        ));
                    }
                }
            }
        }
        if let Some(range) = &self.training_range {
            range.check(n).map_err(|(field, reason)| bad(field, reason))?;
        }
        Ok(())
    }
}

/// The 1-based line of a validation field path (`joints[index=3].q_min`, `tcps[1].id`,
/// `inertials.tool.frame`, `format`) in TOML text, found by scanning table headers and keys.
fn locate_field(text: &str, field: &str) -> Option<usize> {
    // split "a.b[sel].key[3]" into table segments and the final key
    let mut segs: Vec<&str> = field.split('.').collect();
    let strip = |s: &str| -> (String, Option<String>) {
        match s.split_once('[') {
            Some((name, rest)) => (name.to_string(), Some(rest.trim_end_matches(']').to_string())),
            None => (s.to_string(), None),
        }
    };
    let key = if segs.len() > 1 { segs.pop().map(|k| strip(k).0) } else { None };
    let (last_table, selector) = strip(segs.pop()?);
    let mut table_path: Vec<String> = segs.iter().map(|s| s.to_string()).collect();
    table_path.push(last_table);
    let table = table_path.join(".");
    let lines: Vec<&str> = text.lines().collect();
    let key_of = |line: &str| -> Option<(String, String)> {
        let l = line.trim();
        if l.starts_with('#') || l.starts_with('[') {
            return None;
        }
        let (k, v) = l.split_once('=')?;
        let v = v.split('#').next().unwrap_or("").trim().trim_matches('"');
        Some((k.trim().to_string(), v.to_string()))
    };
    let header = |line: &str| -> Option<String> {
        let l = line.trim();
        let l = l.split('#').next().unwrap_or("").trim();
        l.strip_prefix('[').map(|h| h.trim_start_matches('[').trim_end_matches(']').trim().to_string())
    };
    // top-level key without a table ("format", "version")
    if key.is_none() && selector.is_none() {
        for (i, line) in lines.iter().enumerate() {
            if header(line).is_some() {
                break;
            }
            if key_of(line).is_some_and(|(k, _)| k == table) {
                return Some(i + 1);
            }
        }
    }
    // candidate table bodies: (header line, body lines)
    let mut bodies: Vec<(usize, usize, usize)> = Vec::new(); // (header idx, start, end)
    let mut current: Option<usize> = None;
    for (i, line) in lines.iter().enumerate() {
        if let Some(h) = header(line) {
            if let Some(c) = current.take() {
                bodies.push((c, c + 1, i));
            }
            if h == table {
                current = Some(i);
            }
        }
    }
    if let Some(c) = current {
        bodies.push((c, c + 1, lines.len()));
    }
    let chosen = match selector.as_deref() {
        None => bodies.first().copied(),
        Some(sel) => match sel.split_once('=') {
            Some((sk, sv)) => bodies.iter().copied().find(|(_, a, b)| {
                lines[*a..*b].iter().any(|l| key_of(l).is_some_and(|(k, v)| k == sk && v == sv))
            }),
            None => sel.parse::<usize>().ok().and_then(|k| bodies.get(k).copied()),
        },
    };
    let (h, a, b) = chosen?;
    if let Some(key) = key {
        for (i, line) in lines.iter().enumerate().take(b).skip(a) {
            if key_of(line).is_some_and(|(k, _)| k == key) {
                return Some(i + 1);
            }
        }
    }
    Some(h + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn canonical_text() -> String {
        let p = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml");
        std::fs::read_to_string(p).expect("fixture present")
    }

    fn expect_invalid(text: &str, field_part: &str) {
        match CellFile::from_toml_str(text, "test.toml") {
            Err(CellError::Invalid { field, .. }) => {
                assert!(field.contains(field_part), "field `{field}` should mention `{field_part}`")
            }
            Err(e) => panic!("expected Invalid({field_part}), got {e}"),
            Ok(_) => panic!("expected an error for {field_part}"),
        }
    }

    #[test]
    fn canonical_loads_and_round_trips() {
        let cell = CellFile::from_toml_str(&canonical_text(), "canonical").expect("valid");
        assert_eq!(cell.joints.len(), 7);
        assert_eq!(cell.tcp_ids(), vec![1, 2, 3]);
        assert!(cell.obstacles.as_ref().and_then(|o| o.guide.as_ref()).is_some());
        let text = cell.to_toml_string().expect("serialise");
        let back = CellFile::from_toml_str(&text, "round trip").expect("reload");
        assert_eq!(back, cell);
    }

    #[test]
    fn unknown_tables_survive() {
        let text =
            canonical_text() + "\n[provenance]\ntool = \"someone else\"\n[obstacles.extra_box]\nr = 1.0\n";
        let cell = CellFile::from_toml_str(&text, "x").expect("valid");
        assert!(cell.extra.contains_key("provenance"));
        let back = CellFile::from_toml_str(&cell.to_toml_string().expect("s"), "y").expect("reload");
        assert_eq!(back.extra, cell.extra);
        assert!(back.obstacles.expect("o").extra.contains_key("extra_box"));
    }

    /// The optional `[training_range]` (issue 29) round-trips; a file without it loads as
    /// before; a wrong length or inverted values are refused naming the field and its line.
    #[test]
    fn training_range_is_optional_and_checked() {
        let plain = CellFile::from_toml_str(&canonical_text(), "canonical").expect("valid");
        assert!(plain.training_range.is_none());
        assert!(!plain.to_toml_string().expect("s").contains("training_range"));
        let table = "\n[training_range]\nrows = 40\nq_min = [10.0, -20.0, -30.0, -40.0, -50.0, -60.0, -70.0]\nq_max = [200.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0]\n";
        let cell = CellFile::from_toml_str(&(canonical_text() + table), "x").expect("valid");
        let range = cell.training_range.clone().expect("range");
        assert_eq!((range.rows, range.q_min[0], range.q_max[6]), (40, 10.0, 70.0));
        assert!(cell.extra.get("training_range").is_none());
        let back = CellFile::from_toml_str(&cell.to_toml_string().expect("s"), "y").expect("reload");
        assert_eq!(back, cell);
        expect_invalid(&(canonical_text() + &table.replace("-70.0]", "]")), "training_range.q_min");
        let inverted = canonical_text() + &table.replace("q_max = [200.0", "q_max = [5.0");
        match CellFile::from_toml_str(&inverted, "t.toml") {
            Err(e @ CellError::Invalid { line: Some(_), .. }) => {
                assert!(e.to_string().contains("training_range.q_min"), "{e}")
            }
            other => panic!("expected an Invalid error with a line, got {other:?}"),
        }
    }

    #[test]
    fn bad_values_name_the_field() {
        let t = canonical_text();
        expect_invalid(&t.replace("q_min = -70.0", "q_min = 100.0"), "joints[index=3].q_min");
        expect_invalid(&t.replace("kind = \"revolute\"", "kind = \"spherical\""), "kind");
        expect_invalid(&t.replace("format = \"meca500-zaber-cell\"", "format = \"other\""), "format");
        expect_invalid(&t.replace("version = 1", "version = 2"), "version");
        expect_invalid(&t.replace("index = 4", "index = 3"), "index");
        expect_invalid(&t.replace("id = 2\nx_mm = 0.214", "id = 1\nx_mm = 0.214"), "tcps");
        expect_invalid(&t.replace("a_mm = 135.0", "a_mm = nan"), "a_mm");
        expect_invalid(&t.replace("mass_kg = 0.45", "mass_kg = -0.45"), "inertials.tool.mass_kg");
    }

    fn v2_text() -> String {
        canonical_text()
            .replace("format = \"meca500-zaber-cell\"", "format = \"serial-robot-cell\"")
            .replace("version = 1", "version = 2")
    }

    /// The error for `text` must be Invalid, name `field_part`, and carry the line of a text
    /// line that contains `line_part`.
    fn expect_invalid_at(text: &str, field_part: &str, line_part: &str) {
        match CellFile::from_toml_str(text, "test.toml") {
            Err(e @ CellError::Invalid { .. }) => {
                let CellError::Invalid { ref field, line, .. } = e else { unreachable!() };
                assert!(field.contains(field_part), "field `{field}` should mention `{field_part}`");
                let line = line.unwrap_or_else(|| panic!("no line for {e}"));
                let src = text.lines().nth(line - 1).expect("line in the file");
                assert!(src.contains(line_part), "{e}: line {line} is `{src}`, expected `{line_part}`");
                assert!(e.to_string().starts_with(&format!("test.toml:{line}: field `")), "{e}");
            }
            Err(e) => panic!("expected Invalid({field_part}), got {e}"),
            Ok(_) => panic!("expected an error for {field_part}"),
        }
    }

    /// A version-2 chain of `n` revolute rows (continuous joints), tool on frame n.
    fn chain_text(n: usize) -> String {
        let mut t = String::from(
            "format = \"serial-robot-cell\"\nversion = 2\n[units]\nlength = \"mm\"\nangle = \"deg\"\nmass = \"kg\"\ncompliance = \"rad/(N*m)\"\ngravity = \"m/s^2\"\n",
        );
        for i in 1..=n {
            t += &format!(
                "[[joints]]\nindex = {i}\nkind = \"revolute\"\nalpha_deg = 90.0\na_mm = 10.0\ntheta_deg = 0.0\nd_mm = 5.0\n"
            );
        }
        t += "[base_in_world]\nx_mm = 0.0\ny_mm = 0.0\nz_mm = 0.0\nalpha_deg = 0.0\nbeta_deg = 0.0\ngamma_deg = 0.0\n";
        t += "[[tcps]]\nid = 1\nx_mm = 0.0\ny_mm = 0.0\nz_mm = 10.0\n";
        t += "[[calibration_positions]]\nid = 1\nx_mm = 0.0\ny_mm = 0.0\nz_mm = 0.0\n";
        t += "[gravity]\nvector_m_per_s2 = [0.0, 0.0, -9.81]\n";
        t += &format!(
            "[inertials]\nlinks = []\n[inertials.tool]\nframe = {n}\nmass_kg = 0.1\ncom_mm = [0.0, 0.0, 0.0]\n"
        );
        t
    }

    #[test]
    fn v2_any_chain_loads_and_writes_v2() {
        for n in [1, 6, 12] {
            let cell = CellFile::from_toml_str(&chain_text(n), "chain").expect("valid");
            assert_eq!(cell.joint_count(), n);
            assert_eq!(cell.joint_kinds(), vec![JointKind::Revolute; n]);
            assert!(cell.joints.iter().all(|j| j.limits().is_none()));
            let text = cell.to_toml_string().expect("write");
            assert!(text.starts_with("# vatcal cell model (format serial-robot-cell v2)"), "{text}");
            assert_eq!(CellFile::from_toml_str(&text, "back").expect("reload"), cell);
        }
        // the canonical file as version 2 is valid too, and stays version 2
        let v2 = CellFile::from_toml_str(&v2_text(), "v2").expect("valid");
        assert!(v2.to_toml_string().expect("w").contains("version = 2"));
        // a version-1 file stays version 1 while it has the Meca500-on-guide shape ...
        let v1 = CellFile::from_toml_str(&canonical_text(), "v1").expect("valid");
        assert!(v1.is_meca500_on_guide_shape());
        assert!(v1.to_toml_string().expect("w").contains("format = \"meca500-zaber-cell\""));
        // ... and is written as version 2 once it does not
        let mut other = v1.clone();
        other.joints[0].kind = "revolute".into();
        let text = other.to_toml_string().expect("w");
        assert!(text.contains("format = \"serial-robot-cell\"") && text.contains("version = 2"), "{text}");
        assert_eq!(
            CellFile::from_toml_str(&text, "x").expect("valid v2").joint_kinds()[0],
            JointKind::Revolute
        );
    }

    #[test]
    fn v2_bad_chains_name_file_line_and_field() {
        // 0 and 13 rows
        let none = "joints = []\n".to_string()
            + &chain_text(1).replace(
                "[[joints]]\nindex = 1\nkind = \"revolute\"\nalpha_deg = 90.0\na_mm = 10.0\ntheta_deg = 0.0\nd_mm = 5.0\n",
                "",
            );
        expect_invalid(&none, "joints");
        expect_invalid(&chain_text(13), "joints");
        let t = v2_text();
        // non-contiguous index
        expect_invalid_at(&t.replace("index = 4", "index = 9"), "joints[3].index", "index = 9");
        // unknown kind
        expect_invalid_at(&t.replacen("kind = \"revolute\"", "kind = \"spherical\"", 1), "kind", "spherical");
        // compliance on the prismatic row
        expect_invalid_at(
            &t.replace("compliance_rad_per_n_m = 0.0    # unused", "compliance_rad_per_n_m = 1e-3    # bad"),
            "joints[index=1].compliance_rad_per_n_m",
            "compliance_rad_per_n_m = 1e-3",
        );
        // inverted limits
        expect_invalid_at(
            &t.replace("q_min = -70.0", "q_min = 100.0"),
            "joints[index=3].q_min",
            "q_min = 100.0",
        );
        // tool on another frame than N
        expect_invalid_at(
            &t.replace("[inertials.tool]\nframe = 7", "[inertials.tool]\nframe = 6"),
            "inertials.tool.frame",
            "frame = 6",
        );
        // link inertial frame outside 1..=N
        expect_invalid_at(&t.replace("frame = 2\n", "frame = 8\n"), "inertials.links[0].frame", "frame = 8");
        // a prismatic joint needs limits, a revolute one both or none
        expect_invalid_at(&t.replace("q_min = 0.0    # mm", ""), "joints[index=1].q_min", "[[joints]]");
        expect_invalid_at(&t.replace("q_max = 90.0    # deg\n", ""), "joints[index=3].q_max", "[[joints]]");
        let continuous = t.replace("q_min = -70.0    # deg\n", "").replace("q_max = 90.0    # deg\n", "");
        let cell = CellFile::from_toml_str(&continuous, "c").expect("continuous joint 3");
        assert_eq!(cell.joint(3).and_then(|j| j.limits()), None);
        // ... but version 1 needs every limit
        let v1 =
            canonical_text().replace("q_min = -70.0    # deg\n", "").replace("q_max = 90.0    # deg\n", "");
        expect_invalid(&v1, "joints[index=3].q_");
        // version / format mismatch and [robot] in version 1
        expect_invalid_at(&t.replace("version = 2", "version = 1"), "version", "version = 1");
        expect_invalid(&(canonical_text() + "\n[robot]\nname = \"x\"\n"), "robot");
    }

    #[test]
    fn missing_row_and_missing_field() {
        let t = canonical_text();
        // drop row 7 entirely
        let cut = t.find("[[joints]]\nindex = 7").expect("row 7");
        let end = t[cut..].find("# ----").map(|e| cut + e).expect("end");
        let without = format!("{}{}", &t[..cut], &t[end..]);
        expect_invalid(&without, "joints");
        // missing field gives a parse error mentioning the field name
        let e =
            CellFile::from_toml_str(&t.replacen("d_mm = 135.0\n", "", 1), "f.toml").expect_err("must fail");
        assert!(e.to_string().contains("d_mm"), "{e}");
    }
}
