//! Units, joint kinds and the joint vector.
//!
//! Inside vatcal every angle is in radians and every length in millimetres. Files, the CLI and
//! device protocols use degrees; convert with [`deg_to_rad`] / [`rad_to_deg`] at the boundary,
//! or with [`JointVector::from_file_units`] / [`JointVector::to_file_units`] for joint rows
//! (mm for prismatic joints, degrees for revolute joints).

use std::fmt;
use std::ops::{Index, IndexMut};
use std::slice::SliceIndex;

use serde::de::{SeqAccess, Visitor};
use serde::ser::SerializeSeq;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::JOINT_COUNT;

/// The largest number of joints a serial chain may have in vatcal.
pub const MAX_JOINTS: usize = 12;

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

/// What a joint of a serial chain does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Rotation about z_i: `theta_i = q_i + theta_offset_i (+ c_i tau_i + effects)`, q in rad
    /// inside vatcal, degrees in files.
    Revolute,
    /// Translation along z_i: `d_i = q_i + d_offset_i`, q in mm.
    Prismatic,
}

/// The joint kinds of the canonical 7-joint Meca500-on-guide cell: the prismatic guide q1,
/// then the six revolute Meca500 joints q2..q7.
pub const MECA500_ON_GUIDE_KINDS: [JointKind; 7] = [
    JointKind::Prismatic,
    JointKind::Revolute,
    JointKind::Revolute,
    JointKind::Revolute,
    JointKind::Revolute,
    JointKind::Revolute,
    JointKind::Revolute,
];

impl JointKind {
    /// The name used in cell files: `"revolute"` or `"prismatic"`.
    pub fn name(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Prismatic => "prismatic",
        }
    }

    /// Parses a cell-file name (`"revolute"` / `"prismatic"`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "revolute" => Some(JointKind::Revolute),
            "prismatic" => Some(JointKind::Prismatic),
            _ => None,
        }
    }

    /// True for [`JointKind::Revolute`].
    #[inline]
    pub fn is_revolute(self) -> bool {
        self == JointKind::Revolute
    }

    /// Internal value (mm or rad) from a file value (mm or degrees).
    #[inline]
    pub fn from_file_unit(self, v: f64) -> f64 {
        match self {
            JointKind::Revolute => deg_to_rad(v),
            JointKind::Prismatic => v,
        }
    }

    /// File value (mm or degrees) from an internal value (mm or rad).
    #[inline]
    pub fn to_file_unit(self, v: f64) -> f64 {
        match self {
            JointKind::Revolute => rad_to_deg(v),
            JointKind::Prismatic => v,
        }
    }

    /// Unit label of a joint value in files: `"deg"` or `"mm"`.
    pub fn file_unit(self) -> &'static str {
        match self {
            JointKind::Revolute => "deg",
            JointKind::Prismatic => "mm",
        }
    }
}

impl fmt::Display for JointKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A joint vector of the wrong length.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum JointVectorError {
    /// Zero or more than [`MAX_JOINTS`] values.
    #[error("a joint vector has 1..={MAX_JOINTS} values, got {0}")]
    Length(usize),
    /// The values and the joint kinds differ in number.
    #[error("{values} joint values for a chain of {joints} joints")]
    Mismatch {
        /// number of values given
        values: usize,
        /// number of joints of the chain
        joints: usize,
    },
}

/// The joint values of a serial chain of 1..=[`MAX_JOINTS`] joints in **internal units**
/// (mm for prismatic joints, rad for revolute joints). A `Copy` value: fixed storage plus a
/// length, no heap allocation.
///
/// Joint `i` (1-based, as in the paper and the file formats) is `q[i - 1]` (`Index` is
/// 0-based) or [`JointVector::get`]`(i)`. On the canonical Meca500-on-guide cell, `q[0]` is the
/// guide position q1 in mm and `q[1..7]` the Meca500 joints J1..J6 in radians.
#[derive(Clone, Copy, PartialEq)]
pub struct JointVector {
    // invariant: values[len..] are 0.0 (so the derived PartialEq compares the used part)
    values: [f64; MAX_JOINTS],
    len: u8,
}

impl Default for JointVector {
    /// Seven zeros: the canonical Meca500-on-guide cell. Use [`JointVector::zeros`] for other
    /// chains.
    fn default() -> Self {
        Self::zeros(JOINT_COUNT)
    }
}

impl fmt::Debug for JointVector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("JointVector").field(&self.as_slice()).finish()
    }
}

impl JointVector {
    /// Builds a joint vector from `N` values in internal units (mm / rad).
    ///
    /// # Panics
    /// At compile time (or at run time in a non-const context) when `N` is 0 or more than
    /// [`MAX_JOINTS`] — a programming error.
    #[inline]
    pub const fn new<const N: usize>(q: [f64; N]) -> Self {
        const { assert!(N >= 1 && N <= MAX_JOINTS, "a joint vector has 1..=12 values") };
        let mut values = [0.0; MAX_JOINTS];
        let mut k = 0;
        while k < N {
            values[k] = q[k];
            k += 1;
        }
        Self { values, len: N as u8 }
    }

    /// `n` zeros (`n` clamped to 1..=[`MAX_JOINTS`]).
    #[inline]
    pub fn zeros(n: usize) -> Self {
        Self { values: [0.0; MAX_JOINTS], len: n.clamp(1, MAX_JOINTS) as u8 }
    }

    /// Builds a joint vector from a slice in internal units.
    ///
    /// # Errors
    /// [`JointVectorError::Length`] when the slice is empty or longer than [`MAX_JOINTS`].
    pub fn from_slice(q: &[f64]) -> Result<Self, JointVectorError> {
        if q.is_empty() || q.len() > MAX_JOINTS {
            return Err(JointVectorError::Length(q.len()));
        }
        let mut values = [0.0; MAX_JOINTS];
        values[..q.len()].copy_from_slice(q);
        Ok(Self { values, len: q.len() as u8 })
    }

    /// Builds a joint vector from file units (mm for prismatic, degrees for revolute joints).
    ///
    /// # Errors
    /// When the lengths differ or are not in 1..=[`MAX_JOINTS`].
    ///
    /// # Examples
    /// A UR5e-like arm (six revolute joints) and a chain with a prismatic axis first:
    /// ```
    /// use vatcal_core::{JointKind, JointVector};
    ///
    /// let arm = [JointKind::Revolute; 6];
    /// let q = JointVector::from_file_units(&[90.0, -45.0, 0.0, 0.0, 30.0, 0.0], &arm)?;
    /// assert_eq!(q.len(), 6);
    /// assert!((q[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-15); // 0-based index, radians
    /// assert!((q.get(2) + std::f64::consts::FRAC_PI_4).abs() < 1e-15); // 1-based joint number
    /// assert!((q.to_file_units(&arm)[4] - 30.0).abs() < 1e-12);
    ///
    /// let kinds = [JointKind::Prismatic, JointKind::Revolute];
    /// let q = JointVector::from_file_units(&[150.0, 90.0], &kinds)?;
    /// assert_eq!(q[0], 150.0); // mm stay mm
    /// assert!(JointVector::from_file_units(&[1.0], &kinds).is_err()); // one value for two joints
    /// # Ok::<(), vatcal_core::JointVectorError>(())
    /// ```
    pub fn from_file_units(values: &[f64], kinds: &[JointKind]) -> Result<Self, JointVectorError> {
        if values.len() != kinds.len() {
            return Err(JointVectorError::Mismatch { values: values.len(), joints: kinds.len() });
        }
        let mut q = Self::from_slice(values)?;
        for (v, k) in q.as_mut_slice().iter_mut().zip(kinds) {
            *v = k.from_file_unit(*v);
        }
        Ok(q)
    }

    /// The values in file units (mm for prismatic, degrees for revolute joints). A joint
    /// without a kind (more values than `kinds`) is returned unchanged.
    pub fn to_file_units(&self, kinds: &[JointKind]) -> Vec<f64> {
        self.as_slice()
            .iter()
            .enumerate()
            .map(|(k, v)| kinds.get(k).map_or(*v, |kind| kind.to_file_unit(*v)))
            .collect()
    }

    /// Number of joints.
    #[inline]
    #[allow(clippy::len_without_is_empty)] // never empty
    pub fn len(&self) -> usize {
        self.len as usize
    }

    /// The values (internal units).
    #[inline]
    pub fn as_slice(&self) -> &[f64] {
        &self.values[..self.len as usize]
    }

    /// The values, mutable (internal units).
    #[inline]
    pub fn as_mut_slice(&mut self) -> &mut [f64] {
        &mut self.values[..self.len as usize]
    }

    /// Iterator over the values.
    #[inline]
    pub fn iter(&self) -> std::slice::Iter<'_, f64> {
        self.as_slice().iter()
    }

    /// Builds a joint vector from file units on the canonical 7-joint Meca500-on-guide cell
    /// only: q1 in mm and the six Meca500 joints in degrees.
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::JointVector;
    ///
    /// let q = JointVector::from_mm_deg(150.0, [90.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    /// assert_eq!((q.len(), q.guide_mm()), (7, 150.0));
    /// assert!((q.get(2) - std::f64::consts::FRAC_PI_2).abs() < 1e-15); // joint 2 in radians
    /// assert!((q.to_mm_deg()[1] - 90.0).abs() < 1e-12);
    /// ```
    pub fn from_mm_deg(q1_mm: f64, arm_deg: [f64; 6]) -> Self {
        let mut q = [0.0; JOINT_COUNT];
        q[0] = q1_mm;
        for (k, v) in arm_deg.iter().enumerate() {
            q[k + 1] = deg_to_rad(*v);
        }
        Self::new(q)
    }

    /// The values in file units on the canonical 7-joint Meca500-on-guide cell only:
    /// `[q1_mm, q2_deg, ..., q7_deg]` (missing joints are 0; use
    /// [`JointVector::to_file_units`] for any chain).
    pub fn to_mm_deg(&self) -> [f64; JOINT_COUNT] {
        let mut out = [0.0; JOINT_COUNT];
        out.copy_from_slice(&self.values[..JOINT_COUNT]);
        for v in out.iter_mut().skip(1) {
            *v = rad_to_deg(*v);
        }
        out
    }

    /// Guide position q1 \[mm\] — the canonical 7-joint Meca500-on-guide cell only (the first
    /// value otherwise).
    #[inline]
    pub fn guide_mm(&self) -> f64 {
        self.values[0]
    }

    /// Value of joint `joint` (1..=len) in internal units.
    ///
    /// # Panics
    /// If `joint` is not in 1..=len (a programming error).
    #[inline]
    #[track_caller]
    pub fn get(&self, joint: usize) -> f64 {
        assert!((1..=self.len()).contains(&joint), "joint index {joint} not in 1..={}", self.len);
        self.values[joint - 1]
    }

    /// Sets joint `joint` (1..=len) in internal units.
    ///
    /// # Panics
    /// If `joint` is not in 1..=len (a programming error).
    #[inline]
    #[track_caller]
    pub fn set(&mut self, joint: usize, value: f64) {
        assert!((1..=self.len()).contains(&joint), "joint index {joint} not in 1..={}", self.len);
        self.values[joint - 1] = value;
    }

    /// True when every value is finite.
    pub fn is_finite(&self) -> bool {
        self.as_slice().iter().all(|v| v.is_finite())
    }
}

impl<I: SliceIndex<[f64]>> Index<I> for JointVector {
    type Output = I::Output;
    /// 0-based: `q[0]` is joint 1; ranges give slices (`q[1..]`).
    #[inline]
    #[track_caller]
    fn index(&self, k: I) -> &I::Output {
        &self.as_slice()[k]
    }
}

impl<I: SliceIndex<[f64]>> IndexMut<I> for JointVector {
    #[inline]
    #[track_caller]
    fn index_mut(&mut self, k: I) -> &mut I::Output {
        &mut self.as_mut_slice()[k]
    }
}

impl<'a> IntoIterator for &'a JointVector {
    type Item = &'a f64;
    type IntoIter = std::slice::Iter<'a, f64>;
    fn into_iter(self) -> Self::IntoIter {
        self.as_slice().iter()
    }
}

impl Serialize for JointVector {
    /// A sequence of `len` numbers (internal units).
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut seq = s.serialize_seq(Some(self.len()))?;
        for v in self.as_slice() {
            seq.serialize_element(v)?;
        }
        seq.end()
    }
}

impl<'de> Deserialize<'de> for JointVector {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = JointVector;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "a sequence of 1..={MAX_JOINTS} joint values")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<JointVector, A::Error> {
                let mut values = [0.0; MAX_JOINTS];
                let mut n = 0;
                while let Some(v) = seq.next_element::<f64>()? {
                    if n == MAX_JOINTS {
                        return Err(serde::de::Error::invalid_length(n + 1, &self));
                    }
                    values[n] = v;
                    n += 1;
                }
                if n == 0 {
                    return Err(serde::de::Error::invalid_length(0, &self));
                }
                Ok(JointVector { values, len: n as u8 })
            }
        }
        d.deserialize_seq(V)
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

    #[test]
    fn file_units_follow_the_kinds() {
        use JointKind::{Prismatic as P, Revolute as R};
        let kinds = [R, P, R];
        let q = JointVector::from_file_units(&[90.0, 12.5, -45.0], &kinds).expect("valid");
        assert_eq!(q.len(), 3);
        assert!((q[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert_eq!(q[1], 12.5);
        let back = q.to_file_units(&kinds);
        assert!((back[0] - 90.0).abs() < 1e-12 && back[1] == 12.5 && (back[2] + 45.0).abs() < 1e-12);
        assert!(matches!(
            JointVector::from_file_units(&[1.0, 2.0], &kinds),
            Err(JointVectorError::Mismatch { values: 2, joints: 3 })
        ));
        assert_eq!(JointVector::from_slice(&[]), Err(JointVectorError::Length(0)));
        assert_eq!(JointVector::from_slice(&[0.0; 13]), Err(JointVectorError::Length(13)));
        assert_eq!(JointVector::from_slice(&[0.0; 12]).map(|q| q.len()), Ok(12));
    }

    #[test]
    fn indexing_equality_and_serde() {
        let mut q = JointVector::new([1.0, 2.0, 3.0]);
        q[2] = 5.0;
        q.set(1, -1.0);
        assert_eq!(q.as_slice(), &[-1.0, 2.0, 5.0]);
        assert_eq!(q.get(3), 5.0);
        assert_ne!(q, JointVector::new([-1.0, 2.0, 5.0, 0.0]), "lengths differ");
        let json = serde_json::to_string(&q).expect("serialise");
        assert_eq!(json, "[-1.0,2.0,5.0]");
        let back: JointVector = serde_json::from_str(&json).expect("parse");
        assert_eq!(back, q);
        assert!(serde_json::from_str::<JointVector>("[]").is_err());
        assert!(serde_json::from_str::<JointVector>(&format!("{:?}", [0.0; 13])).is_err());
    }

    #[test]
    #[should_panic(expected = "not in 1..=3")]
    fn get_out_of_range_panics() {
        let _ = JointVector::new([0.0; 3]).get(4);
    }
}
