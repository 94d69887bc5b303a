//! Calibration of any chain from its nominal model: initialisation, the parameter set (named,
//! or chosen by cross-validation), the fit.
//!
//! # Choosing the model size ([`cross_validate_sets`])
//! A bigger parameter set always fits the training rows better; whether it predicts postures
//! the fit did not see is what matters. The rows are grouped by posture (rows with the same
//! joint vector are one group: repeated readings of one posture must not be split between
//! training and test), the groups are dealt into K folds after a seeded shuffle, and every
//! candidate set ([`GenericSet`]: registration ⊂ joint-offsets ⊂ kinematic ⊂
//! kinematic+compliance) is fitted K times on K − 1 folds and scored on the held-out fold
//! (mean squared residual of the held-out rows, weighted by kind as in the fit). The score is
//! the mean over the folds, with its standard error `sd / √K`.
//!
//! **The 1-SE rule** (Breiman et al. 1984; Hastie, Tibshirani & Friedman, *Elements of
//! Statistical Learning* §7.10): the smallest set whose CV error is within one standard error of
//! the best one wins. Differences inside one standard error are not resolved by the data; the
//! smaller model is then preferred because its parameters are better determined and it
//! extrapolates more safely (a larger set that merely interpolates the training range better is
//! exactly the failure mode of issue 20: 39 parameters from 111 equations). A candidate whose fit
//! on all rows fails (rank deficiency cannot happen — the sets are reduced to their identifiable
//! basis — but ill-conditioning or non-convergence can) is rejected with the reason.

use vatcal_core::{Measurement, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::sets::{DataDesign, GenericSet, generic_set, resolve_spec};

use crate::{
    Identification, IdentifyError, IdentifyOptions, InitOptions, Initialisation, identify, initialise,
};

/// Options of [`cross_validate_sets`].
#[derive(Debug, Clone, PartialEq)]
pub struct CvOptions {
    /// number of folds K (at least 2; fewer posture groups than K → one group per fold)
    pub folds: usize,
    /// seed of the shuffle that deals the posture groups into folds
    pub seed: u64,
    /// the candidate sets, smallest first
    pub candidates: Vec<GenericSet>,
    /// optional regularisation toward the starting (nominal) values: every parameter of the
    /// robot (MDH values, compliances) gets a Gaussian prior of standard deviation
    /// `prior_scale × ParamId::typical_scale` (0.1 mm, 0.001 rad, 1e-4 rad/(N·m) at 1); the
    /// base pose, TCP and fixed-point coordinates stay free. The prior rows are weighed against
    /// the data's own σ̂ (`IdentifyOptions::prior_sigma_from_fit`). `None` (default): the
    /// scale is chosen by cross-validation among no priors and [`CvOptions::prior_scales`]
    pub prior_scale: Option<f64>,
    /// the prior scales cross-validated with every candidate set that has parameters of the
    /// robot, besides no priors, when `prior_scale` is `None` (default 10, 3, 1: plausible
    /// spreads of 1 mm / 0.01 rad down to 0.1 mm / 0.001 rad); empty: no priors
    pub prior_scales: Vec<f64>,
}

impl Default for CvOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            seed: 1,
            candidates: GenericSet::ALL.to_vec(),
            prior_scale: None,
            prior_scales: vec![10.0, 3.0, 1.0],
        }
    }
}

impl CvOptions {
    /// The options of a candidate's fits: `options` with the priors of
    /// [`CvOptions::prior_scale`] and without the condition-number cap — on the
    /// cross-validated path the prediction error on held-out postures is the judge, and a
    /// combination the data barely see shows there (or, with priors, stays at its nominal
    /// value).
    pub fn fit_options(&self, params: &ParamSet, options: &IdentifyOptions) -> IdentifyOptions {
        Self::fit_options_with(self.prior_scale, params, options)
    }

    /// [`CvOptions::fit_options`] with the prior scale `prior_scale` (`None`: no priors).
    pub fn fit_options_with(
        prior_scale: Option<f64>,
        params: &ParamSet,
        options: &IdentifyOptions,
    ) -> IdentifyOptions {
        let priors = prior_scale.map(|k| {
            params
                .iter()
                .map(|p| match p {
                    vatcal_core::ParamId::Base(_)
                    | vatcal_core::ParamId::Tcp { .. }
                    | vatcal_core::ParamId::Position { .. } => f64::INFINITY,
                    _ => k * p.typical_scale(),
                })
                .collect()
        });
        IdentifyOptions {
            priors,
            prior_sigma_from_fit: true,
            max_condition_number: f64::INFINITY,
            ..options.clone()
        }
    }
}

impl CandidateScore {
    /// The set's name, with its prior scale when it has one (`kinematic, priors x3`).
    pub fn label(&self) -> String {
        match self.prior_scale {
            Some(k) => format!("{}, priors x{k}", self.set),
            None => self.set.to_string(),
        }
    }
}

/// The cross-validated score of one candidate set.
#[derive(Debug, Clone, PartialEq)]
pub struct CandidateScore {
    /// the candidate
    pub set: GenericSet,
    /// its identifiable basis on all rows
    pub params: ParamSet,
    /// the scale of its priors toward nominal ([`CvOptions::prior_scale`]; `None`: none)
    pub prior_scale: Option<f64>,
    /// RMS of the held-out residual norms, `√(mean over folds of the fold's mean squared
    /// residual)` \[mm\] (`NaN` when rejected)
    pub cv_rms_mm: f64,
    /// standard error of the fold mean squared residuals, `sd / √K` \[mm²\]
    pub cv_se_mm2: f64,
    /// mean over folds of the fold's mean squared residual \[mm²\]
    pub cv_mse_mm2: f64,
    /// RMS of the held-out residual norms of every fold \[mm\]
    pub fold_rms_mm: Vec<f64>,
    /// RMS of the residual norms of the fit on all rows \[mm\]
    pub train_rms_mm: f64,
    /// condition number of the fit on all rows
    pub condition_number: f64,
    /// why the candidate was not scored (its fit on all rows or on a fold failed)
    pub rejected: Option<String>,
}

/// The outcome of [`cross_validate_sets`].
#[derive(Debug, Clone, PartialEq)]
pub struct CvSelection {
    /// every candidate, in the order given
    pub candidates: Vec<CandidateScore>,
    /// index of the chosen candidate
    pub chosen: usize,
    /// one sentence: why it won (the 1-SE rule with the numbers)
    pub reason: String,
    /// folds used
    pub folds: usize,
    /// posture groups dealt into the folds
    pub groups: usize,
    /// the seed of the shuffle
    pub seed: u64,
}

impl CvSelection {
    /// The chosen candidate.
    pub fn chosen(&self) -> &CandidateScore {
        &self.candidates[self.chosen]
    }
}

/// Posture groups: rows with the same joint vector (to 1e-9) share a group; groups in order of
/// first appearance.
fn posture_groups(measurements: &[Measurement]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut keys: Vec<&vatcal_core::JointVector> = Vec::new();
    for (k, m) in measurements.iter().enumerate() {
        let same = keys.iter().position(|q| {
            q.len() == m.q.len() && (0..q.len()).all(|i| (q.get(i + 1) - m.q.get(i + 1)).abs() <= 1e-9)
        });
        match same {
            Some(g) => groups[g].push(k),
            None => {
                keys.push(&m.q);
                groups.push(vec![k]);
            }
        }
    }
    groups
}

/// splitmix64: a tiny deterministic generator for the shuffle.
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The fold of every measurement (0..K), posture groups kept together, dealt round-robin after
/// a seeded Fisher–Yates shuffle.
pub fn posture_folds(measurements: &[Measurement], folds: usize, seed: u64) -> (Vec<usize>, usize) {
    let groups = posture_groups(measurements);
    let mut order: Vec<usize> = (0..groups.len()).collect();
    let mut state = seed;
    for i in (1..order.len()).rev() {
        let j = (splitmix(&mut state) % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    let k = folds.max(2).min(groups.len().max(1));
    let mut fold_of = vec![0; measurements.len()];
    for (slot, g) in order.iter().enumerate() {
        for &row in &groups[*g] {
            fold_of[row] = slot % k;
        }
    }
    (fold_of, k)
}

/// Mean squared (kind-weighted) residual norm of `rows` under `model` [mm²].
fn mean_squared(
    model: &Model,
    measurements: &[Measurement],
    rows: &[usize],
    options: &IdentifyOptions,
) -> Result<f64, IdentifyError> {
    let mut sum = 0.0;
    for &k in rows {
        let m = &measurements[k];
        let e = model.residual(m).map_err(|source| IdentifyError::Measurement { index: k, source })?
            + m.target_offset_mm();
        let w = match m.target {
            vatcal_core::Target::Probe { .. } => options.weights.probe,
            vatcal_core::Target::Tracker { .. } => options.weights.tracker,
        };
        sum += w * e.norm_squared();
    }
    Ok(sum / rows.len().max(1) as f64)
}

/// Scores every candidate set by K-fold cross-validation over posture groups and picks one by
/// the 1-SE rule (module docs). `start` should already be initialised ([`initialise`]): each
/// fit starts from it. `options` are those of the final fit; inside the folds the condition
/// cap is not applied (a fold's prediction error is the judge).
///
/// # Errors
/// [`IdentifyError::NoMeasurements`]; the errors of the identifiability analysis; an
/// [`IdentifyError::InvalidOptions`] when every candidate is rejected (the message lists the
/// reasons).
pub fn cross_validate_sets(
    start: &Model,
    measurements: &[Measurement],
    design: &DataDesign,
    options: &IdentifyOptions,
    cv: &CvOptions,
) -> Result<CvSelection, IdentifyError> {
    if measurements.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    let (fold_of, k) = posture_folds(measurements, cv.folds, cv.seed);
    let groups = posture_groups(measurements).len();
    let mut candidates = Vec::new();
    for set in &cv.candidates {
        let (params, unusable) = match generic_set(start, measurements, *set, design) {
            Ok(p) => (p, None),
            Err(e @ vatcal_observability::ObservabilityError::InvalidInput(_)) => {
                (ParamSet::default(), Some(e.to_string()))
            }
            Err(e) => return Err(e.into()),
        };
        let robot_params = params.iter().any(|p| {
            !matches!(
                p,
                vatcal_core::ParamId::Base(_)
                    | vatcal_core::ParamId::Tcp { .. }
                    | vatcal_core::ParamId::Position { .. }
            )
        });
        // simplest first: the strongest priors, then weaker, then none
        let scales: Vec<Option<f64>> = match cv.prior_scale {
            Some(k) => vec![Some(k)],
            None if robot_params && unusable.is_none() => {
                let mut v: Vec<f64> = cv.prior_scales.clone();
                v.sort_by(f64::total_cmp);
                v.into_iter().map(Some).chain([None]).collect()
            }
            None => vec![None],
        };
        for scale in scales {
            candidates.push(score_candidate(
                start,
                measurements,
                options,
                *set,
                &params,
                scale,
                unusable.clone(),
                &fold_of,
                k,
            )?);
        }
    }
    choose(candidates, k, groups, cv.seed)
}

/// Fits one candidate on all rows and on every fold.
#[allow(clippy::too_many_arguments)]
fn score_candidate(
    start: &Model,
    measurements: &[Measurement],
    options: &IdentifyOptions,
    set: GenericSet,
    params: &ParamSet,
    prior_scale: Option<f64>,
    unusable: Option<String>,
    fold_of: &[usize],
    k: usize,
) -> Result<CandidateScore, IdentifyError> {
    {
        let mut score = CandidateScore {
            set,
            prior_scale,
            params: params.clone(),
            cv_rms_mm: f64::NAN,
            cv_se_mm2: f64::NAN,
            cv_mse_mm2: f64::NAN,
            fold_rms_mm: Vec::new(),
            train_rms_mm: f64::NAN,
            condition_number: f64::NAN,
            rejected: unusable,
        };
        if score.rejected.is_some() {
            return Ok(score);
        }
        let fit_options = CvOptions::fit_options_with(prior_scale, params, options);
        match identify(start, measurements, params, &fit_options) {
            Ok(fit) => {
                score.train_rms_mm = fit.residual_stats.rms;
                score.condition_number = fit.condition_number;
            }
            Err(e) => {
                score.rejected = Some(format!("fit on all rows: {e}"));
                return Ok(score);
            }
        }
        let mut fold_mse = Vec::with_capacity(k);
        for fold in 0..k {
            let train: Vec<Measurement> =
                measurements.iter().zip(fold_of).filter(|(_, f)| **f != fold).map(|(m, _)| *m).collect();
            let test: Vec<usize> = (0..measurements.len()).filter(|i| fold_of[*i] == fold).collect();
            match identify(start, &train, params, &fit_options) {
                Ok(fit) => fold_mse.push(mean_squared(&fit.model, measurements, &test, options)?),
                Err(e) => {
                    score.rejected = Some(format!("fold {}: {e}", fold + 1));
                    break;
                }
            }
        }
        if score.rejected.is_none() {
            let n = fold_mse.len() as f64;
            let mean = fold_mse.iter().sum::<f64>() / n;
            let var = fold_mse.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
            score.cv_mse_mm2 = mean;
            score.cv_se_mm2 = (var / n).sqrt();
            score.cv_rms_mm = mean.sqrt();
            score.fold_rms_mm = fold_mse.iter().map(|v| v.sqrt()).collect();
        }
        Ok(score)
    }
}

/// The 1-SE choice among scored candidates (simplest first).
fn choose(
    candidates: Vec<CandidateScore>,
    k: usize,
    groups: usize,
    seed: u64,
) -> Result<CvSelection, IdentifyError> {
    let scored: Vec<usize> = (0..candidates.len()).filter(|i| candidates[*i].rejected.is_none()).collect();
    let Some(&best) =
        scored.iter().min_by(|a, b| candidates[**a].cv_mse_mm2.total_cmp(&candidates[**b].cv_mse_mm2))
    else {
        let reasons: Vec<String> = candidates
            .iter()
            .map(|c| format!("{}: {}", c.label(), c.rejected.as_deref().unwrap_or("?")))
            .collect();
        return Err(IdentifyError::InvalidOptions(format!(
            "no candidate parameter set could be fitted: {}",
            reasons.join("; ")
        )));
    };
    let threshold = candidates[best].cv_mse_mm2 + candidates[best].cv_se_mm2;
    let chosen = scored.iter().copied().find(|i| candidates[*i].cv_mse_mm2 <= threshold).unwrap_or(best);
    let (b, c) = (&candidates[best], &candidates[chosen]);
    let reason = if chosen == best {
        format!(
            "`{}` has the lowest cross-validated error ({:.4} mm RMS over {k} folds) and no simpler candidate is within one standard error of it",
            c.label(),
            c.cv_rms_mm
        )
    } else {
        format!(
            "`{}` ({:.4} mm RMS) is the simplest candidate within one standard error of the best, `{}` ({:.4} mm RMS, threshold {:.4} mm = √(MSE + SE)): the 1-SE rule prefers the simpler model",
            c.label(),
            c.cv_rms_mm,
            b.label(),
            b.cv_rms_mm,
            threshold.sqrt()
        )
    };
    Ok(CvSelection { candidates, chosen, reason, folds: k, groups, seed })
}

/// Everything [`calibrate`] did.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// the initialisation (None when the canonical cell is fitted with a canonical set: its
    /// nominal model is the start, as in the paper)
    pub init: Option<Initialisation>,
    /// the parameters that were identified
    pub params: ParamSet,
    /// the cross-validated choice (only for `default` on a chain other than the canonical cell)
    pub selection: Option<CvSelection>,
    /// the final fit on all rows
    pub fit: Identification,
}

/// What a fit of external data starts from ([`prepare_calibration`]): the initialised start
/// model, the parameter set and the options of the fit.
#[derive(Debug, Clone)]
pub struct CalibrationStart {
    /// the initialisation (None when the canonical cell is fitted with a canonical set)
    pub init: Option<Initialisation>,
    /// the model the fit starts from (the initialised model, or the nominal one)
    pub start: Model,
    /// the parameters to identify
    pub params: ParamSet,
    /// the cross-validated choice (only for `default` on a chain other than the canonical cell)
    pub selection: Option<CvSelection>,
    /// the options of the fit (`options` with the distances of the design and, for a set
    /// chosen by cross-validation, [`CvOptions::fit_options`])
    pub fit_options: IdentifyOptions,
}

/// Everything of [`calibrate`] before the final fit — the one code path of every command that
/// fits a model to external data (`vatcal identify`, `vatcal discover`): resolves `spec`
/// (`default`, a [`GenericSet`] name, `paper34`/`geometric` on the canonical cell,
/// `all-identifiable`, or a list of names; [`resolve_spec`]), initialises the base pose,
/// measured TCPs and unknown fixed points ([`initialise`]) unless the canonical cell is fitted
/// with its own sets, and chooses the set by [`cross_validate_sets`] for `default` on any other
/// chain. The known distances of `design` are used as measurements (they override
/// `options.point_distances`).
///
/// # Errors
/// The errors of [`resolve_spec`] (an unknown name, a canonical-only set on another chain, a
/// distance naming an unknown point), [`initialise`] and [`cross_validate_sets`].
pub fn prepare_calibration(
    nominal: &Model,
    measurements: &[Measurement],
    spec: &str,
    design: &DataDesign,
    options: &IdentifyOptions,
    cv: &CvOptions,
) -> Result<CalibrationStart, IdentifyError> {
    design.check(nominal)?;
    let options = IdentifyOptions { point_distances: design.distances.clone(), ..options.clone() };
    let trimmed = spec.trim();
    let canonical = nominal.is_meca500_on_guide();
    let canonical_fit = canonical
        && design.free_positions.is_empty()
        && (trimmed == "default" || vatcal_core::canonical::is_canonical_only_set(trimmed));
    if canonical_fit {
        let params = resolve_spec(spec, nominal, measurements, design)?;
        return Ok(CalibrationStart {
            init: None,
            start: nominal.clone(),
            params,
            selection: None,
            fit_options: options,
        });
    }
    // the registration set does not need the distances (and unknown points may still coincide
    // at their placeholder coordinates, where a distance row is undefined)
    let points_only = DataDesign { free_positions: design.free_positions.clone(), distances: Vec::new() };
    let registration = generic_set(nominal, measurements, GenericSet::Registration, &points_only)?;
    let init = initialise(nominal, measurements, &InitOptions::for_params(&registration))?;
    let start = init.model.clone();
    let (params, selection, fit_options) = if trimmed == "default" {
        let sel = cross_validate_sets(&start, measurements, design, &options, cv)?;
        let params = sel.chosen().params.clone();
        let fit_options = CvOptions::fit_options_with(sel.chosen().prior_scale, &params, &options);
        (params, Some(sel), fit_options)
    } else {
        (resolve_spec(spec, &start, measurements, design)?, None, options)
    };
    Ok(CalibrationStart { init: Some(init), start, params, selection, fit_options })
}

/// Calibrates `nominal` from `measurements`: [`prepare_calibration`] (initialisation, the
/// parameter set — named, or chosen by cross-validation for `default` on a chain other than
/// the canonical cell), then the fit on all rows.
///
/// # Errors
/// The errors of [`prepare_calibration`] and [`identify`].
pub fn calibrate(
    nominal: &Model,
    measurements: &[Measurement],
    spec: &str,
    design: &DataDesign,
    options: &IdentifyOptions,
    cv: &CvOptions,
) -> Result<Calibration, IdentifyError> {
    let prepared = prepare_calibration(nominal, measurements, spec, design, options, cv)?;
    let fit = identify(&prepared.start, measurements, &prepared.params, &prepared.fit_options)?;
    Ok(Calibration { init: prepared.init, params: prepared.params, selection: prepared.selection, fit })
}
