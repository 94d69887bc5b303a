//! The joint range a calibration was fitted on (`[training_range]` of a calibrated cell file).
//!
//! A calibrated model is trustworthy near the postures it was fitted to; far outside them the
//! parameters that the training postures barely excited extrapolate (issue 29). `vatcal
//! identify` records, per joint, the smallest and largest value over the rows it fitted;
//! `vatcal validate` and `vatcal compensate` warn about postures outside that range by more
//! than [`TrainingRange::tolerance`]. Extrapolation is a warning, never an error.
//!
//! Values are in **file units**: mm for prismatic joints, degrees for revolute joints.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::units::{JointKind, JointVector};

/// Smallest tolerance of a revolute joint \[deg\] (see [`TrainingRange::tolerance`]).
pub const MIN_TOLERANCE_DEG: f64 = 0.5;
/// Smallest tolerance of a prismatic joint \[mm\] (see [`TrainingRange::tolerance`]).
pub const MIN_TOLERANCE_MM: f64 = 0.5;
/// Fraction of a joint's training range it may be left by without a warning.
pub const TOLERANCE_FRACTION: f64 = 0.01;
/// Extrapolation warnings a command prints at most (then a count of the rest).
pub const MAX_WARNINGS: usize = 20;

/// The joints of [`TrainingRange::excursions`] as one comma-separated list, for a warning.
pub fn list(excursions: &[JointExcursion]) -> String {
    excursions.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
}

/// Per-joint minimum and maximum over the rows a calibration was fitted on, in file units
/// (mm for prismatic, degrees for revolute joints). The optional `[training_range]` table of a
/// cell file:
///
/// ```toml
/// [training_range]
/// rows = 80
/// q_min = [-120.5, -80.2, 10.0, -170.0, -90.0, -175.0]
/// q_max = [115.0, 20.4, 150.3, 160.0, 95.5, 170.0]
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainingRange {
    /// number of rows the range was taken from
    pub rows: usize,
    /// smallest value of joint i (index i − 1) over the rows (mm / deg)
    pub q_min: Vec<f64>,
    /// largest value of joint i over the rows (mm / deg)
    pub q_max: Vec<f64>,
}

/// One joint of a posture outside the training range ([`TrainingRange::excursions`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointExcursion {
    /// joint number, 1-based (`q{joint}` in the CSV files)
    pub joint: usize,
    /// the posture's value (mm / deg)
    pub value: f64,
    /// training minimum (mm / deg)
    pub min: f64,
    /// training maximum (mm / deg)
    pub max: f64,
    /// how far beyond the nearer end of the range (> 0, mm / deg)
    pub beyond: f64,
    /// `mm` or `deg`
    pub unit: String,
}

impl fmt::Display for JointExcursion {
    /// `q3 = 152.1 deg (trained -10.0..140.0 deg; 12.1 beyond)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "q{} = {:.3} {u} (trained {:.3}..{:.3} {u}; {:.3} beyond)",
            self.joint,
            self.value,
            self.min,
            self.max,
            self.beyond,
            u = self.unit
        )
    }
}

impl TrainingRange {
    /// The range of `postures` (internal units: mm / rad) of a chain with joints `kinds`;
    /// `None` without postures or when a posture's length differs from `kinds`.
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::training_range::TrainingRange;
    /// use vatcal_core::{JointKind, JointVector};
    ///
    /// let kinds = [JointKind::Prismatic, JointKind::Revolute];
    /// let rows = [
    ///     JointVector::from_file_units(&[100.0, -20.0], &kinds)?,
    ///     JointVector::from_file_units(&[250.0, 40.0], &kinds)?,
    /// ];
    /// let range = TrainingRange::from_postures(&kinds, &rows).expect("two rows");
    /// assert_eq!(range.rows, 2);
    /// assert!((range.q_max[1] - 40.0).abs() < 1e-9); // degrees
    /// // 60 deg on joint 2 is 20 deg beyond the range (tolerance: 1 % of 60 deg, at least 0.5 deg)
    /// let far = JointVector::from_file_units(&[150.0, 60.0], &kinds)?;
    /// let out = range.excursions(&kinds, &far);
    /// assert_eq!(out.len(), 1);
    /// assert_eq!(out[0].joint, 2);
    /// assert!((out[0].beyond - 20.0).abs() < 1e-9);
    /// // 40.4 deg is within the tolerance
    /// let near = JointVector::from_file_units(&[150.0, 40.4], &kinds)?;
    /// assert!(range.excursions(&kinds, &near).is_empty());
    /// # Ok::<(), vatcal_core::JointVectorError>(())
    /// ```
    pub fn from_postures<'a>(
        kinds: &[JointKind],
        postures: impl IntoIterator<Item = &'a JointVector>,
    ) -> Option<Self> {
        let n = kinds.len();
        let mut q_min = vec![f64::INFINITY; n];
        let mut q_max = vec![f64::NEG_INFINITY; n];
        let mut rows = 0;
        for q in postures {
            if q.len() != n {
                return None;
            }
            for (k, v) in q.to_file_units(kinds).into_iter().enumerate() {
                q_min[k] = q_min[k].min(v);
                q_max[k] = q_max[k].max(v);
            }
            rows += 1;
        }
        (rows > 0 && q_min.iter().chain(&q_max).all(|v| v.is_finite())).then_some(Self { rows, q_min, q_max })
    }

    /// How far joint `joint` (1-based) may leave the range without a warning: the larger of
    /// [`TOLERANCE_FRACTION`] (1 %) of its training range and 0.5 deg ([`MIN_TOLERANCE_DEG`],
    /// revolute) or 0.5 mm ([`MIN_TOLERANCE_MM`], prismatic) — the limit tolerance of measured
    /// data (docs/formats.md), above encoder noise and rounding.
    pub fn tolerance(&self, joint: usize, kind: JointKind) -> f64 {
        let k = joint.saturating_sub(1);
        let span = match (self.q_min.get(k), self.q_max.get(k)) {
            (Some(lo), Some(hi)) => hi - lo,
            _ => 0.0,
        };
        let floor = if kind.is_revolute() { MIN_TOLERANCE_DEG } else { MIN_TOLERANCE_MM };
        (TOLERANCE_FRACTION * span).max(floor)
    }

    /// The joints of posture `q` (internal units) outside the range by more than
    /// [`Self::tolerance`], in joint order (empty: inside). Joints beyond the range's length
    /// are not checked.
    pub fn excursions(&self, kinds: &[JointKind], q: &JointVector) -> Vec<JointExcursion> {
        let values = q.to_file_units(kinds);
        let mut out = Vec::new();
        for (k, v) in values.iter().enumerate() {
            let (Some(lo), Some(hi), Some(kind)) = (self.q_min.get(k), self.q_max.get(k), kinds.get(k))
            else {
                continue;
            };
            let beyond = if v < lo { lo - v } else { v - hi };
            if beyond > self.tolerance(k + 1, *kind) {
                out.push(JointExcursion {
                    joint: k + 1,
                    value: *v,
                    min: *lo,
                    max: *hi,
                    beyond,
                    unit: kind.file_unit().to_string(),
                });
            }
        }
        out
    }

    /// Checks the table against a chain of `joints` joints: one `q_min` and `q_max` per joint,
    /// finite, `q_min ≤ q_max`, at least one row. Returns the field (`training_range.q_min`) and
    /// the reason of the first problem.
    pub fn check(&self, joints: usize) -> Result<(), (String, String)> {
        if self.rows == 0 {
            return Err(("training_range.rows".into(), "must be at least 1".into()));
        }
        for (name, list) in [("q_min", &self.q_min), ("q_max", &self.q_max)] {
            if list.len() != joints {
                return Err((
                    format!("training_range.{name}"),
                    format!("one value per joint: expected {joints}, got {}", list.len()),
                ));
            }
            if let Some(v) = list.iter().find(|v| !v.is_finite()) {
                return Err((format!("training_range.{name}"), format!("must be finite numbers, got {v}")));
            }
        }
        if let Some(k) = (0..joints).find(|k| self.q_min[*k] > self.q_max[*k]) {
            return Err((
                "training_range.q_min".into(),
                format!("joint {}: q_min ({}) > q_max ({})", k + 1, self.q_min[k], self.q_max[k]),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tolerance_is_one_percent_or_half_a_unit() {
        let r = TrainingRange { rows: 3, q_min: vec![0.0, -10.0], q_max: vec![300.0, 10.0] };
        assert!((r.tolerance(1, JointKind::Prismatic) - 3.0).abs() < 1e-12);
        assert!((r.tolerance(2, JointKind::Revolute) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn check_names_the_field() {
        let r = TrainingRange { rows: 3, q_min: vec![0.0, 20.0], q_max: vec![1.0, 10.0] };
        assert_eq!(r.check(3).expect_err("length").0, "training_range.q_min");
        let e = r.check(2).expect_err("inverted");
        assert!(e.1.contains("joint 2"), "{e:?}");
        let bad = TrainingRange { rows: 0, ..r };
        assert_eq!(bad.check(2).expect_err("no rows").0, "training_range.rows");
    }

    #[test]
    fn mismatched_postures_give_none() {
        let kinds = [JointKind::Revolute; 2];
        assert!(TrainingRange::from_postures(&kinds, &[]).is_none());
        assert!(TrainingRange::from_postures(&kinds, &[JointVector::zeros(3)]).is_none());
    }
}
