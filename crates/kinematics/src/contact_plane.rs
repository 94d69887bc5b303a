//! The geometry of a contact plane (`n·x = offset` with a tilted reference normal; see the
//! `plane` module for the measurements on it).

use nalgebra::Vector3;
use vatcal_core::{PlaneDof, cell::PlaneEntry};

/// A contact plane of the model (internal units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPlane {
    reference_normal: Vector3<f64>,
    u: Vector3<f64>,
    v: Vector3<f64>,
    /// tilt of the normal towards `u` \[rad\]
    pub tilt_u: f64,
    /// tilt of the normal towards `v` \[rad\]
    pub tilt_v: f64,
    /// signed distance from the world origin along the normal \[mm\]
    pub offset_mm: f64,
    /// radius of the contact face for the tool-axis rows \[mm\]
    pub contact_radius_mm: f64,
}

impl ContactPlane {
    /// A plane with normal `normal` (any non-zero length) at `offset_mm` from the world origin,
    /// tilts zero.
    ///
    /// # Examples
    /// ```
    /// use nalgebra::Vector3;
    /// use vatcal_kinematics::ContactPlane;
    ///
    /// let table = ContactPlane::new(Vector3::new(0.0, 0.0, 2.0), 10.0, 50.0);
    /// assert!((table.height_mm(&Vector3::new(3.0, 4.0, 12.5)) - 2.5).abs() < 1e-12);
    /// ```
    pub fn new(normal: Vector3<f64>, offset_mm: f64, contact_radius_mm: f64) -> Self {
        let n = normal.normalize();
        // the world axis least aligned with n gives a well-conditioned tangent basis
        let k = (0..3).min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs())).unwrap_or(0);
        let u = Vector3::ith(k, 1.0).cross(&n).normalize();
        let v = n.cross(&u);
        Self { reference_normal: n, u, v, tilt_u: 0.0, tilt_v: 0.0, offset_mm, contact_radius_mm }
    }

    /// From a cell file's `[[planes]]` entry.
    pub fn from_entry(e: &PlaneEntry) -> Self {
        Self::new(
            Vector3::from(e.normal),
            e.offset_mm,
            e.contact_radius_mm.unwrap_or(PlaneEntry::DEFAULT_CONTACT_RADIUS_MM),
        )
    }

    /// The unit normal.
    pub fn normal(&self) -> Vector3<f64> {
        self.unnormalised().normalize()
    }

    fn unnormalised(&self) -> Vector3<f64> {
        self.reference_normal + self.tilt_u * self.u + self.tilt_v * self.v
    }

    /// The fixed tangent basis `(u, v)` of the reference normal.
    pub fn basis(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.u, self.v)
    }

    /// Derivative of the unit normal with respect to a tilt (zero for the offset).
    pub fn normal_derivative(&self, dof: PlaneDof) -> Vector3<f64> {
        let w = self.unnormalised();
        let n = w / w.norm();
        let dir = match dof {
            PlaneDof::TiltU => self.u,
            PlaneDof::TiltV => self.v,
            PlaneDof::Offset => return Vector3::zeros(),
        };
        (dir - n * n.dot(&dir)) / w.norm()
    }

    /// Signed height of the point `p` above the plane \[mm\].
    pub fn height_mm(&self, p: &Vector3<f64>) -> f64 {
        self.normal().dot(p) - self.offset_mm
    }

    /// The value of one degree of freedom.
    pub fn dof(&self, dof: PlaneDof) -> f64 {
        match dof {
            PlaneDof::TiltU => self.tilt_u,
            PlaneDof::TiltV => self.tilt_v,
            PlaneDof::Offset => self.offset_mm,
        }
    }

    /// Sets one degree of freedom.
    pub fn set_dof(&mut self, dof: PlaneDof, value: f64) {
        match dof {
            PlaneDof::TiltU => self.tilt_u = value,
            PlaneDof::TiltV => self.tilt_v = value,
            PlaneDof::Offset => self.offset_mm = value,
        }
    }

    /// The cell file entry of this plane (its current normal and offset; tilts folded in).
    pub fn to_entry(&self, id: u32) -> PlaneEntry {
        let n = self.normal();
        PlaneEntry {
            id,
            normal: [n.x, n.y, n.z],
            offset_mm: self.offset_mm,
            contact_radius_mm: Some(self.contact_radius_mm),
        }
    }

    /// The predicted block of a contact at TCP position `p` \[mm\]: the height and, with the
    /// tool axis `z` (held normal), the rim rows ([`ContactPlane::axis_rows`]); zeros without.
    pub(crate) fn block(&self, p: &Vector3<f64>, z: Option<&Vector3<f64>>) -> Vector3<f64> {
        let [a, b] = z.map_or([0.0, 0.0], |z| self.axis_rows(&self.normal(), z));
        Vector3::new(self.height_mm(p), a, b)
    }

    /// The tool-axis rows (2 and 3 of the block) predicted for tool axis `z`: `r·u·(n × z)`,
    /// `r·v·(n × z)` \[mm\].
    pub(crate) fn axis_rows(&self, n: &Vector3<f64>, z: &Vector3<f64>) -> [f64; 2] {
        let c = n.cross(z);
        [self.contact_radius_mm * self.u.dot(&c), self.contact_radius_mm * self.v.dot(&c)]
    }
}
