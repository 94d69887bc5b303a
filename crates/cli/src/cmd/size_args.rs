//! The run-size options shared by `vatcal demo` and `vatcal calibrate`.

use vatcal_pipeline::RunSizes;

/// Sizes of the planned and validated run (defaults: the paper's).
#[derive(clap::Args, Debug, Clone)]
pub struct SizeArgs {
    /// Random tool orientations per TCP × calibration position for the candidates.
    #[arg(long, default_value_t = 500)]
    pub orientations: usize,
    /// Guide positions of the candidates.
    #[arg(long, default_value_t = 10)]
    pub guide_steps: usize,
    /// Measurements selected by Detmax.
    #[arg(long, default_value_t = 40)]
    pub count: usize,
    /// Random validation poses measured by the tracker.
    #[arg(long, default_value_t = 573)]
    pub random_poses: usize,
    /// Slices of the validation printing path.
    #[arg(long, default_value_t = 300)]
    pub slices: usize,
}

impl SizeArgs {
    /// The sizes as the pipeline takes them.
    pub fn run_sizes(&self) -> RunSizes {
        RunSizes {
            orientations: self.orientations,
            guide_steps: self.guide_steps,
            count: self.count,
            random_poses: self.random_poses,
            slices: self.slices,
        }
    }
}
