//! One linear gauge (a Sylvac S_Dial WORK Nano Smart digital indicator).

use crate::error::Result;

/// A digital length gauge reading in **mm**.
///
/// # Implementation
/// * `read_mm` returns a fresh reading (not a cached notification older than the last motion)
///   or fails after the driver's I/O timeout.
/// * A plunger beyond the measuring range is [`crate::ErrorKind::OutOfRange`], never a clamped
///   value.
/// * `preset_mm(v)` makes the current plunger position read `v` from now on.
pub trait Gauge: Send {
    /// Current reading \[mm\].
    fn read_mm(&mut self) -> Result<f64>;

    /// Sets the current position to read `value_mm`.
    fn preset_mm(&mut self, value_mm: f64) -> Result<()>;

    /// Sets the current position to read zero.
    fn zero(&mut self) -> Result<()> {
        self.preset_mm(0.0)
    }
}

impl<T: Gauge + ?Sized> Gauge for &mut T {
    fn read_mm(&mut self) -> Result<f64> {
        (**self).read_mm()
    }
    fn preset_mm(&mut self, value_mm: f64) -> Result<()> {
        (**self).preset_mm(value_mm)
    }
    fn zero(&mut self) -> Result<()> {
        (**self).zero()
    }
}

impl<T: Gauge + ?Sized> Gauge for Box<T> {
    fn read_mm(&mut self) -> Result<f64> {
        (**self).read_mm()
    }
    fn preset_mm(&mut self, value_mm: f64) -> Result<()> {
        (**self).preset_mm(value_mm)
    }
    fn zero(&mut self) -> Result<()> {
        (**self).zero()
    }
}
