//! A position tracker (a laser tracker following an SMR in a nest of the end-effector).

use nalgebra::Vector3;

use crate::error::Result;

/// Measures the world position \[mm\] of a target (an SMR nest identified by the TCP id it
/// stands for), in the cell's world (tank) frame — the tracker driver owns the registration.
///
/// # Implementation
/// A target that cannot be seen is [`crate::ErrorKind::OutOfRange`]; calls use the driver's
/// I/O timeout.
pub trait PositionTracker: Send {
    /// World position of `target` \[mm\].
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>>;
}

impl<T: PositionTracker + ?Sized> PositionTracker for &mut T {
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>> {
        (**self).measure_mm(target)
    }
}

impl<T: PositionTracker + ?Sized> PositionTracker for Box<T> {
    fn measure_mm(&mut self, target: u32) -> Result<Vector3<f64>> {
        (**self).measure_mm(target)
    }
}
