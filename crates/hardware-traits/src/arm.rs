//! The robot arm (a Meca500, or any 6-axis arm with a joint and a Cartesian interface).

use std::time::Duration;

use nalgebra::Vector3;
use vatcal_core::{JointVector, deg_to_rad, rad_to_deg};

use crate::error::Result;

/// The six arm joints J1..J6 in **radians** (cell joints q2..q7). Degrees exist only inside
/// device protocols; convert with [`ArmJoints::from_deg`] / [`ArmJoints::to_deg`] there.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ArmJoints(pub [f64; 6]);

impl ArmJoints {
    /// From degrees (as a robot controller reports them).
    pub fn from_deg(deg: [f64; 6]) -> Self {
        Self(deg.map(deg_to_rad))
    }

    /// In degrees.
    pub fn to_deg(&self) -> [f64; 6] {
        self.0.map(rad_to_deg)
    }

    /// The arm part (q2..q7) of a joint vector of the 7-joint Meca500-on-guide cell (joints
    /// missing from a shorter vector read as 0).
    pub fn from_joint_vector(q: &JointVector) -> Self {
        Self(std::array::from_fn(|k| q.as_slice().get(k + 1).copied().unwrap_or(0.0)))
    }

    /// The cell joint vector with the guide at `guide_mm`.
    pub fn with_guide(&self, guide_mm: f64) -> JointVector {
        let mut q = [0.0; 7];
        q[0] = guide_mm;
        q[1..].copy_from_slice(&self.0);
        JointVector::new(q)
    }

    /// Largest absolute joint difference [rad].
    pub fn max_abs_diff(&self, other: &ArmJoints) -> f64 {
        self.0.iter().zip(other.0.iter()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
    }
}

/// Speed and timeout of one motion command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionOptions {
    /// fraction (0, 1] of the device's maximum speed
    pub speed_fraction: f64,
    /// how long a wait on this motion may take before it fails with
    /// [`crate::ErrorKind::Timeout`]
    pub timeout: Duration,
}

impl Default for MotionOptions {
    /// 25 % speed, 120 s timeout.
    fn default() -> Self {
        Self { speed_fraction: 0.25, timeout: Duration::from_secs(120) }
    }
}

/// Frame in which a relative linear move is expressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LinearFrame {
    /// The axes of the controller's world reference frame (Meca500: WRF, by default its base
    /// frame). Each driver documents where this frame is.
    World,
    /// The axes of the flange frame (the cell's MDH frame 7, the tool-changer frame): the
    /// displacement is expressed in the current tool orientation (Meca500: `MoveLinRelTrf` with
    /// the TRF's orientation equal to the flange's).
    Tool,
}

/// What the controller reports about itself.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ArmStatus {
    /// motors powered
    pub activated: bool,
    /// homing done
    pub homed: bool,
    /// a motion is in progress or queued
    pub moving: bool,
    /// the controller is in error mode: `(code, message)`
    pub error: Option<(i32, String)>,
}

/// A robot arm with six revolute joints.
///
/// Blocking and object-safe (`Box<dyn RobotArm>` works). Motion commands **start** a motion and
/// return once the controller accepted it; [`RobotArm::wait_idle`] blocks until it finished.
/// Each call either completes, fails, or times out: no call waits forever.
///
/// # Implementation
/// * Units: joints in rad, lengths in mm (convert to the protocol's degrees inside the driver).
/// * Non-motion calls (`status`, `joints`, `stop`, `reset_error`) use the I/O timeout of the
///   driver's configuration and fail with [`crate::ErrorKind::Timeout`] when it expires.
/// * A motion issued while another one runs is either queued or refused with
///   [`crate::ErrorKind::Busy`]; callers in this workspace always wait in between.
/// * A refused or failed motion leaves the arm in error mode; report it as
///   [`crate::ErrorKind::DeviceFault`] with the controller's code, and clear it in
///   [`RobotArm::reset_error`].
/// * `joints` must return the joints the controller **targets/measures now**, fresh from the
///   device (not a stale cache): they are recorded as calibration data.
pub trait RobotArm: Send {
    /// Powers the motors and homes the arm if needed; blocks until done or `timeout`.
    fn activate_and_home(&mut self, timeout: Duration) -> Result<()>;

    /// Controller state.
    fn status(&mut self) -> Result<ArmStatus>;

    /// Current joint positions [rad].
    fn joints(&mut self) -> Result<ArmJoints>;

    /// Starts a joint-space move to `target` [rad].
    fn move_joints(&mut self, target: &ArmJoints, options: &MotionOptions) -> Result<()>;

    /// Starts a straight-line translation of the tool by `displacement_mm`, expressed in the
    /// axes of `frame`; the tool orientation does not change, so every tool point (every TCP)
    /// moves by the same vector. The controller computes the joints with **its own** kinematic
    /// model, which is exactly why the cell needs calibrating.
    fn move_linear_relative(
        &mut self,
        displacement_mm: &Vector3<f64>,
        frame: LinearFrame,
        options: &MotionOptions,
    ) -> Result<()>;

    /// Blocks until the arm stands still with an empty motion queue, or fails after `timeout`
    /// (or at once if the controller entered error mode).
    fn wait_idle(&mut self, timeout: Duration) -> Result<()>;

    /// Stops the motion as fast as possible and empties the queue.
    fn stop(&mut self) -> Result<()>;

    /// Leaves error mode (and resumes motion where the controller needs that).
    fn reset_error(&mut self) -> Result<()>;

    /// [`RobotArm::move_joints`] then [`RobotArm::wait_idle`] with `options.timeout`.
    fn move_joints_and_wait(&mut self, target: &ArmJoints, options: &MotionOptions) -> Result<()> {
        self.move_joints(target, options)?;
        self.wait_idle(options.timeout)
    }

    /// [`RobotArm::move_linear_relative`] then [`RobotArm::wait_idle`] with `options.timeout`.
    fn move_linear_relative_and_wait(
        &mut self,
        displacement_mm: &Vector3<f64>,
        frame: LinearFrame,
        options: &MotionOptions,
    ) -> Result<()> {
        self.move_linear_relative(displacement_mm, frame, options)?;
        self.wait_idle(options.timeout)
    }
}

macro_rules! forward_robot_arm {
    ($($ty:ty),*) => {$(
        impl<T: RobotArm + ?Sized> RobotArm for $ty {
            fn activate_and_home(&mut self, timeout: Duration) -> Result<()> {
                (**self).activate_and_home(timeout)
            }
            fn status(&mut self) -> Result<ArmStatus> {
                (**self).status()
            }
            fn joints(&mut self) -> Result<ArmJoints> {
                (**self).joints()
            }
            fn move_joints(&mut self, target: &ArmJoints, options: &MotionOptions) -> Result<()> {
                (**self).move_joints(target, options)
            }
            fn move_linear_relative(
                &mut self,
                displacement_mm: &Vector3<f64>,
                frame: LinearFrame,
                options: &MotionOptions,
            ) -> Result<()> {
                (**self).move_linear_relative(displacement_mm, frame, options)
            }
            fn wait_idle(&mut self, timeout: Duration) -> Result<()> {
                (**self).wait_idle(timeout)
            }
            fn stop(&mut self) -> Result<()> {
                (**self).stop()
            }
            fn reset_error(&mut self) -> Result<()> {
                (**self).reset_error()
            }
            fn move_joints_and_wait(&mut self, target: &ArmJoints, options: &MotionOptions) -> Result<()> {
                (**self).move_joints_and_wait(target, options)
            }
            fn move_linear_relative_and_wait(
                &mut self,
                displacement_mm: &Vector3<f64>,
                frame: LinearFrame,
                options: &MotionOptions,
            ) -> Result<()> {
                (**self).move_linear_relative_and_wait(displacement_mm, frame, options)
            }
        }
    )*};
}

forward_robot_arm!(&mut T, Box<T>);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joint_vector_round_trip() {
        let q = JointVector::from_mm_deg(120.0, [10.0, -20.0, 30.0, -40.0, 50.0, -60.0]);
        let a = ArmJoints::from_joint_vector(&q);
        assert_eq!(a.with_guide(120.0), q);
        let d = a.to_deg();
        assert!((d[3] + 40.0).abs() < 1e-12);
        assert!(ArmJoints::from_deg(d).max_abs_diff(&a) < 1e-15);
    }
}
