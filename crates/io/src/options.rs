//! Reader options of the measured-data readers (`*_with` functions): the units of the file,
//! the tolerance on joint limits, and the derivation of the approach directions `dir{i}` from
//! the row order.
//!
//! The readers without options ([`crate::read_joint_rows`], [`crate::read_probe_measurements`],
//! [`crate::read_tracker_measurements`], [`crate::read_measurements`]) read as before: mm and
//! degrees, every joint within its limits ([`ReadOptions::strict`]). The command line's
//! `fk`, `validate`, `discover` and `identify` read measured data with [`ReadOptions::default`]:
//! a row beyond a joint limit by less than [`LimitTolerance::MEASURED`] is a warning, not an
//! error (an encoder reads a little past a soft limit; a URDF's limit is rounded).

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

/// Unit of the lengths of a file: prismatic joint values and tracker `x,y,z`. (Columns whose
/// name carries their unit, e.g. `offset_x_mm`, are always in that unit.)
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LengthUnit {
    /// millimetres (vatcal's own files)
    #[default]
    Mm,
    /// metres (ROS and most recorders: SI)
    M,
}

impl LengthUnit {
    /// Millimetres per file unit.
    pub fn to_mm(self) -> f64 {
        match self {
            LengthUnit::Mm => 1.0,
            LengthUnit::M => 1000.0,
        }
    }

    /// The unit's label: `mm` or `m`.
    pub fn label(self) -> &'static str {
        match self {
            LengthUnit::Mm => "mm",
            LengthUnit::M => "m",
        }
    }
}

impl FromStr for LengthUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "mm" => Ok(LengthUnit::Mm),
            "m" => Ok(LengthUnit::M),
            other => Err(format!("unknown length unit `{other}` (expected `mm` or `m`)")),
        }
    }
}

impl fmt::Display for LengthUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.label())
    }
}

/// Unit of the revolute joint values of a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AngleUnit {
    /// degrees (vatcal's own files)
    #[default]
    Deg,
    /// radians (ROS `sensor_msgs/JointState` and most recorders)
    Rad,
}

impl AngleUnit {
    /// Radians per file unit.
    pub fn to_rad(self) -> f64 {
        match self {
            AngleUnit::Deg => std::f64::consts::PI / 180.0,
            AngleUnit::Rad => 1.0,
        }
    }

    /// The unit's label: `deg` or `rad`.
    pub fn label(self) -> &'static str {
        match self {
            AngleUnit::Deg => "deg",
            AngleUnit::Rad => "rad",
        }
    }
}

impl FromStr for AngleUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "deg" => Ok(AngleUnit::Deg),
            "rad" => Ok(AngleUnit::Rad),
            other => Err(format!("unknown angle unit `{other}` (expected `deg` or `rad`)")),
        }
    }
}

impl fmt::Display for AngleUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.label())
    }
}

/// How far a measured joint value may lie beyond its limit and still be read (with a
/// [`ReadWarning`]); beyond it the row is an error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitTolerance {
    /// revolute joints \[deg\]
    pub revolute_deg: f64,
    /// prismatic joints \[mm\]
    pub prismatic_mm: f64,
}

impl LimitTolerance {
    /// No tolerance: every joint within its limits (planning, compensation, vatcal's own
    /// files).
    pub const STRICT: LimitTolerance = LimitTolerance { revolute_deg: 0.0, prismatic_mm: 0.0 };

    /// The default for measured data: 0.5 deg and 0.5 mm. Larger than what an encoder reads
    /// past a soft limit or what rounding a URDF limit to 4 decimals in radians (0.003 deg)
    /// or to 1 mm leaves (a recorded torso at 350.18 mm against a 350 mm limit); small enough
    /// that a row in the wrong unit or of another robot is still refused.
    pub const MEASURED: LimitTolerance = LimitTolerance { revolute_deg: 0.5, prismatic_mm: 0.5 };
}

impl Default for LimitTolerance {
    fn default() -> Self {
        Self::MEASURED
    }
}

/// Options of the measured-data readers (`*_with`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadOptions {
    /// unit of prismatic joint values and tracker `x,y,z`
    pub length_unit: LengthUnit,
    /// unit of revolute joint values
    pub angle_unit: AngleUnit,
    /// tolerance on the joint limits (a warning within it, an error beyond)
    pub limit_tolerance: LimitTolerance,
    /// derive the approach direction `dir{i}` of every revolute joint i from the row order
    /// (rows recorded in sequence): the sign of the joint's last change of more than
    /// [`DIR_DEADBAND_DEG`], 0 (unknown) until the joint first moves. A file that has `dir`
    /// columns of its own is then refused.
    pub dir_from_row_order: bool,
    /// check that the values look like the given units (e.g. every angle within ±2π with
    /// degrees: radians?) and refuse the file with a hint otherwise
    pub check_units: bool,
    /// probe rows name fixed points at unknown places (e.g. the sockets of a fixture): any
    /// `position` id is read, not only the model's calibration positions
    pub any_position_id: bool,
    /// rows name markers the model may lack (several markers of one body, fitted at unknown
    /// offsets): any `tcp` id is read, not only the model's TCPs. The caller adds the TCPs the
    /// data use to the model (`vatcal identify --unknown-tcps`) or refuses them.
    pub any_tcp_id: bool,
}

impl ReadOptions {
    /// The behaviour of the readers without options: mm and degrees, no tolerance on the
    /// limits, no direction derivation, no unit heuristics.
    pub const fn strict() -> Self {
        ReadOptions {
            length_unit: LengthUnit::Mm,
            angle_unit: AngleUnit::Deg,
            limit_tolerance: LimitTolerance::STRICT,
            dir_from_row_order: false,
            check_units: false,
            any_position_id: false,
            any_tcp_id: false,
        }
    }
}

impl Default for ReadOptions {
    /// Measured data: mm and degrees, [`LimitTolerance::MEASURED`], unit checks on, no
    /// direction derivation.
    fn default() -> Self {
        ReadOptions {
            length_unit: LengthUnit::Mm,
            angle_unit: AngleUnit::Deg,
            limit_tolerance: LimitTolerance::MEASURED,
            dir_from_row_order: false,
            check_units: true,
            any_position_id: false,
            any_tcp_id: false,
        }
    }
}

/// Changes of a joint smaller than this (degrees) do not change its derived approach direction
/// (encoder jitter of a joint at rest).
pub const DIR_DEADBAND_DEG: f64 = 1e-3;

/// A value that was read but deserves the user's attention (e.g. a joint slightly beyond its
/// limit), with the file, line and column.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadWarning {
    /// file
    pub path: PathBuf,
    /// 1-based line
    pub line: u64,
    /// column
    pub column: String,
    /// what is unusual
    pub message: String,
}

impl fmt::Display for ReadWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: column `{}`: {}", self.path.display(), self.line, self.column, self.message)
    }
}

/// The rows of a file read with options, and the warnings, in line order.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadOutcome<T> {
    /// the rows, in file order
    pub rows: Vec<T>,
    /// warnings, in line order
    pub warnings: Vec<ReadWarning>,
    /// the 1-based line of every row of `rows` in the file (same order and length), so that a
    /// later step can name a row as `file:line` ([`ReadOutcome::sources`])
    pub lines: Vec<u64>,
    /// the file that was read
    pub path: PathBuf,
}

/// Where a row came from: file and 1-based line. Displays as `file:line`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RowSource {
    /// the file
    pub path: PathBuf,
    /// 1-based line
    pub line: u64,
}

impl fmt::Display for RowSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.path.display(), self.line)
    }
}

impl<T> ReadOutcome<T> {
    /// The source (`file:line`) of every row, in the order of `rows`.
    pub fn sources(&self) -> Vec<RowSource> {
        self.lines.iter().map(|line| RowSource { path: self.path.clone(), line: *line }).collect()
    }
}

/// The approach directions of a sequence of joint vectors recorded in this order (internal
/// units, radians for revolute joints): for each revolute joint (`revolute[k]`) the sign of its
/// last change larger than [`DIR_DEADBAND_DEG`], 0 before its first such change; non-revolute
/// joints get 0.
pub fn dirs_from_row_order(q: &[&[f64]], revolute: &[bool]) -> Vec<Vec<i8>> {
    let deadband = DIR_DEADBAND_DEG.to_radians();
    let n = revolute.len();
    let mut current = vec![0i8; n];
    let mut out = Vec::with_capacity(q.len());
    for (k, row) in q.iter().enumerate() {
        if k > 0 {
            for (j, d) in current.iter_mut().enumerate() {
                let delta = row.get(j).copied().unwrap_or(0.0) - q[k - 1].get(j).copied().unwrap_or(0.0);
                if revolute[j] && delta.abs() > deadband {
                    *d = if delta > 0.0 { 1 } else { -1 };
                }
            }
        }
        out.push(current.clone());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_parse_and_scale() {
        assert_eq!("m".parse::<LengthUnit>(), Ok(LengthUnit::M));
        assert_eq!("rad".parse::<AngleUnit>(), Ok(AngleUnit::Rad));
        assert!("inch".parse::<LengthUnit>().expect_err("bad").contains("`mm` or `m`"));
        assert!("grad".parse::<AngleUnit>().expect_err("bad").contains("`deg` or `rad`"));
        assert_eq!(LengthUnit::M.to_mm(), 1000.0);
        assert!((AngleUnit::Deg.to_rad() * 180.0 - std::f64::consts::PI).abs() < 1e-15);
    }

    #[test]
    fn directions_follow_the_last_move_of_each_joint() {
        let d = 1e-4_f64.to_radians(); // below the dead band
        let rows: Vec<Vec<f64>> =
            vec![vec![0.0, 5.0], vec![0.1, 5.0], vec![0.1 + d, 5.0], vec![0.05, 5.0], vec![0.05, 4.0]];
        let refs: Vec<&[f64]> = rows.iter().map(Vec::as_slice).collect();
        let dirs = dirs_from_row_order(&refs, &[true, true]);
        assert_eq!(dirs, vec![vec![0, 0], vec![1, 0], vec![1, 0], vec![-1, 0], vec![-1, -1]]);
        // a prismatic joint has no approach direction column
        let dirs = dirs_from_row_order(&refs, &[true, false]);
        assert_eq!(dirs[4], vec![-1, 0]);
    }
}
