//! A position tracker (a laser tracker following an SMR in a nest of the end-effector).

use nalgebra::Vector3;
use vatcal_core::Frame;

use crate::error::Result;

/// The target id of the SMR seated in the probe's trihedral nest (where the master ball sits),
/// measured at each calibration position to register the tracker to the tank frame (the
/// paper's §5). TCP ids of a cell start at 1, so 0 never names a TCP.
pub const PROBE_NEST_TARGET: u32 = 0;

/// Measures the position \[mm\] of a target: an SMR in a nest of the end-effector (identified by
/// the TCP id it stands for), or [`PROBE_NEST_TARGET`].
///
/// A driver reports the tracker's readings in the frame it measures in: the tracker's own
/// frame for a real instrument, unless its software is registered already. [`RegisteredTracker`]
/// wraps a tracker with the registration `tank ← tracker` (the registration step of the
/// validation campaign computes it) so that campaign code gets world (tank) positions.
///
/// # Implementation
/// A target that cannot be seen (line of sight lost, beam broken, unknown target) is
/// [`crate::ErrorKind::OutOfRange`]; calls use the driver's I/O timeout.
pub trait PositionTracker: Send {
    /// Position of `target` \[mm\].
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>>;

    /// Position of `target` \[mm\], where the caller expects it at `nominal_mm` (in the frame of
    /// the readings; `None`: unknown). A real tracker points its beam there to find the SMR;
    /// the default ignores the hint.
    fn measure_near_mm(&mut self, target: u32, nominal_mm: Option<&Vector3<f64>>) -> Result<Vector3<f64>> {
        let _ = nominal_mm;
        self.measure_mm(target)
    }
}

impl<T: PositionTracker + ?Sized> PositionTracker for &mut T {
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>> {
        (**self).measure_mm(target)
    }

    fn measure_near_mm(&mut self, target: u32, nominal_mm: Option<&Vector3<f64>>) -> Result<Vector3<f64>> {
        (**self).measure_near_mm(target, nominal_mm)
    }
}

impl<T: PositionTracker + ?Sized> PositionTracker for Box<T> {
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>> {
        (**self).measure_mm(target)
    }

    fn measure_near_mm(&mut self, target: u32, nominal_mm: Option<&Vector3<f64>>) -> Result<Vector3<f64>> {
        (**self).measure_near_mm(target, nominal_mm)
    }
}

/// A tracker whose readings are carried into the tank (world) frame by a registration
/// `tank ← tracker`: every reading `p` is reported as `R p + t`, and a nominal hint given in
/// the tank frame is carried back into the tracker's frame before it reaches the driver.
#[derive(Debug)]
pub struct RegisteredTracker<T> {
    inner: T,
    tank_from_tracker: Frame,
}

impl<T: PositionTracker> RegisteredTracker<T> {
    /// `inner`'s readings mapped by `tank_from_tracker`.
    pub fn new(inner: T, tank_from_tracker: Frame) -> Self {
        Self { inner, tank_from_tracker }
    }

    /// The registration `tank ← tracker`.
    pub fn registration(&self) -> &Frame {
        &self.tank_from_tracker
    }

    /// The wrapped tracker (readings in its own frame).
    pub fn inner_mut(&mut self) -> &mut T {
        &mut self.inner
    }

    /// Hands the wrapped tracker back.
    pub fn into_inner(self) -> T {
        self.inner
    }
}

impl<T: PositionTracker> PositionTracker for RegisteredTracker<T> {
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>> {
        self.measure_near_mm(target, None)
    }

    fn measure_near_mm(&mut self, target: u32, nominal_mm: Option<&Vector3<f64>>) -> Result<Vector3<f64>> {
        let hint = nominal_mm.map(|n| self.tank_from_tracker.inverse().transform_point(n));
        let p = self.inner.measure_near_mm(target, hint.as_ref())?;
        Ok(self.tank_from_tracker.transform_point(&p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    /// Reports a fixed point in its own frame, and remembers the last hint.
    struct Fixed {
        at: Vector3<f64>,
        hint: Option<Vector3<f64>>,
    }

    impl PositionTracker for Fixed {
        fn measure_mm(&mut self, _target: u32) -> Result<Vector3<f64>> {
            Ok(self.at)
        }

        fn measure_near_mm(
            &mut self,
            target: u32,
            nominal_mm: Option<&Vector3<f64>>,
        ) -> Result<Vector3<f64>> {
            self.hint = nominal_mm.copied();
            self.measure_mm(target)
        }
    }

    #[test]
    fn registration_maps_readings_to_the_tank_and_hints_back() {
        let frame = Frame {
            r: *Rotation3::from_euler_angles(0.1, -0.2, 0.7).matrix(),
            p: Vector3::new(-1500.0, 200.0, 30.0),
        };
        let in_tank = Vector3::new(100.0, 50.0, -20.0);
        let in_tracker = frame.inverse().transform_point(&in_tank);
        let mut t = RegisteredTracker::new(Fixed { at: in_tracker, hint: None }, frame);
        let got = t.measure_near_mm(2, Some(&in_tank)).expect("reads");
        assert!((got - in_tank).norm() < 1e-9, "{got}");
        let hint = t.inner_mut().hint.expect("hint passed on");
        assert!((hint - in_tracker).norm() < 1e-9, "the hint is carried into the tracker frame");
        // the boxed trait object forwards the hint too
        let mut boxed: Box<dyn PositionTracker> = Box::new(t);
        assert!((boxed.measure_near_mm(1, None).expect("reads") - in_tank).norm() < 1e-9);
    }
}
