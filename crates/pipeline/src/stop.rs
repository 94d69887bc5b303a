//! Stopping a campaign from outside (Ctrl-C): a shared [`StopFlag`] and wrappers that make the
//! arm and the guide honour it.
//!
//! A wrapped device refuses new motion once the flag is raised, and waits for the end of a
//! motion in short slices so that a raised flag stops the device within about
//! [`WAIT_SLICE`] (the device's own `stop` is sent, then the call fails with
//! [`ErrorKind::Cancelled`]). The campaign then returns its error with the journal holding
//! every completed step; the caller stops the other device too and the run can be resumed.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use nalgebra::Vector3;
use vatcal_hardware_traits::{
    ArmJoints, ArmStatus, Error, ErrorKind, LinearAxis, LinearFrame, MotionOptions, Result, RobotArm,
};

/// How long one slice of a wait lasts before the flag is checked again.
pub const WAIT_SLICE: Duration = Duration::from_millis(200);

/// A flag raised once to stop (e.g. by a Ctrl-C handler); cheap to clone and share.
#[derive(Debug, Clone, Default)]
pub struct StopFlag(Arc<AtomicBool>);

impl StopFlag {
    /// A lowered flag.
    pub fn new() -> Self {
        Self::default()
    }

    /// Raises the flag.
    pub fn raise(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// True once raised.
    pub fn is_raised(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }

    fn check(&self, device: &str) -> Result<()> {
        if self.is_raised() {
            Err(Error::new(ErrorKind::Cancelled, device, "stopped by the operator (Ctrl-C)"))
        } else {
            Ok(())
        }
    }
}

/// Waits for the end of a motion in slices of [`WAIT_SLICE`], checking the flag between
/// slices; a raised flag sends `stop` and fails with [`ErrorKind::Cancelled`].
fn sliced_wait(
    flag: &StopFlag,
    device: &str,
    timeout: Duration,
    mut wait: impl FnMut(Duration) -> Result<()>,
    mut stop: impl FnMut() -> Result<()>,
) -> Result<()> {
    let start = Instant::now();
    loop {
        if flag.is_raised() {
            // best effort: the Cancelled error is what the caller must see
            let _ = stop();
            return flag.check(device);
        }
        let left = timeout.saturating_sub(start.elapsed());
        match wait(left.min(WAIT_SLICE)) {
            // a slice ended with the motion still running: wait again
            Err(e) if e.is_timeout() && left > WAIT_SLICE => continue,
            // the whole timeout: the drivers leave a still-moving device alone, stop it here
            Err(e) if e.is_timeout() => {
                let _ = stop();
                return Err(e);
            }
            other => return other,
        }
    }
}

/// A robot arm that honours a [`StopFlag`].
#[derive(Debug)]
pub struct StoppableArm<A> {
    inner: A,
    flag: StopFlag,
}

impl<A: RobotArm> StoppableArm<A> {
    /// Wraps `inner`.
    pub fn new(inner: A, flag: StopFlag) -> Self {
        Self { inner, flag }
    }

    /// The wrapped arm.
    pub fn inner_mut(&mut self) -> &mut A {
        &mut self.inner
    }
}

impl<A: RobotArm> RobotArm for StoppableArm<A> {
    fn joint_count(&self) -> usize {
        self.inner.joint_count()
    }
    fn activate_and_home(&mut self, timeout: Duration) -> Result<()> {
        self.flag.check("arm")?;
        self.inner.activate_and_home(timeout)
    }
    fn status(&mut self) -> Result<ArmStatus> {
        self.inner.status()
    }
    fn joints(&mut self) -> Result<ArmJoints> {
        self.inner.joints()
    }
    fn move_joints(&mut self, target: &ArmJoints, options: &MotionOptions) -> Result<()> {
        self.flag.check("arm")?;
        self.inner.move_joints(target, options)
    }
    fn move_linear_relative(
        &mut self,
        d: &Vector3<f64>,
        frame: LinearFrame,
        options: &MotionOptions,
    ) -> Result<()> {
        self.flag.check("arm")?;
        self.inner.move_linear_relative(d, frame, options)
    }
    fn wait_idle(&mut self, timeout: Duration) -> Result<()> {
        let inner = std::cell::RefCell::new(&mut self.inner);
        sliced_wait(
            &self.flag,
            "arm",
            timeout,
            |t| inner.borrow_mut().wait_idle(t),
            || inner.borrow_mut().stop(),
        )
    }
    fn stop(&mut self) -> Result<()> {
        self.inner.stop()
    }
    fn reset_error(&mut self) -> Result<()> {
        self.inner.reset_error()
    }
}

/// A linear axis that honours a [`StopFlag`].
#[derive(Debug)]
pub struct StoppableAxis<G> {
    inner: G,
    flag: StopFlag,
}

impl<G: LinearAxis> StoppableAxis<G> {
    /// Wraps `inner`.
    pub fn new(inner: G, flag: StopFlag) -> Self {
        Self { inner, flag }
    }

    /// The wrapped axis.
    pub fn inner_mut(&mut self) -> &mut G {
        &mut self.inner
    }
}

impl<G: LinearAxis> LinearAxis for StoppableAxis<G> {
    fn home(&mut self, timeout: Duration) -> Result<()> {
        self.flag.check("guide")?;
        self.inner.home(timeout)
    }
    fn is_homed(&mut self) -> Result<bool> {
        self.inner.is_homed()
    }
    fn position_mm(&mut self) -> Result<f64> {
        self.inner.position_mm()
    }
    fn move_absolute_mm(&mut self, target_mm: f64, options: &MotionOptions) -> Result<()> {
        self.flag.check("guide")?;
        self.inner.move_absolute_mm(target_mm, options)
    }
    fn wait_idle(&mut self, timeout: Duration) -> Result<()> {
        let inner = std::cell::RefCell::new(&mut self.inner);
        sliced_wait(
            &self.flag,
            "guide",
            timeout,
            |t| inner.borrow_mut().wait_idle(t),
            || inner.borrow_mut().stop(),
        )
    }
    fn stop(&mut self) -> Result<()> {
        self.inner.stop()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    #[test]
    fn a_raised_flag_stops_a_wait_and_cancels() {
        let flag = StopFlag::new();
        let (waits, stops) = (Cell::new(0), Cell::new(0));
        let f2 = flag.clone();
        let r = sliced_wait(
            &flag,
            "guide",
            Duration::from_secs(60),
            |_| {
                waits.set(waits.get() + 1);
                if waits.get() == 3 {
                    f2.raise();
                }
                Err(Error::timeout("guide", "idle", WAIT_SLICE))
            },
            || {
                stops.set(stops.get() + 1);
                Ok(())
            },
        );
        let e = r.expect_err("cancelled");
        assert_eq!(e.kind(), ErrorKind::Cancelled);
        assert_eq!((waits.get(), stops.get()), (3, 1));
        assert!(e.to_string().starts_with("guide: cancelled"), "{e}");
    }

    #[test]
    fn a_wait_that_outlasts_its_timeout_fails_with_the_device_timeout() {
        let flag = StopFlag::new();
        let stops = Cell::new(0);
        let r = sliced_wait(
            &flag,
            "arm",
            Duration::from_millis(1),
            |t| Err(Error::timeout("arm", "idle", t)),
            || {
                stops.set(stops.get() + 1);
                Ok(())
            },
        );
        assert!(r.expect_err("timeout").is_timeout());
        // the drivers leave a device that is still moving alone: the wrapper stops it once
        assert_eq!(stops.get(), 1);
        let r = sliced_wait(&flag, "arm", Duration::from_secs(1), |_| Ok(()), || Ok(()));
        assert!(r.is_ok());
    }
}
