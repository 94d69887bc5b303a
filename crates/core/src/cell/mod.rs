//! The cell model file.
//!
//! * Version 1 (`format = "meca500-zaber-cell"`, `version = 1`): the canonical Meca500 on its
//!   linear guide — exactly 7 `[[joints]]` rows, row 1 prismatic (the guide), rows 2..7
//!   revolute.
//! * Version 2 (`format = "serial-robot-cell"`, `version = 2`): any serial chain of
//!   1..=[`MAX_JOINTS`](crate::units::MAX_JOINTS) rows, each `kind = "revolute" | "prismatic"`
//!   in any order, with optional limits on revolute rows (absent = continuous joint), an
//!   optional `[robot]` table, and the same other tables as version 1. Frame N (the last row)
//!   is the flange in which the TCPs are given.
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

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::units::JointKind;

mod locate;
mod tables;
mod validate;

pub use tables::{
    BaseInWorld, BoxObstacle, CylinderObstacle, EffectEntry, Gravity, Inertials, JointRow, LinkInertial,
    MotionLimits, Obstacles, PlaneEntry, PlaneObstacle, PointEntry, RobotInfo, ToolInertial, Units,
};

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
    /// contact planes in the world (optional, for plane rows)
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub planes: Vec<PlaneEntry>,
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
                CellError::Invalid { origin, line: locate::locate_field(text, &field), field, reason }
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

    /// Issue 31: the optional `[[planes]]` round-trip; a zero normal, a radius ≤ 0 and a
    /// duplicate id are refused naming the field.
    #[test]
    fn planes_are_optional_round_trip_and_are_checked() {
        let plane = "\n[[planes]]\nid = 3\nnormal = [0.0, 0.0, 2.0]\noffset_mm = -50.0\n";
        let cell = CellFile::from_toml_str(&(canonical_text() + plane), "p").expect("valid");
        assert_eq!((cell.planes[0].id, cell.planes[0].contact_radius_mm), (3, None));
        let back = CellFile::from_toml_str(&cell.to_toml_string().expect("s"), "q").expect("reload");
        assert_eq!(back.planes, cell.planes);
        expect_invalid(&(canonical_text() + &plane.replace("2.0]", "0.0]")), "planes[id=3].normal");
        let radius = format!("{plane}contact_radius_mm = 0.0\n");
        expect_invalid(&(canonical_text() + &radius), "planes[id=3].contact_radius_mm");
        expect_invalid(&(canonical_text() + plane + plane), "planes[1].id");
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
