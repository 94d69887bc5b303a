//! Requested poses and the Mecademic pose convention.
//!
//! A Meca500 writes a pose as `x, y, z [mm], α, β, γ [deg]` with the orientation as
//! **intrinsic (mobile) X-Y-Z Euler angles**: `R = Rx(α) · Ry(β) · Rz(γ)` (protocols.md §1.10).
//! The conversions here are those of the Meca500 simulator in `vatcal-drivers-meca500`
//! (`sim::to_xyzabc` / `sim::from_xyzabc`), reused, not re-derived: the same convention the
//! controller speaks.

use nalgebra::{Isometry3, Matrix3, Vector3};
use vatcal_core::{Frame, JointVector, MeasurementContext};
use vatcal_drivers_meca500::sim::{from_xyzabc, to_xyzabc};
use vatcal_kinematics::Model;

use crate::{CompensationError, JointSplit};

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
///
/// The pose fixes six degrees of freedom; the values of the chain's other joints are part of
/// the request ([`crate::JointSplit`]: the prismatic external axes of a chain with more than six
/// joints, e.g. the canonical cell's guide `q1`; none on a six-joint arm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseRequest {
    /// TCP id whose point must reach `xyz_mm`
    pub tcp: u32,
    /// a joint vector of the chain (one entry per joint) holding the values of the joints the
    /// pose does not determine ([`crate::JointSplit::given_joints`], prismatic: mm); the other
    /// entries are not used
    pub given: JointVector,
    /// TCP point in the world \[mm\]
    pub xyz_mm: [f64; 3],
    /// orientation of the chain's last frame (flange / tool-changer frame), Mecademic
    /// intrinsic X-Y-Z Euler angles \[deg\]
    pub abc_deg: [f64; 3],
    /// per-sample context passed to the model (time, temperature, motion directions)
    pub context: MeasurementContext,
}

impl PoseRequest {
    /// A request on the canonical Meca500-on-guide cell: the guide at `q1_mm`, no context.
    pub fn on_guide(tcp: u32, q1_mm: f64, xyz_mm: [f64; 3], abc_deg: [f64; 3]) -> Self {
        let mut given = JointVector::default();
        given[0] = q1_mm;
        Self { tcp, given, xyz_mm, abc_deg, context: MeasurementContext::default() }
    }

    /// A request on a chain of `joints` joints that determines all of them (a six-joint arm),
    /// no context.
    pub fn for_arm(joints: usize, tcp: u32, xyz_mm: [f64; 3], abc_deg: [f64; 3]) -> Self {
        Self {
            tcp,
            given: JointVector::zeros(joints),
            xyz_mm,
            abc_deg,
            context: MeasurementContext::default(),
        }
    }

    /// The request as a world tool-changer frame under `model` (the model's own coordinates
    /// of the TCP: a calibrated model's calibrated TCP). `row` names the request in errors.
    ///
    /// # Errors
    /// [`CompensationError::UnsupportedChain`] for a chain compensation does not handle,
    /// [`CompensationError::Model`] for a `given` of the wrong length or an unknown TCP,
    /// [`CompensationError::NonFinite`] for a value that is not finite.
    pub fn tool_target(&self, model: &Model, row: usize) -> Result<ToolTarget, CompensationError> {
        let split = JointSplit::of(model)?;
        model.check_joint_count(&self.given)?;
        for j in split.given_joints() {
            let value = self.given.get(j);
            if !value.is_finite() {
                return Err(CompensationError::NonFinite { row, field: joint_field(j), value });
            }
        }
        let values = [
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
        Ok(ToolTarget { given: self.given, tool: Frame { r, p: point - r * tcp }, context: self.context })
    }

    /// The request that asks for tool-changer frame `tool` (world) with TCP `tcp` of `model`,
    /// with the given joints of `given`: the inverse of [`PoseRequest::tool_target`].
    ///
    /// # Errors
    /// An unknown TCP.
    pub fn from_tool_frame(
        model: &Model,
        tcp: u32,
        given: JointVector,
        tool: &Frame,
        context: MeasurementContext,
    ) -> Result<Self, CompensationError> {
        let t =
            model.tcp(tcp).ok_or_else(|| vatcal_kinematics::ModelError::UnknownTcp(tcp, model.tcp_ids()))?;
        let p = tool.transform_point(&t);
        Ok(Self { tcp, given, xyz_mm: [p.x, p.y, p.z], abc_deg: rotation_to_euler_xyz_deg(&tool.r), context })
    }
}

/// The column name `q<i>` of joint `i` (1..=12) as a static string (error fields).
pub(crate) fn joint_field(i: usize) -> &'static str {
    const NAMES: [&str; 12] = ["q1", "q2", "q3", "q4", "q5", "q6", "q7", "q8", "q9", "q10", "q11", "q12"];
    NAMES.get(i.wrapping_sub(1)).copied().unwrap_or("q")
}

/// A requested pose as a world frame of the tool-changer frame (internal units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolTarget {
    /// a joint vector of the chain holding the values of the joints the pose does not
    /// determine (held fixed; [`crate::JointSplit::given_joints`]); the other entries are not
    /// used
    pub given: JointVector,
    /// requested world pose of the tool-changer frame
    pub tool: Frame,
    /// per-sample context passed to the model
    pub context: MeasurementContext,
}

impl ToolTarget {
    /// A target on the canonical Meca500-on-guide cell (guide at `q1_mm`), without context.
    pub fn new(q1_mm: f64, tool: Frame) -> Self {
        let mut given = JointVector::default();
        given[0] = q1_mm;
        Self { given, tool, context: MeasurementContext::default() }
    }

    /// A target on any chain: `given` holds the values of the joints the pose does not
    /// determine (one entry per joint of the chain), without context.
    pub fn with_given(given: JointVector, tool: Frame) -> Self {
        Self { given, tool, context: MeasurementContext::default() }
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
