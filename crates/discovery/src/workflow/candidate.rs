//! A candidate effect's state during a round, and its line in the report.

use vatcal_core::ParamId;
use vatcal_core::effects::EffectSpec;

use super::context::CrossValidation;
use super::report::{CandidateScore, CandidateStatus, RefitEvidence};
use crate::fit::Fit;
use crate::linear::{EffectDirections, ScoreTest};
use crate::power::Detectability;

/// Internal state of a candidate during a round.
pub(super) struct Candidate {
    pub(super) spec: EffectSpec,
    pub(super) new_params: Vec<ParamId>,
    pub(super) directions: Option<EffectDirections>,
    pub(super) score: Option<ScoreTest>,
    pub(super) status: CandidateStatus,
    pub(super) refit: Option<(RefitEvidence, Fit, CrossValidation)>,
    pub(super) detect: Option<Detectability>,
    /// ln of the candidate's weight in the round's screening (weighted Bonferroni,
    /// [`screening_weights`]): its p-value is compared with `weight · alpha_r / m`
    pub(super) ln_weight: f64,
}

impl Candidate {
    /// The screening's ln p-value divided by the candidate's weight (compared with the
    /// round's unweighted threshold).
    pub(super) fn weighted_ln_p(&self) -> Option<f64> {
        self.score.map(|s| s.ln_p_value - self.ln_weight)
    }
}

pub(super) fn candidate_score(c: Candidate) -> CandidateScore {
    CandidateScore {
        effect: c.spec.kind().name().to_string(),
        label: c.spec.label(),
        joint: c.spec.joint(),
        params: c.new_params.iter().map(|p| p.name()).collect(),
        novelty: c.directions.as_ref().map(|d| d.novelty),
        score: c.score,
        refit: c.refit.map(|r| r.0),
        detectability: c.detect,
        status: c.status,
    }
}
