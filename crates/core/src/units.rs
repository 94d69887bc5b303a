//! Units and the joint vector.
//!
//! Inside vatcal every angle is in radians and every length in millimetres. Files, the CLI and
//! device protocols use degrees; convert with [`deg_to_rad`] / [`rad_to_deg`] at the boundary.

use serde::{Deserialize, Serialize};

use crate::JOINT_COUNT;

/// Degrees to radians.
#[inline]
pub fn deg_to_rad(deg: f64) -> f64 {
    deg.to_radians()
}

/// Radians to degrees.
#[inline]
pub fn rad_to_deg(rad: f64) -> f64 {
    rad.to_degrees()
}

/// The seven joint values of the cell in **internal units**: `q[0]` = guide position q1 in mm,
/// `q[1..7]` = Meca500 joints J1..J6 (cell joints q2..q7) in radians.
///
/// Cell joint `i` (1-based, as in the paper and the file formats) is `q[i - 1]`; use
/// [`JointVector::get`] to index by cell joint number.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct JointVector(pub [f64; JOINT_COUNT]);

impl JointVector {
    /// Builds a joint vector from internal units (q1 mm, q2..q7 rad).
    pub fn new(q: [f64; JOINT_COUNT]) -> Self {
        Self(q)
    }

    /// Builds a joint vector from file units: q1 in mm and q2..q7 in degrees.
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::JointVector;
    ///
    /// let q = JointVector::from_mm_deg(150.0, [90.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    /// assert_eq!(q.guide_mm(), 150.0);
    /// assert!((q.get(2) - std::f64::consts::FRAC_PI_2).abs() < 1e-15); // joint 2 in radians
    /// assert!((q.to_mm_deg()[1] - 90.0).abs() < 1e-12);
    /// ```
    pub fn from_mm_deg(q1_mm: f64, arm_deg: [f64; 6]) -> Self {
        let mut q = [0.0; JOINT_COUNT];
        q[0] = q1_mm;
        for (k, v) in arm_deg.iter().enumerate() {
            q[k + 1] = deg_to_rad(*v);
        }
        Self(q)
    }

    /// Returns the values in file units: `[q1_mm, q2_deg, ..., q7_deg]`.
    pub fn to_mm_deg(&self) -> [f64; JOINT_COUNT] {
        let mut out = self.0;
        for v in out.iter_mut().skip(1) {
            *v = rad_to_deg(*v);
        }
        out
    }

    /// Guide position q1 [mm].
    #[inline]
    pub fn guide_mm(&self) -> f64 {
        self.0[0]
    }

    /// Value of cell joint `joint` (1..=7) in internal units (mm for 1, rad otherwise).
    ///
    /// # Panics
    /// If `joint` is not in 1..=7 (a programming error).
    #[inline]
    #[track_caller]
    pub fn get(&self, joint: usize) -> f64 {
        assert!((1..=JOINT_COUNT).contains(&joint), "cell joint index {joint} not in 1..=7");
        self.0[joint - 1]
    }

    /// Sets cell joint `joint` (1..=7) in internal units.
    ///
    /// # Panics
    /// If `joint` is not in 1..=7 (a programming error).
    #[inline]
    #[track_caller]
    pub fn set(&mut self, joint: usize, value: f64) {
        assert!((1..=JOINT_COUNT).contains(&joint), "cell joint index {joint} not in 1..=7");
        self.0[joint - 1] = value;
    }

    /// True when every value is finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mm_deg_round_trip() {
        let q = JointVector::from_mm_deg(123.5, [10.0, -20.0, 30.0, -40.0, 50.0, -60.0]);
        assert!((q.get(3) - (-20f64).to_radians()).abs() < 1e-15);
        let back = q.to_mm_deg();
        assert_eq!(back[0], 123.5);
        for (a, b) in back[1..].iter().zip([10.0, -20.0, 30.0, -40.0, 50.0, -60.0]) {
            assert!((a - b).abs() < 1e-12);
        }
    }
}
