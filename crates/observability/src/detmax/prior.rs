//! Selection with prior information: rows that are in every design (e.g. known distances
//! between fixed points or parallel planes, [`crate::sets::DataDesign::constraint_jacobian`]),
//! so that the candidates only have to identify what the prior leaves open.
//!
//! The prior rows are packed into zero-padded 3-row pseudo-candidates appended after the real
//! candidates and held in every design as fixed poses; the exchange never removes them, and
//! they are stripped from what is returned.

use faer::MatRef;

use super::ablation::{SelectionIndices, indices_of_design};
use super::candidates::Candidates;
use super::options::{DetmaxOptions, Objective, Selection, o1_from_log_det};
use super::restarts::detmax;
use crate::error::ObservabilityError;

/// Number of 3-row pseudo-candidates that hold `rows` prior rows.
fn pseudo_count(rows: usize) -> usize {
    rows.div_ceil(3)
}

/// `candidates` followed by the prior rows packed three by three into pseudo-candidates (the
/// last one zero-padded). The pseudo-candidates are the indices `candidates.len()..` of the
/// result.
///
/// # Errors
/// [`ObservabilityError::InvalidInput`] when `prior_rows` does not have one column per
/// parameter or holds a non-finite value.
pub fn with_prior_rows(
    candidates: &Candidates,
    prior_rows: MatRef<'_, f64>,
) -> Result<Candidates, ObservabilityError> {
    let l = candidates.parameter_count();
    if prior_rows.ncols() != l {
        return Err(ObservabilityError::InvalidInput(format!(
            "the prior rows have {} columns for {l} parameters",
            prior_rows.ncols()
        )));
    }
    let p = prior_rows.nrows();
    if let Some((r, c)) =
        (0..p).flat_map(|r| (0..l).map(move |c| (r, c))).find(|(r, c)| !prior_rows[(*r, *c)].is_finite())
    {
        return Err(ObservabilityError::InvalidInput(format!(
            "prior row {} is not finite in `{}`",
            r + 1,
            candidates.params().0[c]
        )));
    }
    let mut rows = candidates.rows.clone();
    rows.reserve(3 * pseudo_count(p) * l);
    for r in 0..3 * pseudo_count(p) {
        rows.extend((0..l).map(|c| if r < p { prior_rows[(r, c)] } else { 0.0 }));
    }
    Ok(Candidates { rows, l, params: candidates.params().clone() })
}

/// [`detmax`] of `options.count` candidates with `prior_rows` (one column per parameter, in the
/// units of the candidate blocks) in every design: the information matrix of a design is
/// `Σ_{k∈S} B_kᵀB_k + PᵀP`. Use it when the candidates alone cannot identify the parameters
/// (e.g. plane contacts on unknown planes, whose scale only a known distance fixes) or to
/// select what a prior does not already know.
///
/// The returned [`Selection::selected`] holds `options.count` indices into `candidates` only
/// (ascending; `options.fixed` refers to `candidates` too). Its `log_det`, `tracked_log_det`
/// and `objective_value` (and those of every restart) **include the prior rows**; O1 counts
/// `options.count` poses (a prior row is no pose), as
/// [`observability_indices_for`](crate::observability_indices_for) with the measurement count.
/// Column normalisation inside the exchange and a relative `options.ridge` are computed over
/// the candidates and the prior rows together. With no prior row this is [`detmax`].
///
/// # Errors
/// As [`detmax`] (a rank-deficiency is that of the candidates and the prior together; an
/// equation-count error counts the prior's pseudo-candidates as poses), and
/// [`ObservabilityError::InvalidInput`] for prior rows with the wrong number of columns or a
/// non-finite value.
pub fn detmax_with_prior(
    candidates: &Candidates,
    prior_rows: MatRef<'_, f64>,
    options: &DetmaxOptions,
) -> Result<Selection, ObservabilityError> {
    if prior_rows.nrows() == 0 {
        return detmax(candidates, options);
    }
    let n = candidates.len();
    if options.count > n {
        return Err(ObservabilityError::TooFewCandidates { available: n, requested: options.count });
    }
    if let Some(f) = options.fixed.iter().find(|f| **f >= n) {
        return Err(ObservabilityError::InvalidInput(format!(
            "fixed pose index {f} is out of range (there are {n} candidates)"
        )));
    }
    let augmented = with_prior_rows(candidates, prior_rows)?;
    let pseudo = n..augmented.len();
    let mut fixed = options.fixed.clone();
    fixed.extend(pseudo.clone());
    let o = DetmaxOptions { count: options.count + pseudo.len(), fixed, ..options.clone() };
    let mut selection = detmax(&augmented, &o)?;
    selection.selected.retain(|k| *k < n);
    if options.objective == Objective::O1 {
        let (l, count) = (candidates.parameter_count(), options.count);
        selection.objective_value = o1_from_log_det(selection.log_det, l, count);
        for r in &mut selection.restarts {
            r.objective_value = o1_from_log_det(r.log_det, l, count);
        }
    }
    Ok(selection)
}

/// [`selection_indices`](super::selection_indices) of `selected` (indices into `candidates`)
/// with `prior_rows` added to its Jacobian: O1 counts `selected.len()` poses; the normalised
/// indices divide each column by its norm over the candidates and the prior rows together.
///
/// # Errors
/// As [`selection_indices`](super::selection_indices) and [`with_prior_rows`].
pub fn selection_indices_with_prior(
    candidates: &Candidates,
    prior_rows: MatRef<'_, f64>,
    selected: &[usize],
) -> Result<SelectionIndices, ObservabilityError> {
    let augmented = with_prior_rows(candidates, prior_rows)?;
    let mut design = selected.to_vec();
    design.extend(candidates.len()..augmented.len());
    indices_of_design(&augmented, &design, selected.len())
}

#[cfg(test)]
mod tests {
    use faer::Mat;
    use rand::SeedableRng;
    use rand::rngs::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};
    use vatcal_core::ParamSet;

    use super::*;
    use crate::detmax::{log_det, selection_indices};

    /// `n` Gaussian 3 × `l` blocks; the columns in `blind` are zero (directions no candidate
    /// sees).
    fn gaussian(n: usize, l: usize, blind: &[usize], seed: u64) -> Candidates {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let j = Mat::from_fn(3 * n, l, |_, c| {
            let z: f64 = StandardNormal.sample(&mut rng);
            if blind.contains(&c) { 0.0 } else { z * 10f64.powi((c % 3) as i32 - 1) }
        });
        let params = ParamSet(ParamSet::paper34().0.into_iter().take(l).collect());
        Candidates::from_stacked(j, params).expect("candidates")
    }

    fn options(count: usize, seed: u64) -> DetmaxOptions {
        DetmaxOptions { restarts: 3, seed, excursions: Some(2), ..DetmaxOptions::new(count) }
    }

    /// ln det of `selected` plus the prior, from scratch.
    fn log_det_with(c: &Candidates, prior: MatRef<'_, f64>, selected: &[usize]) -> f64 {
        let augmented = with_prior_rows(c, prior).expect("augmented");
        let mut design = selected.to_vec();
        design.extend(c.len()..augmented.len());
        log_det(&augmented, &design, 0.0).expect("non-singular")
    }

    #[test]
    fn a_prior_that_fixes_an_unseen_direction_makes_the_selection_possible() {
        let (l, blind) = (8, 5);
        let c = gaussian(60, l, &[blind], 3);
        let o = options(10, 1);
        let plain = detmax(&c, &o);
        assert!(matches!(plain, Err(ObservabilityError::RankDeficient { .. })), "{plain:?}");
        // one row that sees the blind column (and a little of another)
        let prior = Mat::from_fn(1, l, |_, col| match col {
            5 => 2.0,
            0 => 0.5,
            _ => 0.0,
        });
        let s = detmax_with_prior(&c, prior.as_ref(), &o).expect("selection with the prior");
        assert_eq!(s.selected.len(), 10);
        // the reported criterion is the design's with the prior
        let scratch = log_det_with(&c, prior.as_ref(), &s.selected);
        assert!((s.log_det - scratch).abs() < 1e-9 * scratch.abs().max(1.0), "{} vs {scratch}", s.log_det);
        assert!((s.objective_value - s.o1(l)).abs() < 1e-12 * s.o1(l));
        let i = selection_indices_with_prior(&c, prior.as_ref(), &s.selected).expect("indices");
        assert_eq!(i.raw.rank, l);
        assert_eq!(i.raw.pose_count, 10);
        assert!((i.raw.o1 - s.o1(l)).abs() < 1e-6 * s.o1(l), "{} vs {}", i.raw.o1, s.o1(l));
        // without the prior the same poses are blind
        assert!(selection_indices(&c, &s.selected).expect("indices").raw.rank < l);
    }

    #[test]
    fn the_selection_names_real_candidates_only_and_keeps_the_fixed_ones() {
        let (l, n) = (7, 40);
        let c = gaussian(n, l, &[], 11);
        // four rows: two pseudo-candidates, the second zero-padded
        let prior = Mat::from_fn(4, l, |r, col| if col == r { 30.0 } else { 0.0 });
        let o = DetmaxOptions { fixed: vec![3, 17], ..options(6, 2) };
        let s = detmax_with_prior(&c, prior.as_ref(), &o).expect("selection");
        assert_eq!(s.selected.len(), 6, "{:?}", s.selected);
        assert!(s.selected.iter().all(|k| *k < n), "{:?}", s.selected);
        assert!(s.selected.windows(2).all(|w| w[0] < w[1]), "{:?}", s.selected);
        assert!(s.selected.contains(&3) && s.selected.contains(&17), "{:?}", s.selected);
        // a fixed index beyond the real candidates is refused, not taken for a pseudo-candidate
        let bad = DetmaxOptions { fixed: vec![n], ..options(6, 2) };
        assert!(matches!(
            detmax_with_prior(&c, prior.as_ref(), &bad),
            Err(ObservabilityError::InvalidInput(_))
        ));
        let wide = Mat::<f64>::zeros(1, l + 1);
        assert!(matches!(detmax_with_prior(&c, wide.as_ref(), &o), Err(ObservabilityError::InvalidInput(_))));
        let too_many = options(n + 1, 2);
        assert!(matches!(
            detmax_with_prior(&c, prior.as_ref(), &too_many),
            Err(ObservabilityError::TooFewCandidates { available: 40, requested: 41 })
        ));
    }

    #[test]
    fn an_all_zero_prior_selects_as_plain_detmax() {
        let (l, n) = (9, 80);
        let c = gaussian(n, l, &[], 5);
        for seed in [0, 7] {
            let o = options(12, seed);
            let plain = detmax(&c, &o).expect("plain");
            let zero = Mat::<f64>::zeros(5, l);
            let s = detmax_with_prior(&c, zero.as_ref(), &o).expect("with a zero prior");
            assert_eq!(s.selected, plain.selected, "seed {seed}");
            assert_eq!(s.best_restart, plain.best_restart, "seed {seed}");
            assert!((s.log_det - plain.log_det).abs() < 1e-9 * plain.log_det.abs().max(1.0));
            assert!((s.objective_value - plain.objective_value).abs() < 1e-9 * plain.objective_value);
        }
    }
}
