//! A small rigid transform type (rotation matrix + translation in mm).
//!
//! Kinematics works with explicit rotation matrices because the Jacobian needs the frame axes
//! (matrix columns) anyway; [`Frame::to_isometry`] converts to nalgebra's `Isometry3`.

use nalgebra::{Isometry3, Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion, Vector3};

/// Rotation matrix about x by `a` \[rad\].
pub fn rot_x(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

/// Rotation matrix about y by `a` \[rad\].
pub fn rot_y(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

/// Rotation matrix about z by `a` \[rad\].
pub fn rot_z(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Rigid transform `p_parent = r * p_child + p` (translation in mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// rotation (columns = child axes expressed in the parent frame)
    pub r: Matrix3<f64>,
    /// origin of the child frame in the parent frame \[mm\]
    pub p: Vector3<f64>,
}

impl Default for Frame {
    fn default() -> Self {
        Self::identity()
    }
}

impl Frame {
    /// Identity.
    pub fn identity() -> Self {
        Self { r: Matrix3::identity(), p: Vector3::zeros() }
    }

    /// Composition `self * other`.
    #[inline]
    pub fn compose(&self, other: &Frame) -> Frame {
        Frame { r: self.r * other.r, p: self.p + self.r * other.p }
    }

    /// Maps a point of the child frame into the parent frame.
    #[inline]
    pub fn transform_point(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.r * v + self.p
    }

    /// Inverse transform.
    pub fn inverse(&self) -> Frame {
        let rt = self.r.transpose();
        Frame { r: rt, p: -(rt * self.p) }
    }

    /// x axis (first column).
    #[inline]
    pub fn x_axis(&self) -> Vector3<f64> {
        self.r.column(0).into_owned()
    }

    /// y axis (second column).
    #[inline]
    pub fn y_axis(&self) -> Vector3<f64> {
        self.r.column(1).into_owned()
    }

    /// z axis (third column).
    #[inline]
    pub fn z_axis(&self) -> Vector3<f64> {
        self.r.column(2).into_owned()
    }

    /// As an nalgebra isometry (translation in mm).
    pub fn to_isometry(&self) -> Isometry3<f64> {
        let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(self.r));
        Isometry3::from_parts(Translation3::from(self.p), rot)
    }

    /// From an nalgebra isometry.
    pub fn from_isometry(iso: &Isometry3<f64>) -> Self {
        Self { r: *iso.rotation.to_rotation_matrix().matrix(), p: iso.translation.vector }
    }

    /// As a 4×4 homogeneous matrix.
    pub fn to_matrix4(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.r);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.p);
        m
    }
}
