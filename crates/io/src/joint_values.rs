//! The joint values of a row: file units to internal units, the joint limits with the reader's
//! tolerance, and the checks that a value can be in the stated unit (also of tracker lengths).

use vatcal_core::{JointKind, JointVector, MAX_JOINTS};
use vatcal_kinematics::Model;

use crate::error::IoError;
use crate::options::{AngleUnit, LengthUnit, ReadOptions};
use crate::table::Table;

impl Table {
    /// The joints `q1..qN` of a row (file units → internal units), checked against the
    /// model's limits.
    pub(crate) fn joints(
        &self,
        line: u64,
        rec: &csv::StringRecord,
        model: &Model,
    ) -> Result<JointVector, IoError> {
        let kinds = model.joint_kinds();
        let mut values = [0.0; MAX_JOINTS];
        let joints = &self.cols.joints;
        for (k, v) in values.iter_mut().enumerate().take(kinds.len()) {
            *v = match joints.get(k) {
                Some((name, index)) => self.float_at(line, rec, name, *index)?,
                None => self.float(line, rec, &format!("q{}", k + 1))?,
            };
        }
        let opts = &self.opts;
        if *opts == ReadOptions::strict() {
            let q = JointVector::from_file_units(&values[..kinds.len()], kinds)
                .map_err(|e| self.err(line, "q1", e.to_string()))?;
            if let Some((joint, _, lo, hi)) = model.limit_violation(&q) {
                let kind = kinds[joint - 1];
                let (lo, hi) = (kind.to_file_unit(lo), kind.to_file_unit(hi));
                let unit = kind.file_unit();
                return Err(self.err(
                    line,
                    &format!("q{joint}"),
                    format!("{} {unit} is outside the joint limits [{lo}, {hi}] {unit}", values[joint - 1]),
                ));
            }
            return Ok(q);
        }
        // file units -> internal units (mm, rad), then the limits with their tolerance
        let mut internal = [0.0; MAX_JOINTS];
        for (k, kind) in kinds.iter().enumerate() {
            let (scale, unit) = self.joint_unit(*kind);
            let v = values[k];
            if opts.check_units {
                self.check_joint_unit(line, k + 1, *kind, v)?;
            }
            internal[k] = v * scale;
            let Some((lo, hi)) = model.joint_limit(k + 1) else { continue };
            let x = internal[k];
            if (lo..=hi).contains(&x) {
                continue;
            }
            // the excess in the user's units of tolerance (deg / mm)
            let excess = kind.to_file_unit(if x < lo { lo - x } else { x - hi });
            let (tolerance, tol_unit) = match kind {
                JointKind::Revolute => (opts.limit_tolerance.revolute_deg, "deg"),
                JointKind::Prismatic => (opts.limit_tolerance.prismatic_mm, "mm"),
            };
            let limits = format!("[{}, {}] {unit}", lo / scale, hi / scale);
            let column = format!("q{}", k + 1);
            if excess <= tolerance {
                self.warn(
                    line,
                    &column,
                    format!(
                        "{v} {unit} is beyond the joint limits {limits} by {excess:.4} {tol_unit} (within the \
                         tolerance of {tolerance} {tol_unit}: read as measured)"
                    ),
                );
            } else {
                return Err(self.err(
                    line,
                    &column,
                    format!(
                        "{v} {unit} is outside the joint limits {limits} (by {excess:.4} {tol_unit}, more than \
                         the tolerance of {tolerance} {tol_unit}){}",
                        if self.fits_other_unit(*kind, v, lo, hi) { self.unit_hint(*kind) } else { "" }
                    ),
                ));
            }
        }
        JointVector::from_slice(&internal[..kinds.len()]).map_err(|e| self.err(line, "q1", e.to_string()))
    }

    /// Internal units per file unit of a joint of `kind`, and the file unit's label.
    pub(crate) fn joint_unit(&self, kind: JointKind) -> (f64, &'static str) {
        match kind {
            JointKind::Revolute => (self.opts.angle_unit.to_rad(), self.opts.angle_unit.label()),
            JointKind::Prismatic => (self.opts.length_unit.to_mm(), self.opts.length_unit.label()),
        }
    }

    /// Whether the file value `v` of a joint of `kind` would lie within the limits `[lo, hi]`
    /// (internal units) if it were in the other unit (degrees for radians — only beyond a turn,
    /// as a smaller value is a plausible angle in radians —, metres for mm, and back).
    pub(crate) fn fits_other_unit(&self, kind: JointKind, v: f64, lo: f64, hi: f64) -> bool {
        let other = match kind {
            JointKind::Revolute => match self.opts.angle_unit {
                AngleUnit::Deg => v,
                // a value within a turn is a plausible angle in radians: no hint at degrees
                AngleUnit::Rad if v.abs() <= std::f64::consts::TAU => return false,
                AngleUnit::Rad => v.to_radians(),
            },
            JointKind::Prismatic => match self.opts.length_unit {
                LengthUnit::Mm => v * 1000.0,
                LengthUnit::M => v,
            },
        };
        (lo..=hi).contains(&other)
    }

    /// A hint at the other unit (for an error on a value that fits it).
    pub(crate) fn unit_hint(&self, kind: JointKind) -> &'static str {
        match (kind, self.opts.angle_unit, self.opts.length_unit) {
            (JointKind::Revolute, AngleUnit::Deg, _) => " (radians? use --angle-unit rad)",
            (JointKind::Revolute, AngleUnit::Rad, _) => " (degrees? use --angle-unit deg)",
            (JointKind::Prismatic, _, LengthUnit::Mm) => " (metres? use --length-unit m)",
            (JointKind::Prismatic, _, LengthUnit::M) => " (millimetres? use --length-unit mm)",
        }
    }

    /// Refuses a joint value that cannot be in the stated unit: more than two turns in radians
    /// (degrees?) or more than 20 m in metres (millimetres?).
    pub(crate) fn check_joint_unit(
        &self,
        line: u64,
        joint: usize,
        kind: JointKind,
        v: f64,
    ) -> Result<(), IoError> {
        let bad = match kind {
            JointKind::Revolute => {
                self.opts.angle_unit == AngleUnit::Rad && v.abs() > 4.0 * std::f64::consts::PI
            }
            JointKind::Prismatic => self.opts.length_unit == LengthUnit::M && v.abs() > 20.0,
        };
        if bad {
            let (_, unit) = self.joint_unit(kind);
            return Err(self.err(
                line,
                &format!("q{joint}"),
                format!("{v} {unit} is implausible for a joint{}", self.unit_hint(kind)),
            ));
        }
        Ok(())
    }

    /// A length column (`x,y,z`) in mm, from the file's length unit.
    pub(crate) fn length_mm(&self, line: u64, rec: &csv::StringRecord, col: &str) -> Result<f64, IoError> {
        let v = self.float(line, rec, col)?;
        if self.opts.check_units && self.opts.length_unit == LengthUnit::M && v.abs() > 100.0 {
            return Err(self.err(
                line,
                col,
                format!(
                    "{v} m is more than 100 m from the instrument's origin (millimetres? use --length-unit mm)"
                ),
            ));
        }
        Ok(v * self.opts.length_unit.to_mm())
    }
}
