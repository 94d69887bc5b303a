//! A linear axis (the Zaber X-LRQ300AP guide that carries the arm).

use std::time::Duration;

use crate::arm::MotionOptions;
use crate::error::Result;

/// A motorised linear axis, positions in **mm** (microsteps exist only inside the driver).
///
/// Blocking and object-safe. `move_absolute_mm` starts the move; `wait_idle` blocks.
///
/// # Implementation
/// * `position_mm` returns the encoder/step position now, read from the device.
/// * A target outside the stroke is refused with [`crate::ErrorKind::OutOfRange`]; a move before
///   homing with [`crate::ErrorKind::NotHomed`].
/// * Non-motion calls use the driver's configured I/O timeout.
pub trait LinearAxis: Send {
    /// Homes the axis; blocks until done or `timeout`.
    fn home(&mut self, timeout: Duration) -> Result<()>;

    /// True when the axis knows its position (homed since power-up).
    fn is_homed(&mut self) -> Result<bool>;

    /// Current position \[mm\].
    fn position_mm(&mut self) -> Result<f64>;

    /// Starts a move to `target_mm`.
    fn move_absolute_mm(&mut self, target_mm: f64, options: &MotionOptions) -> Result<()>;

    /// Blocks until the axis is idle, or fails after `timeout`.
    fn wait_idle(&mut self, timeout: Duration) -> Result<()>;

    /// Stops at once.
    fn stop(&mut self) -> Result<()>;

    /// [`LinearAxis::move_absolute_mm`] then [`LinearAxis::wait_idle`] with `options.timeout`.
    fn move_absolute_and_wait(&mut self, target_mm: f64, options: &MotionOptions) -> Result<()> {
        self.move_absolute_mm(target_mm, options)?;
        self.wait_idle(options.timeout)
    }
}

macro_rules! forward_linear_axis {
    ($($ty:ty),*) => {$(
        impl<T: LinearAxis + ?Sized> LinearAxis for $ty {
            fn home(&mut self, timeout: Duration) -> Result<()> {
                (**self).home(timeout)
            }
            fn is_homed(&mut self) -> Result<bool> {
                (**self).is_homed()
            }
            fn position_mm(&mut self) -> Result<f64> {
                (**self).position_mm()
            }
            fn move_absolute_mm(&mut self, target_mm: f64, options: &MotionOptions) -> Result<()> {
                (**self).move_absolute_mm(target_mm, options)
            }
            fn wait_idle(&mut self, timeout: Duration) -> Result<()> {
                (**self).wait_idle(timeout)
            }
            fn stop(&mut self) -> Result<()> {
                (**self).stop()
            }
            fn move_absolute_and_wait(&mut self, target_mm: f64, options: &MotionOptions) -> Result<()> {
                (**self).move_absolute_and_wait(target_mm, options)
            }
        }
    )*};
}

forward_linear_axis!(&mut T, Box<T>);
