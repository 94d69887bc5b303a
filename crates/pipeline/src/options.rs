//! What a run is asked to do: its seed, nominal cell, sizes and campaign settings
//! ([`RunOptions`]), the labels of the models it compares, and the planning options every
//! planned campaign starts from ([`plan_options`]).

use vatcal_campaign::CampaignConfig;
use vatcal_core::{CellFile, ParamSet};
use vatcal_planning::candidates::CandidateOptions;
use vatcal_planning::plan::PlanOptions;

use crate::PipelineError;

/// Labels of the two models compared by the validation.
pub const NOMINAL: &str = "nominal";
/// Label of the calibrated model in the validation.
pub const CALIBRATED: &str = "calibrated";
/// Label of the discovered model in the validation.
pub const DISCOVERED: &str = "discovered";
/// Label of the model fitted with the true effect structure (the floor) in the validation.
pub const TRUE_STRUCTURE: &str = "true-structure";

/// Sizes of a run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunSizes {
    /// random tool orientations per TCP × calibration position (paper: 500)
    pub orientations: usize,
    /// guide positions of the candidates (paper: 10)
    pub guide_steps: usize,
    /// measurements selected by Detmax (paper: 40)
    pub count: usize,
    /// random validation poses (paper: 573)
    pub random_poses: usize,
    /// slices of the printing path (paper: 300)
    pub slices: usize,
}

impl RunSizes {
    /// Checks every size; errors name the option.
    ///
    /// # Errors
    /// A size below its minimum.
    pub fn check(&self) -> Result<(), PipelineError> {
        let at_least = |option: &str, value: usize, min: usize| {
            if value < min {
                return Err(PipelineError::Option {
                    option: option.into(),
                    reason: format!("must be at least {min}, got {value}"),
                });
            }
            Ok(())
        };
        at_least("orientations", self.orientations, 1)?;
        at_least("guide_steps", self.guide_steps, 1)?;
        at_least("count", self.count, 1)?;
        at_least("random_poses", self.random_poses, 1)?;
        at_least("slices", self.slices, 2)
    }

    /// The small sizes of a quick look (`--quick`): 20 orientations, 3 guide steps, 40
    /// measurements, 200 random validation poses; the slices are kept.
    pub fn quick(self) -> Self {
        Self { orientations: 20, guide_steps: 3, count: 40, random_poses: 200, ..self }
    }
}

impl Default for RunSizes {
    /// The paper's sizes: 500 orientations, 10 guide steps, 40 measurements, 573 random
    /// validation poses, 300 slices.
    fn default() -> Self {
        Self { orientations: 500, guide_steps: 10, count: 40, random_poses: 573, slices: 300 }
    }
}

/// Options of a whole run ([`crate::run`]).
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// master seed: planning and validation poses
    pub seed: u64,
    /// the nominal cell (what the robot controller believes)
    pub nominal: CellFile,
    /// sizes of every stage
    pub sizes: RunSizes,
    /// settings of the measurement and validation campaigns
    pub campaign: CampaignConfig,
}

/// The planning options of a run.
pub fn plan_options(opts: &RunOptions) -> PlanOptions {
    PlanOptions {
        candidates: CandidateOptions {
            orientations: opts.sizes.orientations,
            guide_steps: opts.sizes.guide_steps,
            progress: false,
            ..CandidateOptions::default()
        },
        count: opts.sizes.count,
        // empty: the chain's default set (the paper's 34 on the canonical cell)
        params: ParamSet(Vec::new()),
        motion: opts.nominal.motion_limits(),
        seed: opts.seed,
        ..PlanOptions::default()
    }
}
