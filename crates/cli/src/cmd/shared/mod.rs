//! Helpers the commands share (not through each other): the real cell of `vatcal campaign`
//! and `vatcal calibrate`, the progress bars of every command that runs pipeline stages, and
//! the discovery budget option of `vatcal demo` and `vatcal calibrate`.

pub mod budget;
pub mod cell;
pub mod progress;
