//! The options of the commands that read measured joint / measurement CSV files (`fk`,
//! `validate`, `discover`, `identify`, `evaluate-fixed-points`): units, the tolerance on the
//! joint limits and the approach directions from the row order (`vatcal_io::ReadOptions`).

use std::path::Path;

use vatcal_core::Measurement;
use vatcal_io::{
    AngleUnit, JointRow, LengthUnit, LimitTolerance, ReadOptions, ReadOutcome, ReadWarning, RowSource,
};
use vatcal_kinematics::Model;

/// Reader options of the measured-data files, flattened into a command's arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct ReadArgs {
    /// Unit of the lengths in the CSV files: prismatic joint values and tracker x,y,z (`mm` or
    /// `m`; ROS and most recorders write metres). Columns named with a unit (`offset_x_mm`)
    /// keep it.
    #[arg(long, default_value = "mm", value_parser = parse_length_unit)]
    pub length_unit: LengthUnit,
    /// Unit of the revolute joint values in the CSV files (`deg` or `rad`; ROS
    /// `sensor_msgs/JointState` is in radians).
    #[arg(long, default_value = "deg", value_parser = parse_angle_unit)]
    pub angle_unit: AngleUnit,
    /// A revolute joint read beyond its limit by at most this much \[deg\] is a warning naming
    /// file, line and joint; further beyond, an error.
    #[arg(long, default_value_t = LimitTolerance::MEASURED.revolute_deg)]
    pub limit_tolerance_deg: f64,
    /// A prismatic joint read beyond its limit by at most this much \[mm\] is a warning; further
    /// beyond, an error.
    #[arg(long, default_value_t = LimitTolerance::MEASURED.prismatic_mm)]
    pub limit_tolerance_mm: f64,
    /// Derive the approach direction dir{i} of every revolute joint i from the row order of
    /// each file (rows recorded in sequence): the sign of the joint's last change (0 until it
    /// first moves). Backlash needs it; a file with dir columns of its own is refused.
    #[arg(long)]
    pub dir_from_row_order: bool,
}

fn parse_length_unit(s: &str) -> Result<LengthUnit, String> {
    s.parse()
}

fn parse_angle_unit(s: &str) -> Result<AngleUnit, String> {
    s.parse()
}

impl ReadArgs {
    /// The reader options (checks the tolerances).
    pub fn options(&self) -> anyhow::Result<ReadOptions> {
        for (flag, v) in [
            ("--limit-tolerance-deg", self.limit_tolerance_deg),
            ("--limit-tolerance-mm", self.limit_tolerance_mm),
        ] {
            anyhow::ensure!(v.is_finite() && v >= 0.0, "{flag} must be a number >= 0, got {v}");
        }
        Ok(ReadOptions {
            length_unit: self.length_unit,
            angle_unit: self.angle_unit,
            limit_tolerance: LimitTolerance {
                revolute_deg: self.limit_tolerance_deg,
                prismatic_mm: self.limit_tolerance_mm,
            },
            dir_from_row_order: self.dir_from_row_order,
            ..ReadOptions::default()
        })
    }

    /// `vatcal_io::read_joint_rows_with`, warnings printed.
    pub fn joint_rows(&self, path: &Path, model: &Model) -> anyhow::Result<Vec<JointRow>> {
        Ok(print_warnings(vatcal_io::read_joint_rows_with(path, model, &self.options()?)?))
    }

    /// `vatcal_io::read_any_measurements_with` (probe and/or tracker rows, or pose rows: a
    /// tracker and an orientation measurement each), warnings printed.
    pub fn measurements(&self, path: &Path, model: &Model) -> anyhow::Result<Vec<Measurement>> {
        Ok(print_warnings(vatcal_io::read_any_measurements_with(path, model, &self.options()?)?))
    }

    /// [`Self::measurements`] with the source (`file:line`) of every row, in the same order,
    /// reading rows of any `tcp` id, also one the model lacks (markers: the caller adds them,
    /// `--unknown-tcps`, or refuses them: `super::markers`).
    pub fn markers_with_sources(
        &self,
        path: &Path,
        model: &Model,
    ) -> anyhow::Result<(Vec<Measurement>, Vec<RowSource>)> {
        let options = ReadOptions { any_tcp_id: true, ..self.options()? };
        let read = vatcal_io::read_any_measurements_with(path, model, &options)?;
        let sources = read.sources();
        Ok((print_warnings(read), sources))
    }

    /// Fixed-point rows (probe rows whose `position` is any point id), warnings printed.
    pub fn fixed_points(&self, path: &Path, model: &Model) -> anyhow::Result<Vec<Measurement>> {
        let options = ReadOptions { any_position_id: true, ..self.options()? };
        Ok(print_warnings(vatcal_io::read_probe_measurements_with(path, model, &options)?))
    }
}

/// Warnings shown at most per file (the rest counted).
const MAX_WARNINGS_SHOWN: usize = 20;

/// Prints the warnings of a read to stderr (`warning: file:line: column `q4`: ...`) and
/// returns the rows.
pub fn print_warnings<T>(read: ReadOutcome<T>) -> Vec<T> {
    let warnings: &[ReadWarning] = &read.warnings;
    for w in warnings.iter().take(MAX_WARNINGS_SHOWN) {
        eprintln!("warning: {w}");
    }
    if warnings.len() > MAX_WARNINGS_SHOWN {
        eprintln!("warning: ... and {} more warnings of the same file", warnings.len() - MAX_WARNINGS_SHOWN);
    }
    read.rows
}
