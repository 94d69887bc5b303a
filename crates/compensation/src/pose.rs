//! Requested poses and the Mecademic pose convention.
//!
//! A Meca500 writes a pose as `x, y, z [mm], α, β, γ [deg]` with the orientation as
//! **intrinsic (mobile) X-Y-Z Euler angles**: `R = Rx(α) · Ry(β) · Rz(γ)` (protocols.md §1.10).
//! The conversions here are those of the Meca500 simulator in `vatcal-drivers-meca500`
//! (`sim::to_xyzabc` / `sim::from_xyzabc`), reused, not re-derived: the same convention the
//! controller speaks.

use nalgebra::{Isometry3, Matrix3, Vector3};
use vatcal_core::{Frame, MeasurementContext};
use vatcal_drivers_meca500::sim::{from_xyzabc, to_xyzabc};
use vatcal_kinematics::Model;

use crate::CompensationError;

/// Rotation `Rx(α) Ry(β) Rz(γ)` of Mecademic Euler angles `[α, β, γ]` \[deg\].
pub fn euler_xyz_deg_to_rotation(abc_deg: [f64; 3]) -> Matrix3<f64> {
    meca_pose_to_frame(&[0.0, 0.0, 0.0, abc_deg[0], abc_deg[1], abc_deg[2]]).r
}

/// Mecademic Euler angles `[α, β, γ]` \[deg\] of a rotation (β in \[−90°, 90°\]; at β = ±90°
/// everything goes into γ, as the controller does).
pub fn rotation_to_euler_xyz_deg(r: &Matrix3<f64>) -> [f64; 3] {
    let p = frame_to_meca_pose(&Frame { r: *r, p: Vector3::zeros() });
    [p[3], p[4], p[5]]
}

/// A frame as a Mecademic pose `[x, y, z (mm), α, β, γ (deg)]`.
pub fn frame_to_meca_pose(f: &Frame) -> [f64; 6] {
    to_xyzabc(&f.to_isometry())
}

/// A Mecademic pose `[x, y, z (mm), α, β, γ (deg)]` as a frame.
pub fn meca_pose_to_frame(p: &[f64; 6]) -> Frame {
    let iso: Isometry3<f64> = from_xyzabc(p);
    Frame::from_isometry(&iso)
}

/// One requested pose in the world (resin-tank) frame, in file units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseRequest {
    /// TCP id whose point must reach `xyz_mm`
    pub tcp: u32,
    /// guide position \[mm\]
    pub q1_mm: f64,
    /// TCP point in the world \[mm\]
    pub xyz_mm: [f64; 3],
    /// orientation of the tool-changer frame, Mecademic intrinsic X-Y-Z Euler angles \[deg\]
    pub abc_deg: [f64; 3],
    /// per-sample context passed to the model (time, temperature, motion directions)
    pub context: MeasurementContext,
}

impl PoseRequest {
    /// The request as a world tool-changer frame under `model` (the model's own coordinates
    /// of the TCP: a calibrated model's calibrated TCP). `row` names the request in errors.
    pub fn tool_target(&self, model: &Model, row: usize) -> Result<ToolTarget, CompensationError> {
        let values = [
            ("q1", self.q1_mm),
            ("x", self.xyz_mm[0]),
            ("y", self.xyz_mm[1]),
            ("z", self.xyz_mm[2]),
            ("alpha", self.abc_deg[0]),
            ("beta", self.abc_deg[1]),
            ("gamma", self.abc_deg[2]),
        ];
        if let Some((field, value)) = values.into_iter().find(|(_, v)| !v.is_finite()) {
            return Err(CompensationError::NonFinite { row, field, value });
        }
        let tcp = model
            .tcp(self.tcp)
            .ok_or_else(|| vatcal_kinematics::ModelError::UnknownTcp(self.tcp, model.tcp_ids()))?;
        let r = euler_xyz_deg_to_rotation(self.abc_deg);
        let point = Vector3::from(self.xyz_mm);
        Ok(ToolTarget { q1_mm: self.q1_mm, tool: Frame { r, p: point - r * tcp }, context: self.context })
    }

    /// The request that asks for tool-changer frame `tool` (world) with TCP `tcp` of `model`,
    /// at guide position `q1_mm`: the inverse of [`PoseRequest::tool_target`].
    pub fn from_tool_frame(
        model: &Model,
        tcp: u32,
        q1_mm: f64,
        tool: &Frame,
        context: MeasurementContext,
    ) -> Result<Self, CompensationError> {
        let t =
            model.tcp(tcp).ok_or_else(|| vatcal_kinematics::ModelError::UnknownTcp(tcp, model.tcp_ids()))?;
        let p = tool.transform_point(&t);
        Ok(Self { tcp, q1_mm, xyz_mm: [p.x, p.y, p.z], abc_deg: rotation_to_euler_xyz_deg(&tool.r), context })
    }
}

/// A requested pose as a world frame of the tool-changer frame (internal units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolTarget {
    /// guide position \[mm\] (held fixed: the arm joints solve the pose)
    pub q1_mm: f64,
    /// requested world pose of the tool-changer frame
    pub tool: Frame,
    /// per-sample context passed to the model
    pub context: MeasurementContext,
}

impl ToolTarget {
    /// A target without context.
    pub fn new(q1_mm: f64, tool: Frame) -> Self {
        Self { q1_mm, tool, context: MeasurementContext::default() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::frame::{rot_x, rot_y, rot_z};

    #[test]
    fn euler_convention_is_intrinsic_xyz() {
        let (a, b, c) = (10.0f64, -25.0f64, 70.0f64);
        let r = euler_xyz_deg_to_rotation([a, b, c]);
        let expect = rot_x(a.to_radians()) * rot_y(b.to_radians()) * rot_z(c.to_radians());
        assert!((r - expect).abs().max() < 1e-12, "{r} vs {expect}");
        let back = rotation_to_euler_xyz_deg(&r);
        for (x, y) in back.iter().zip([a, b, c]) {
            assert!((x - y).abs() < 1e-9, "{back:?}");
        }
    }

    #[test]
    fn meca_pose_round_trip() {
        let p = [190.0, -3.5, 308.0, 12.0, 40.0, -100.0];
        let f = meca_pose_to_frame(&p);
        let q = frame_to_meca_pose(&f);
        for (x, y) in p.iter().zip(q) {
            assert!((x - y).abs() < 1e-9, "{q:?}");
        }
    }
}
