//! The checks of a read over the whole file: tracker coordinates that are metres read as
//! millimetres, revolute values that are radians read as degrees, and the directions derived
//! from the row order; then the read's outcome with its warnings.

use vatcal_core::{JointVector, MAX_JOINTS, Measurement, MeasurementContext, Target};
use vatcal_kinematics::Model;

use crate::error::IoError;
use crate::options::{AngleUnit, LengthUnit, ReadOutcome, dirs_from_row_order};
use crate::table::Table;

/// Below this largest |x|, |y|, |z| \[mm\] over every tracker row of a file (3 rows or more),
/// the coordinates are taken for metres read as millimetres: an instrument that saw a robot
/// move, with every point within 10 mm of its origin, is implausible.
const TRACKER_METRES_AS_MM_BOUND_MM: f64 = 10.0;

impl Table {
    /// Refuses tracker coordinates that are plainly metres read as millimetres (every
    /// coordinate of 3+ tracker rows within ±10 mm of the instrument's origin), naming the line
    /// and column of the largest.
    pub(crate) fn check_tracker_length_unit(&self, rows: &[Measurement]) -> Result<(), IoError> {
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
    pub(crate) fn finish<T>(
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
