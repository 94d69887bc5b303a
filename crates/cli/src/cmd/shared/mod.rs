//! Helpers the commands share (not through each other): the real cell of `vatcal campaign`
//! and `vatcal calibrate`, and the progress bars of every command that runs pipeline stages.

pub mod cell;
pub mod progress;
