//! Contact planes and plane contacts ([`Target::Plane`]): the plane's geometry, the residual
//! block of a plane row and its parameter Jacobian.
//!
//! A plane is `n·x = offset` in the world frame, with `n = normalize(n₀ + tilt_u·u + tilt_v·v)`
//! (`n₀` the reference normal, `u`, `v` a fixed orthonormal basis of the plane it spans;
//! [`PlaneDof`]). A plane row's residual block has three rows \[mm\]:
//!
//! 1. `offset − n·p`: minus the TCP's height `p` above the plane;
//! 2. and 3., only when the tool axis was held normal to the plane: `−r·u·(n × z)` and
//!    `−r·v·(n × z)`, with `z` the tool-changer frame's z axis and `r` the contact-face
//!    radius: the height error at the rim of a flat face of radius `r` whose axis is tilted by
//!    `|n × z|` (either sign of `z` is normal). Without the normal they are zero, with zero
//!    Jacobian rows ([`Target::residual_rows`] counts 1).
//!
//! The Jacobian of row 1 is analytic (`nᵀ` times the position Jacobian, and the plane's own
//! columns); rows 2–3 use the analytic plane columns and central finite differences of the
//! tool axis for the other parameters (as orientation rows do, see the `orientation` module).

use nalgebra::Vector3;
use vatcal_core::{Measurement, ParamId, PlaneDof, Target};

use crate::contact_plane::ContactPlane;

use crate::model::{Model, ModelError};

impl Model {
    /// Ids of the contact planes, in order.
    pub fn plane_ids(&self) -> Vec<u32> {
        self.planes.iter().map(|p| p.0).collect()
    }

    /// Contact plane `id`.
    pub fn plane(&self, id: u32) -> Option<&ContactPlane> {
        self.planes.iter().find(|p| p.0 == id).map(|p| &p.1)
    }

    pub(crate) fn plane_mut(&mut self, id: u32) -> Option<&mut ContactPlane> {
        self.planes.iter_mut().find(|p| p.0 == id).map(|p| &mut p.1)
    }

    pub(crate) fn plane_or_err(&self, id: u32) -> Result<&ContactPlane, ModelError> {
        self.plane(id).ok_or_else(|| ModelError::UnknownPlane(id, self.plane_ids()))
    }

    /// Adds (or replaces) contact plane `id` (e.g. a plane the cell file lacks, first estimated
    /// from the data; see `vatcal_identification::estimate_planes`).
    pub fn insert_plane(&mut self, id: u32, plane: ContactPlane) {
        match self.plane_mut(id) {
            Some(p) => *p = plane,
            None => self.planes.push((id, plane)),
        }
    }

    /// The predicted block of a plane row (minus its residual; ideally 0) \[mm\] (module docs).
    pub(crate) fn plane_predict(
        &self,
        m: &Measurement,
        plane: u32,
        normal: bool,
    ) -> Result<Vector3<f64>, ModelError> {
        let pl = self.plane_or_err(plane)?;
        let p = self.tcp_position_ctx(&m.q, &m.context, m.tcp)?;
        let z = if normal { Some(self.tool_axis(m)?) } else { None };
        Ok(pl.block(&p, z.as_ref()))
    }

    /// Jacobian of [`Model::plane_predict`] with respect to `params`, column-major into `out`
    /// (module docs); returns the residual.
    pub(crate) fn plane_jacobian_into(
        &self,
        m: &Measurement,
        plane: u32,
        normal: bool,
        params: &[ParamId],
        out: &mut [f64],
    ) -> Result<Vector3<f64>, ModelError> {
        let pl = *self.plane_or_err(plane)?;
        let n = pl.normal();
        // position Jacobian of the TCP (zero columns for the plane's own parameters)
        let p = self.jacobian_into(&m.q, &m.context, m.tcp, params, out)?;
        let z = if normal { Some(self.tool_axis(m)?) } else { None };
        let mut work = normal.then(|| self.clone());
        for (j, id) in params.iter().enumerate() {
            let col = Vector3::new(out[3 * j], out[3 * j + 1], out[3 * j + 2]);
            let mut block = [n.dot(&col), 0.0, 0.0];
            match *id {
                ParamId::Plane { id, dof } if id == plane => {
                    let dn = pl.normal_derivative(dof);
                    block[0] = dn.dot(&p) - if dof == PlaneDof::Offset { 1.0 } else { 0.0 };
                    if let Some(z) = &z {
                        // the rows are linear in n: their derivative is the rows of dn
                        [block[1], block[2]] = pl.axis_rows(&dn, z);
                    }
                }
                ParamId::Plane { .. } | ParamId::Tcp { .. } | ParamId::Position { .. } => {}
                _ => {
                    if let Some(w) = work.as_mut() {
                        let dz = w.tool_axis_column(m, *id)?;
                        [block[1], block[2]] = pl.axis_rows(&n, &dz);
                    }
                }
            }
            out[3 * j..3 * j + 3].copy_from_slice(&block);
        }
        Ok(-pl.block(&p, z.as_ref()))
    }

    /// Central-difference derivative of the tool axis (z of the tool-changer frame) with
    /// respect to one parameter ([`Model::central_difference`]).
    fn tool_axis_column(&mut self, m: &Measurement, id: ParamId) -> Result<Vector3<f64>, ModelError> {
        self.central_difference(id, &|model| model.tool_axis(m))
    }

    /// The tool axis (z of the tool-changer frame) in the world at a measurement's posture.
    fn tool_axis(&self, m: &Measurement) -> Result<Vector3<f64>, ModelError> {
        Ok(self.tool_rotation_ctx(&m.q, &m.context)?.column(2).into_owned())
    }
}

/// Whether a measurement is a plane row with the tool axis held normal.
pub(crate) fn plane_of(m: &Measurement) -> Option<(u32, bool)> {
    match m.target {
        Target::Plane { plane, normal } => Some((plane, normal)),
        _ => None,
    }
}
