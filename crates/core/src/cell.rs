//! The cell model file (`format = "meca500-zaber-cell"`, `version = 1`).
//!
//! [`CellFile`] mirrors the canonical TOML exactly, in **file units** (mm, degrees, kg,
//! rad/(N·m), m/s²). [`CellFile::from_toml_str`] parses *and validates*; every validation error
//! names the file and the field. Unknown tables are kept in [`CellFile::extra`] and written
//! back unchanged, so optional tables added by other tools survive a round trip.
//!
//! Conversion to the internal model (radians, cached transforms) is done by
//! `vatcal_kinematics::Model::from_cell`.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The value of the `format` key.
pub const FORMAT_NAME: &str = "meca500-zaber-cell";
/// The supported `version`.
pub const FORMAT_VERSION: i64 = 1;

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
    #[error("{origin}: field `{field}`: {reason}")]
    Invalid {
        /// file path or `<string>`
        origin: String,
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

/// One `[[joints]]` row: MDH row `index` (transform from frame index-1 to frame index).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointRow {
    /// row / cell joint index 1..=7
    pub index: u8,
    /// joint name (e.g. `guide`, `J1`)
    pub name: String,
    /// `"prismatic"` (row 1) or `"revolute"` (rows 2..7)
    pub kind: String,
    /// alpha_{i-1} [deg]
    pub alpha_deg: f64,
    /// a_{i-1} [mm]
    pub a_mm: f64,
    /// Hayati beta_{i-1} [deg] (optional, default 0)
    #[serde(default)]
    pub beta_deg: f64,
    /// theta offset of joint i [deg]
    pub theta_deg: f64,
    /// d offset of joint i [mm]
    pub d_mm: f64,
    /// lower joint limit (mm for the guide, deg otherwise)
    pub q_min: f64,
    /// upper joint limit
    pub q_max: f64,
    /// joint compliance c_i [rad/(N·m)] (optional, default 0; unused on the guide)
    #[serde(default)]
    pub compliance_rad_per_n_m: f64,
}

/// `[base_in_world]`: `H_0^W = T(x,y,z) Rx(alpha) Ry(beta) Rz(gamma)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BaseInWorld {
    /// x [mm]
    pub x_mm: f64,
    /// y [mm]
    pub y_mm: f64,
    /// z [mm]
    pub z_mm: f64,
    /// alpha [deg]
    pub alpha_deg: f64,
    /// beta [deg]
    pub beta_deg: f64,
    /// gamma [deg]
    pub gamma_deg: f64,
}

/// A `[[tcps]]` or `[[calibration_positions]]` entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointEntry {
    /// id
    pub id: u32,
    /// x [mm]
    pub x_mm: f64,
    /// y [mm]
    pub y_mm: f64,
    /// z [mm]
    pub z_mm: f64,
}

/// `[gravity]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gravity {
    /// gravity vector in the world frame [m/s²]
    pub vector_m_per_s2: [f64; 3],
}

/// `[[inertials.links]]`: mass and COM of link `frame` in its own MDH frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinkInertial {
    /// MDH frame 2..=7
    pub frame: u8,
    /// informational URDF link name
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub urdf_link: Option<String>,
    /// mass [kg]
    pub mass_kg: f64,
    /// centre of mass in frame `frame` [mm]
    pub com_mm: [f64; 3],
}

/// `[inertials.tool]`: the tool (tool changer + end-effector), rigidly attached to frame 7.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ToolInertial {
    /// must be 7
    pub frame: u8,
    /// mass [kg]
    pub mass_kg: f64,
    /// COM in frame 7 [mm]
    pub com_mm: [f64; 3],
}

/// `[inertials]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Inertials {
    /// moving links 2..7
    pub links: Vec<LinkInertial>,
    /// tool
    pub tool: ToolInertial,
}

/// A vertical cylinder on the world z axis (or, for `trical`, below the active position).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CylinderObstacle {
    /// radius [mm]
    pub radius_mm: f64,
    /// bottom [mm]
    pub z_min_mm: f64,
    /// top [mm]
    pub z_max_mm: f64,
}

/// An axis-aligned box in frame-0 coordinates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoxObstacle {
    /// x min [mm]
    pub x_min_mm: f64,
    /// x max [mm]
    pub x_max_mm: f64,
    /// y min [mm]
    pub y_min_mm: f64,
    /// y max [mm]
    pub y_max_mm: f64,
    /// z min [mm]
    pub z_min_mm: f64,
    /// z max [mm]
    pub z_max_mm: f64,
}

/// A horizontal plane (world z).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaneObstacle {
    /// height [mm]
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// reference temperature [°C] for a temperature-driven `thermal-drift` (default 20)
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
    /// parameter values in file units
    #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
    pub values: toml::Table,
}

/// `[motion]` (optional): speed limits used to estimate motion time when planning a tour.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotionLimits {
    /// maximum speed of the Meca500 joints J1..J6 [deg/s]
    pub joint_speed_deg_per_s: [f64; 6],
    /// maximum speed of the linear guide [mm/s]
    pub guide_speed_mm_per_s: f64,
    /// fraction of the maximum speed used for planned moves (0..1]
    #[serde(default = "default_speed_fraction")]
    pub speed_fraction: f64,
    /// time to settle + auto-centre at each measurement [s]
    #[serde(default = "default_measure_s")]
    pub measurement_s: f64,
    /// time for the operator to re-place the probe plate [s]
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
    /// must be `"meca500-zaber-cell"`
    pub format: String,
    /// must be 1
    pub version: i64,
    /// unit declaration
    pub units: Units,
    /// the seven MDH rows
    pub joints: Vec<JointRow>,
    /// base pose in the world
    pub base_in_world: BaseInWorld,
    /// calibration TCPs in frame 7
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
    /// assert!(e.to_string().starts_with("bad.toml: field `version`"), "{e}");
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
        cell.validate(origin)?;
        Ok(cell)
    }

    /// Serialises to TOML (file units). The output loads back to an equal `CellFile`.
    pub fn to_toml_string(&self) -> Result<String, CellError> {
        let body = toml::to_string_pretty(self).map_err(|e| CellError::Write(e.to_string()))?;
        Ok(format!(
            "# vatcal cell model (format {FORMAT_NAME} v{FORMAT_VERSION}).\n\
             # UNITS: mm, deg, kg, rad/(N*m), m/s^2. See docs/formats.md and docs/conventions.md.\n\n{body}"
        ))
    }

    /// Writes the file (validating first).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), CellError> {
        let path = path.as_ref();
        self.validate(&path.display().to_string())?;
        let text = self.to_toml_string()?;
        std::fs::write(path, text).map_err(|source| CellError::Io { path: path.to_path_buf(), cause: source })
    }

    /// The row of cell joint `index` (1..=7). Valid files have all seven.
    pub fn joint(&self, index: u8) -> Option<&JointRow> {
        self.joints.iter().find(|j| j.index == index)
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
    pub fn validate(&self, origin: &str) -> Result<(), CellError> {
        let bad =
            |field: String, reason: String| CellError::Invalid { origin: origin.to_string(), field, reason };
        let finite = |field: String, v: f64| -> Result<(), CellError> {
            if v.is_finite() { Ok(()) } else { Err(bad(field, format!("must be a finite number, got {v}"))) }
        };
        if self.format != FORMAT_NAME {
            return Err(bad("format".into(), format!("expected \"{FORMAT_NAME}\", got \"{}\"", self.format)));
        }
        if self.version != FORMAT_VERSION {
            return Err(bad(
                "version".into(),
                format!("unsupported version {} (this vatcal reads version {FORMAT_VERSION})", self.version),
            ));
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
        // joints: exactly indices 1..=7, each once
        let mut seen = BTreeSet::new();
        for (k, j) in self.joints.iter().enumerate() {
            if !(1..=7).contains(&j.index) {
                return Err(bad(format!("joints[{k}].index"), format!("must be 1..=7, got {}", j.index)));
            }
            if !seen.insert(j.index) {
                return Err(bad(format!("joints[{k}].index"), format!("duplicate joint row {}", j.index)));
            }
        }
        for i in 1..=7u8 {
            if !seen.contains(&i) {
                return Err(bad("joints".into(), format!("missing [[joints]] row with index = {i}")));
            }
        }
        for j in &self.joints {
            let f = |name: &str| format!("joints[index={}].{name}", j.index);
            let expected = if j.index == 1 { "prismatic" } else { "revolute" };
            match j.kind.as_str() {
                "prismatic" | "revolute" => {
                    if j.kind != expected {
                        return Err(bad(
                            f("kind"),
                            format!(
                                "joint {} must be {expected} in this cell (joint 1 is the linear guide, 2..7 the Meca500), got \"{}\"",
                                j.index, j.kind
                            ),
                        ));
                    }
                }
                other => {
                    return Err(bad(
                        f("kind"),
                        format!("unknown joint kind \"{other}\" (expected \"prismatic\" or \"revolute\")"),
                    ));
                }
            }
            for (name, v) in [
                ("alpha_deg", j.alpha_deg),
                ("a_mm", j.a_mm),
                ("beta_deg", j.beta_deg),
                ("theta_deg", j.theta_deg),
                ("d_mm", j.d_mm),
                ("q_min", j.q_min),
                ("q_max", j.q_max),
                ("compliance_rad_per_n_m", j.compliance_rad_per_n_m),
            ] {
                finite(f(name), v)?;
            }
            if j.q_min > j.q_max {
                return Err(bad(f("q_min"), format!("q_min ({}) > q_max ({})", j.q_min, j.q_max)));
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
            if !(2..=7).contains(&l.frame) {
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
        if t.frame != 7 {
            return Err(bad(
                "inertials.tool.frame".into(),
                format!("the tool is attached to frame 7, got {}", t.frame),
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
        Ok(())
    }
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
