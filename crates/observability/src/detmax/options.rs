//! What a selection is asked for ([`DetmaxOptions`], [`Objective`]) and what it returns
//! ([`Selection`]), with the criterion of a design ([`log_det`], [`o1_from_log_det`]).

use super::bookkeeping::{factor, ridge_diagonal, with_ridge};
use super::candidates::Candidates;
use crate::error::ObservabilityError;
use crate::identifiability::ColumnScaling;
use crate::indices::ObservabilityIndices;

/// The objective a selection maximises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Objective {
    /// O1 — D-optimality (fast rank-3 path; scale-invariant)
    #[default]
    O1,
    /// O2 = σ_min/σ_max (exact evaluation)
    O2,
    /// O3 = σ_min (exact evaluation)
    O3,
    /// O4 = σ_min²/σ_max (exact evaluation)
    O4,
    /// O5 = 1/Σ 1/σ_i (exact evaluation)
    O5,
}

impl Objective {
    /// Parses `o1`..`o5` (case-insensitive).
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "o1" => Some(Self::O1),
            "o2" => Some(Self::O2),
            "o3" => Some(Self::O3),
            "o4" => Some(Self::O4),
            "o5" => Some(Self::O5),
            _ => None,
        }
    }

    /// The objective's value for a design with these singular values and `poses` poses.
    pub fn evaluate(self, singular_values: &[f64], parameter_count: usize, poses: usize) -> f64 {
        let i = ObservabilityIndices::from_singular_values(
            singular_values,
            parameter_count,
            poses,
            ColumnScaling::None,
        );
        match self {
            Self::O1 => i.o1,
            Self::O2 => i.o2,
            Self::O3 => i.o3,
            Self::O4 => i.o4,
            Self::O5 => i.o5,
        }
    }
}

/// How each restart starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Initialisation {
    /// `fixed` plus a random subset (greedy if that is singular)
    #[default]
    Random,
    /// greedy (Dykstra) from `fixed` — deterministic, so all restarts coincide
    Greedy,
}

/// Options of [`detmax`](fn@super::detmax).
#[derive(Debug, Clone, PartialEq)]
pub struct DetmaxOptions {
    /// design size n
    pub count: usize,
    /// number of restarts (≥ 1), run in parallel
    pub restarts: usize,
    /// master seed; restart r uses a seed derived from (seed, r)
    pub seed: u64,
    /// cap on exchange steps per restart (and on exact-objective swaps)
    pub max_exchanges: usize,
    /// maximum excursion depth (None = plain exchange)
    pub excursions: Option<usize>,
    /// candidate indices that must be in the design
    pub fixed: Vec<usize>,
    /// the objective
    pub objective: Objective,
    /// relative ridge: `R = ridge · diag(Σ_all B_kᵀB_k) / N` is added to every design's
    /// information matrix (0 = none). Needed only to select from a candidate set that cannot
    /// identify all parameters (e.g. the one-position ablation).
    pub ridge: f64,
    /// refactor `M⁻¹` and all `G_k` from scratch after this many updates
    pub refactor_every: usize,
    /// non-members (largest D-gain) tried per swap by the exact objectives O2..O5
    pub shortlist: usize,
    /// how restarts start
    pub init: Initialisation,
}

impl DetmaxOptions {
    /// Defaults for a design of `count` poses: 8 restarts, seed 0, no excursions, O1.
    pub fn new(count: usize) -> Self {
        Self {
            count,
            restarts: 8,
            seed: 0,
            max_exchanges: 10_000,
            excursions: None,
            fixed: Vec::new(),
            objective: Objective::O1,
            ridge: 0.0,
            refactor_every: 50,
            shortlist: 32,
            init: Initialisation::Random,
        }
    }
}

/// What one restart did.
#[derive(Debug, Clone, PartialEq)]
pub struct RestartOutcome {
    /// the restart's own seed
    pub seed: u64,
    /// ln det of its final design (from scratch, ridge included)
    pub log_det: f64,
    /// objective value of its final design
    pub objective_value: f64,
    /// exchange steps taken (excursion steps included)
    pub exchanges: usize,
    /// excursions that improved the design
    pub excursions_accepted: usize,
    /// true when the start was greedy (requested, or the random start was singular)
    pub greedy_start: bool,
}

/// Result of a selection.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// selected candidate indices, ascending
    pub selected: Vec<usize>,
    /// ln det(M + R) of the selection, computed from scratch (Cholesky)
    pub log_det: f64,
    /// ln det as tracked incrementally by the winning restart (equals `log_det` up to
    /// round-off)
    pub tracked_log_det: f64,
    /// objective value of the selection
    pub objective_value: f64,
    /// index of the winning restart
    pub best_restart: usize,
    /// every restart, in order
    pub restarts: Vec<RestartOutcome>,
}

impl Selection {
    /// The selection of the winning restart `best` (`(restart index, design, tracked ln det)`)
    /// among `restarts`.
    ///
    /// # Errors
    /// No restart ran (`best` is `None`).
    pub(super) fn of_best(
        best: Option<(usize, Vec<usize>, f64)>,
        restarts: Vec<RestartOutcome>,
    ) -> Result<Self, ObservabilityError> {
        let (best_restart, selected, tracked_log_det) =
            best.ok_or_else(|| ObservabilityError::InvalidInput("no restart ran".into()))?;
        let won = &restarts[best_restart];
        Ok(Selection {
            selected,
            log_det: won.log_det,
            tracked_log_det,
            objective_value: won.objective_value,
            best_restart,
            restarts,
        })
    }

    /// O1 of the selection from its log-determinant (exact when there is no ridge):
    /// `exp(ln det / 2L) / √n`, in the units of the candidate blocks.
    pub fn o1(&self, parameter_count: usize) -> f64 {
        o1_from_log_det(self.log_det, parameter_count, self.selected.len())
    }
}

/// `exp(ln det M / 2L) / √n`.
pub fn o1_from_log_det(log_det: f64, parameter_count: usize, poses: usize) -> f64 {
    (log_det / (2.0 * parameter_count as f64)).exp() / (poses.max(1) as f64).sqrt()
}

/// `ln det(Σ_{k∈design} B_kᵀB_k + R)` from scratch (Cholesky), `R = ridge · diag(Σ_all)/N`;
/// `None` when singular.
pub fn log_det(candidates: &Candidates, design: &[usize], ridge: f64) -> Option<f64> {
    let r = ridge_diagonal(candidates, ridge);
    factor(&with_ridge(candidates.information(design), &r)).map(|f| f.1)
}

pub(super) fn validate(c: &Candidates, o: &DetmaxOptions) -> Result<(), ObservabilityError> {
    let (n_cand, l) = (c.len(), c.parameter_count());
    if o.count > n_cand {
        return Err(ObservabilityError::TooFewCandidates { available: n_cand, requested: o.count });
    }
    if o.ridge <= 0.0 && 3 * o.count < l {
        return Err(ObservabilityError::InvalidInput(format!(
            "{} poses give {} equations for {l} parameters: choose at least {} poses",
            o.count,
            3 * o.count,
            l.div_ceil(3)
        )));
    }
    // plane contacts without the tool axis give one equation (their other rows are zero)
    let most = most_equations(c, o.count);
    if o.ridge <= 0.0 && most < l {
        return Err(ObservabilityError::InvalidInput(format!(
            "any {} of these candidates give at most {most} equations for {l} parameters (3 per pose, 1 per plane contact without the tool axis held normal): choose more poses",
            o.count
        )));
    }
    if o.count == 0 {
        return Err(ObservabilityError::InvalidInput("the design size must be at least 1".into()));
    }
    if o.restarts == 0 {
        return Err(ObservabilityError::InvalidInput("at least one restart is needed".into()));
    }
    if !(o.ridge >= 0.0 && o.ridge.is_finite()) {
        return Err(ObservabilityError::InvalidInput(format!(
            "ridge must be finite and ≥ 0, got {}",
            o.ridge
        )));
    }
    if o.fixed.len() > o.count {
        return Err(ObservabilityError::InvalidInput(format!(
            "{} fixed poses do not fit in a design of {}",
            o.fixed.len(),
            o.count
        )));
    }
    let mut seen = vec![false; n_cand];
    for &f in &o.fixed {
        if f >= n_cand {
            return Err(ObservabilityError::InvalidInput(format!(
                "fixed pose index {f} is out of range (there are {n_cand} candidates)"
            )));
        }
        if std::mem::replace(&mut seen[f], true) {
            return Err(ObservabilityError::InvalidInput(format!("fixed pose index {f} is listed twice")));
        }
    }
    Ok(())
}

/// The most equations (non-zero Jacobian rows) `count` of the candidates can give: the sum of
/// the `count` largest per-candidate counts.
fn most_equations(c: &Candidates, count: usize) -> usize {
    let mut rows: Vec<usize> =
        (0..c.len()).map(|k| (0..3).filter(|a| c.row(k, *a).iter().any(|x| *x != 0.0)).count()).collect();
    rows.sort_unstable_by(|a, b| b.cmp(a));
    rows.iter().take(count).sum()
}
