//! Reporting helpers: the observability indices of a selection and the calibration-position
//! ablation.

use super::bookkeeping::column_norms;
use super::candidates::Candidates;
use super::options::DetmaxOptions;
use super::restarts::detmax;
use crate::error::ObservabilityError;
use crate::identifiability::ColumnScaling;
use crate::indices::ObservabilityIndices;

/// The indices of a selection, in the two conventions of background.md §3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectionIndices {
    /// natural units (mm per parameter unit): the O1 to compare with the paper
    pub raw: ObservabilityIndices,
    /// columns divided by their norms over the **whole candidate set** (so designs stay
    /// comparable): the O2..O5, condition number and σ_min to read
    pub normalized: ObservabilityIndices,
}

/// O1..O5, rank, condition number and σ_min of `selected` (raw and candidate-normalised).
pub fn selection_indices(
    candidates: &Candidates,
    selected: &[usize],
) -> Result<SelectionIndices, ObservabilityError> {
    indices_of_design(candidates, selected, selected.len())
}

/// [`selection_indices`] of `design` with O1 counting `poses` poses (a design that holds
/// prior pseudo-candidates counts only its real poses).
pub(super) fn indices_of_design(
    candidates: &Candidates,
    design: &[usize],
    poses: usize,
) -> Result<SelectionIndices, ObservabilityError> {
    let j = candidates.design_jacobian(design);
    let raw = crate::indices::observability_indices_for(
        j.as_ref(),
        candidates.params(),
        ColumnScaling::None,
        poses,
    )?;
    let factors: Vec<f64> =
        column_norms(candidates).iter().map(|x| if *x > 0.0 { 1.0 / x } else { 1.0 }).collect();
    let mut jn = j;
    crate::identifiability::scale_columns(&mut jn, &factors);
    let mut normalized = crate::indices::observability_indices_for(
        jn.as_ref(),
        candidates.params(),
        ColumnScaling::None,
        poses,
    )?;
    normalized.scaling = ColumnScaling::UnitNorm;
    Ok(SelectionIndices { raw, normalized })
}

/// One row of [`position_ablation`].
#[derive(Debug, Clone, PartialEq)]
pub struct AblationRow {
    /// the calibration positions the candidates were restricted to
    pub positions: Vec<u32>,
    /// number of candidates at those positions
    pub candidate_count: usize,
    /// the selection (indices into the **full** candidate list, ascending), None when there
    /// were fewer candidates than poses requested
    pub selected: Option<Vec<usize>>,
    /// its indices (None when no selection)
    pub indices: Option<SelectionIndices>,
}

/// The paper's ablation: the best Detmax selection of `options.count` poses when the
/// candidates are restricted to every subset of `subset_size` calibration positions.
/// `positions[k]` is candidate k's calibration position (None for tracker rows, which are
/// never used here). With fewer than three positions the world frame is not identifiable, so
/// the restricted selections use a ridge (`max(options.ridge, 1e-6)`); their indices are
/// computed without it, and their rank shows what is lost.
pub fn position_ablation(
    candidates: &Candidates,
    positions: &[Option<u32>],
    subset_size: usize,
    options: &DetmaxOptions,
) -> Result<Vec<AblationRow>, ObservabilityError> {
    if positions.len() != candidates.len() {
        return Err(ObservabilityError::InvalidInput(format!(
            "{} position labels for {} candidates",
            positions.len(),
            candidates.len()
        )));
    }
    let mut ids: Vec<u32> = positions.iter().flatten().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let mut rows = Vec::new();
    for subset in subsets(&ids, subset_size) {
        let members: Vec<usize> =
            (0..candidates.len()).filter(|k| positions[*k].is_some_and(|p| subset.contains(&p))).collect();
        let mut row =
            AblationRow { positions: subset, candidate_count: members.len(), selected: None, indices: None };
        if members.len() >= options.count {
            let restricted = candidates.subset(&members);
            let o = DetmaxOptions { ridge: options.ridge.max(1e-6), fixed: Vec::new(), ..options.clone() };
            let s = detmax(&restricted, &o)?;
            let selected: Vec<usize> = s.selected.iter().map(|i| members[*i]).collect();
            row.indices = Some(selection_indices(candidates, &selected)?);
            row.selected = Some(selected);
        }
        rows.push(row);
    }
    Ok(rows)
}

/// All `k`-element subsets of `ids`, in lexicographic order.
fn subsets(ids: &[u32], k: usize) -> Vec<Vec<u32>> {
    if k == 0 {
        return vec![Vec::new()];
    }
    let mut out = Vec::new();
    for (i, id) in ids.iter().enumerate() {
        for mut rest in subsets(&ids[i + 1..], k - 1) {
            rest.insert(0, *id);
            out.push(rest);
        }
    }
    out
}
