//! The robot arm (a Meca500, a UR5e, or any arm of 1..=12 joints with a joint and a Cartesian
//! interface), its joint values, and how a cell's joint vector splits into an external guide and
//! the arm ([`JointLayout`]).

use std::fmt;
use std::ops::{Index, IndexMut};
use std::time::Duration;

use nalgebra::Vector3;
use vatcal_core::{JointKind, JointVector, JointVectorError, MAX_JOINTS, deg_to_rad, rad_to_deg};

use crate::error::{Error, ErrorKind, Result};

/// The joints of a robot arm (1..=[`MAX_JOINTS`] values) in **internal units**: radians for
/// revolute joints (mm for a prismatic joint of the arm itself). `Copy`, no heap: a fixed
/// capacity and a length, like [`JointVector`]. Degrees exist only inside device protocols;
/// convert with [`ArmJoints::from_deg`] / [`ArmJoints::to_deg`] there.
///
/// On the canonical Meca500-on-guide cell these are J1..J6 = cell joints q2..q7; in general
/// [`JointLayout`] maps them onto the cell's joint vector.
#[derive(Clone, Copy, PartialEq)]
pub struct ArmJoints(JointVector);

impl Default for ArmJoints {
    /// Six zeros (a six-axis arm); use [`ArmJoints::zeros`] for other arms.
    fn default() -> Self {
        Self::zeros(6)
    }
}

impl fmt::Debug for ArmJoints {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("ArmJoints").field(&self.as_slice()).finish()
    }
}

impl ArmJoints {
    /// From `N` values \[rad\] (`N` in 1..=[`MAX_JOINTS`], checked at compile time).
    pub fn new<const N: usize>(rad: [f64; N]) -> Self {
        Self(JointVector::new(rad))
    }

    /// `n` zeros (`n` clamped to 1..=[`MAX_JOINTS`]).
    pub fn zeros(n: usize) -> Self {
        Self(JointVector::zeros(n))
    }

    /// From a slice of values \[rad\].
    ///
    /// # Errors
    /// The slice is empty or longer than [`MAX_JOINTS`].
    pub fn from_slice(rad: &[f64]) -> std::result::Result<Self, JointVectorError> {
        JointVector::from_slice(rad).map(Self)
    }

    /// From degrees (as a robot controller reports them).
    ///
    /// # Errors
    /// The slice is empty or longer than [`MAX_JOINTS`].
    pub fn from_deg(deg: &[f64]) -> std::result::Result<Self, JointVectorError> {
        let mut a = Self::from_slice(deg)?;
        for v in a.as_mut_slice() {
            *v = deg_to_rad(*v);
        }
        Ok(a)
    }

    /// From `N` values in degrees (`N` checked at compile time, like [`ArmJoints::new`]).
    pub fn from_deg_array<const N: usize>(deg: [f64; N]) -> Self {
        Self::new(deg.map(deg_to_rad))
    }

    /// In degrees, one value per joint.
    pub fn to_deg(&self) -> Vec<f64> {
        self.as_slice().iter().map(|v| rad_to_deg(*v)).collect()
    }

    /// Number of joints.
    #[allow(clippy::len_without_is_empty)] // never empty
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// The values \[rad\].
    pub fn as_slice(&self) -> &[f64] {
        self.0.as_slice()
    }

    /// The values, mutable \[rad\].
    pub fn as_mut_slice(&mut self) -> &mut [f64] {
        self.0.as_mut_slice()
    }

    /// The values as a [`JointVector`] of the arm's joints (not the cell's: see
    /// [`JointLayout::join`]).
    pub fn values(&self) -> JointVector {
        self.0
    }

    /// From the arm's joint values (see [`ArmJoints::values`]).
    pub fn from_values(values: JointVector) -> Self {
        Self(values)
    }

    /// Largest absolute joint difference \[rad\] (over the joints both have).
    pub fn max_abs_diff(&self, other: &ArmJoints) -> f64 {
        self.as_slice().iter().zip(other.as_slice()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
    }
}

impl Index<usize> for ArmJoints {
    type Output = f64;
    /// Joint `k` (0-based: J1 is `[0]`).
    fn index(&self, k: usize) -> &f64 {
        &self.as_slice()[k]
    }
}

impl IndexMut<usize> for ArmJoints {
    fn index_mut(&mut self, k: usize) -> &mut f64 {
        &mut self.as_mut_slice()[k]
    }
}

/// How the joint vector of a cell (its model's joints 1..=N) splits into an optional external
/// **guide** (a [`crate::LinearAxis`]) and the **arm** (a [`RobotArm`]).
///
/// The guide is joint 1 when that joint is prismatic and followed by at least one more joint
/// (the arm); every other joint belongs to the arm, in order. Derived from the model's joint
/// kinds ([`JointLayout::of`], e.g. `JointLayout::of(model.joint_kinds())`), used wherever a
/// campaign or a simulator splits or joins joint vectors.
///
/// ```
/// use vatcal_core::{JointKind, JointVector};
/// use vatcal_hardware_traits::{ArmJoints, JointLayout};
///
/// let canonical = JointLayout::of(&[JointKind::Prismatic, JointKind::Revolute, JointKind::Revolute,
///     JointKind::Revolute, JointKind::Revolute, JointKind::Revolute, JointKind::Revolute]);
/// assert_eq!(canonical, JointLayout::MECA500_ON_GUIDE);
/// let ur5e = JointLayout::of(&[JointKind::Revolute; 6]);
/// assert_eq!((ur5e.has_guide(), ur5e.arm_joint_count()), (false, 6));
/// let q = ur5e.join(None, &ArmJoints::new([0.1, 0.2, 0.3, 0.4, 0.5, 0.6]))?;
/// assert_eq!(q, JointVector::new([0.1, 0.2, 0.3, 0.4, 0.5, 0.6]));
/// assert_eq!(ur5e.cell_joint(0), 1);
/// # Ok::<(), vatcal_hardware_traits::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct JointLayout {
    joints: u8,
    guide: bool,
}

impl JointLayout {
    /// The canonical cell: the guide (q1) and a six-axis arm (q2..q7).
    pub const MECA500_ON_GUIDE: JointLayout = JointLayout { joints: 7, guide: true };

    /// The layout of a chain with joints `kinds` (1..=[`MAX_JOINTS`]; a longer list is cut).
    pub fn of(kinds: &[JointKind]) -> Self {
        let n = kinds.len().clamp(1, MAX_JOINTS);
        let guide = n >= 2 && kinds.first() == Some(&JointKind::Prismatic);
        Self { joints: n as u8, guide }
    }

    /// Number of joints N of the cell.
    pub fn joint_count(&self) -> usize {
        usize::from(self.joints)
    }

    /// True when the cell has an external guide (joint 1).
    pub fn has_guide(&self) -> bool {
        self.guide
    }

    /// The guide's cell joint (1-based), if any.
    pub fn guide_joint(&self) -> Option<usize> {
        self.guide.then_some(1)
    }

    /// Number of arm joints.
    pub fn arm_joint_count(&self) -> usize {
        self.joint_count() - usize::from(self.guide)
    }

    /// The cell joint (1-based) of arm joint `k` (0-based: J1 is `k = 0`).
    pub fn cell_joint(&self, k: usize) -> usize {
        k + 1 + usize::from(self.guide)
    }

    /// The cell joints (1-based) of the arm's joints, in order.
    pub fn arm_cell_joints(&self) -> std::ops::RangeInclusive<usize> {
        self.cell_joint(0)..=self.joint_count()
    }

    /// The arm's part of a cell joint vector (joints missing from a shorter vector read as 0).
    pub fn arm(&self, q: &JointVector) -> ArmJoints {
        let mut a = ArmJoints::zeros(self.arm_joint_count());
        for (k, v) in a.as_mut_slice().iter_mut().enumerate() {
            *v = q.as_slice().get(self.cell_joint(k) - 1).copied().unwrap_or(0.0);
        }
        a
    }

    /// The guide's value in a cell joint vector \[mm\] (`None` without a guide).
    pub fn guide_mm(&self, q: &JointVector) -> Option<f64> {
        if self.guide { q.as_slice().first().copied() } else { None }
    }

    /// The cell joint vector of the guide at `guide_mm` and the arm at `arm`.
    ///
    /// # Errors
    /// [`ErrorKind::OutOfRange`] when `arm` does not have [`JointLayout::arm_joint_count`]
    /// values, or a guide position is given without a guide (or missing with one).
    pub fn join(&self, guide_mm: Option<f64>, arm: &ArmJoints) -> Result<JointVector> {
        self.check_arm(arm)?;
        let mut q = JointVector::zeros(self.joint_count());
        match (self.guide, guide_mm) {
            (true, Some(g)) => q[0] = g,
            (false, None) => {}
            (true, None) => {
                return Err(Error::new(
                    ErrorKind::OutOfRange,
                    "guide",
                    "the cell has a guide but none was read",
                ));
            }
            (false, Some(_)) => {
                return Err(Error::new(
                    ErrorKind::OutOfRange,
                    "guide",
                    "a guide position was given but the cell has no guide",
                ));
            }
        }
        for (k, v) in arm.as_slice().iter().enumerate() {
            q[self.cell_joint(k) - 1] = *v;
        }
        Ok(q)
    }

    /// `Ok` when `arm` has one value per arm joint of this layout.
    ///
    /// # Errors
    /// [`ErrorKind::OutOfRange`] naming both counts.
    pub fn check_arm(&self, arm: &ArmJoints) -> Result<()> {
        self.check_arm_count(arm.len())
    }

    /// `Ok` when an arm with `n` joints fits this layout.
    ///
    /// # Errors
    /// [`ErrorKind::OutOfRange`] naming both counts.
    pub fn check_arm_count(&self, n: usize) -> Result<()> {
        if n == self.arm_joint_count() {
            Ok(())
        } else {
            Err(Error::new(
                ErrorKind::OutOfRange,
                "arm",
                format!(
                    "the arm has {n} joints but the cell's model has {} arm joints ({} joints{})",
                    self.arm_joint_count(),
                    self.joint_count(),
                    if self.guide { ", the first one the guide" } else { ", no guide" }
                ),
            ))
        }
    }

    /// Motion directions per cell joint (index `i - 1` = joint i, the guide and unused entries
    /// 0) from one direction per arm joint: a measurement's `dir` context.
    pub fn cell_dirs(&self, arm_dirs: &[i8]) -> [i8; MAX_JOINTS] {
        let mut d = [0; MAX_JOINTS];
        for (k, v) in arm_dirs.iter().enumerate().take(self.arm_joint_count()) {
            d[self.cell_joint(k) - 1] = *v;
        }
        d
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

/// A robot arm with [`RobotArm::joint_count`] joints (a Meca500: six revolute joints).
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
    /// Number of joints of the arm: every [`ArmJoints`] it reports or accepts has this many
    /// values (a Meca500: 6).
    fn joint_count(&self) -> usize;

    /// Powers the motors and homes the arm if needed; blocks until done or `timeout`.
    fn activate_and_home(&mut self, timeout: Duration) -> Result<()>;

    /// Controller state.
    fn status(&mut self) -> Result<ArmStatus>;

    /// Current joint positions \[rad\].
    fn joints(&mut self) -> Result<ArmJoints>;

    /// Starts a joint-space move to `target` \[rad\].
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
            fn joint_count(&self) -> usize {
                (**self).joint_count()
            }
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

    use vatcal_core::MECA500_ON_GUIDE_KINDS as CANONICAL;

    #[test]
    fn joint_vector_round_trip() {
        let l = JointLayout::of(&CANONICAL);
        assert_eq!(l, JointLayout::MECA500_ON_GUIDE);
        let q = JointVector::from_mm_deg(120.0, [10.0, -20.0, 30.0, -40.0, 50.0, -60.0]);
        let a = l.arm(&q);
        assert_eq!(a.len(), 6);
        assert_eq!(l.guide_mm(&q), Some(120.0));
        assert_eq!(l.join(Some(120.0), &a).expect("join"), q);
        let d = a.to_deg();
        assert!((d[3] + 40.0).abs() < 1e-12);
        assert!(ArmJoints::from_deg(&d).expect("deg").max_abs_diff(&a) < 1e-15);
        assert_eq!(
            l.cell_dirs(&[1, -1, 0, 1, 1, -1]),
            vatcal_core::measurement::dirs_from_meca500_arm([1, -1, 0, 1, 1, -1])
        );
    }

    #[test]
    fn layouts_of_other_chains() {
        // a UR5e-class arm: no guide, all six joints are the arm's
        let ur = JointLayout::of(&[JointKind::Revolute; 6]);
        assert!(!ur.has_guide() && ur.guide_joint().is_none());
        assert_eq!(ur.arm_cell_joints(), 1..=6);
        let q = JointVector::new([0.1, 0.2, 0.3, 0.4, 0.5, 0.6]);
        assert_eq!(ur.arm(&q).as_slice(), q.as_slice());
        assert_eq!(ur.guide_mm(&q), None);
        assert_eq!(ur.cell_dirs(&[1, 1, -1, 0, 0, 1])[..7], [1, 1, -1, 0, 0, 1, 0]);
        // a prismatic joint alone is the arm, not a guide; a prismatic joint later is an arm joint
        assert!(!JointLayout::of(&[JointKind::Prismatic]).has_guide());
        let scara = JointLayout::of(&[JointKind::Revolute, JointKind::Revolute, JointKind::Prismatic]);
        assert_eq!((scara.has_guide(), scara.arm_joint_count()), (false, 3));
        // a 7-axis arm on a guide: 8 joints
        let mut kinds = vec![JointKind::Prismatic];
        kinds.extend([JointKind::Revolute; 7]);
        let l = JointLayout::of(&kinds);
        assert_eq!((l.joint_count(), l.arm_joint_count(), l.cell_joint(6)), (8, 7, 8));
    }

    #[test]
    fn mismatched_joint_counts_are_errors() {
        let ur = JointLayout::of(&[JointKind::Revolute; 6]);
        let e = ur.join(None, &ArmJoints::zeros(7)).expect_err("7 for 6");
        assert_eq!(e.kind(), ErrorKind::OutOfRange);
        assert!(e.to_string().contains("7 joints") && e.to_string().contains("6 arm joints"), "{e}");
        assert!(ur.join(Some(1.0), &ArmJoints::zeros(6)).is_err(), "a guide value without a guide");
        assert!(JointLayout::MECA500_ON_GUIDE.join(None, &ArmJoints::zeros(6)).is_err(), "guide missing");
        assert!(ArmJoints::from_deg(&[]).is_err());
        assert!(ArmJoints::from_slice(&[0.0; 13]).is_err());
    }
}
