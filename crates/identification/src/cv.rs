//! Calibration of any chain from its nominal model: initialisation, the parameter set (named,
//! or the default MAP fit), the fit.
//!
//! # The default on other chains: the richest set, realistic priors, the scale by CV
//! With few postures, cross-validation cannot rank nested parameter sets (issue 29: eleven
//! candidates within 3 % of each other, rank correlation 0.11 with the held-out error), and
//! "within one standard error, take the smallest" then picks the model that extrapolates worst:
//! every real robot has kinematic errors. The default is therefore a **MAP fit of the richest
//! physically meaningful set** ([`GenericSet::KinematicCompliance`], reduced to its identifiable
//! basis: the measured frames, TCPs and unknown points, every MDH value and Hayati tilt, the
//! compliances) with Gaussian priors of realistic width per kind of parameter
//! ([`PriorWidths::realistic`]: 10 mrad joint zeros, 1 mm lengths, 3 mrad twists and tilts, 2 mrad
//! of gravity deflection; the frames free). What cross-validation chooses is only the **prior
//! scale**, on a wide grid ([`CvOptions::prior_scales`], ×0.1 … ×30), by the **lowest** score.
//!
//! The score: rows are grouped by posture (rows with the same joint vector are one group:
//! repeated readings of one posture must not be split between training and test), the groups are
//! dealt into K folds after a seeded shuffle, repeated R times with other seeds (repeated K-fold;
//! with K ≥ the number of postures, leave-one-posture-out, once). Every candidate is fitted on
//! K − 1 folds and scored on the held-out fold (mean squared residual of the held-out rows,
//! weighted by kind as in the fit); the score is the mean over the R·K folds, with its standard
//! error. The fits inside the CV get an iteration cap that grows with the problem
//! ([`cv_iteration_cap`]); a fold fit that still reaches it is scored at its last iterate (and
//! counted), never rejected.
//!
//! [`CvOptions::candidates`] can still list the nested sets (registration ⊂ joint-offsets ⊂
//! kinematic ⊂ kinematic+compliance) and [`CvOptions::unregularised`] add fits without priors:
//! the lowest score wins among all of them.

use vatcal_core::{Measurement, ParamSet};
use vatcal_kinematics::Model;
use vatcal_observability::sets::{DataDesign, GenericSet, generic_set, resolve_spec};

use crate::priors::{PriorSpec, PriorWidths};
use crate::{
    Identification, IdentifyError, IdentifyOptions, InitOptions, Initialisation, identify, initialise,
};

/// The smallest iteration cap of a fit on the cross-validated (default) path.
pub const CV_MIN_ITERATIONS: usize = 200;

/// The iteration cap of a fit of `n_params` parameters on the default path: `max(cap, 200,
/// 5 L)`. Ill-conditioned fits (tens of parameters seen through one marker) crawl along the
/// weak directions; a fixed cap of 50 rejected whole candidates on real data.
pub fn cv_iteration_cap(cap: usize, n_params: usize) -> usize {
    cap.max(CV_MIN_ITERATIONS).max(5 * n_params)
}

/// Options of [`cross_validate_sets`].
#[derive(Debug, Clone, PartialEq)]
pub struct CvOptions {
    /// number of folds K (at least 2; K ≥ the number of posture groups: leave-one-posture-out)
    pub folds: usize,
    /// repetitions of the K-fold split, each with its own shuffle (seeds `seed`, `seed + 1`,
    /// …); 1 with leave-one-posture-out. Default 3
    pub repeats: usize,
    /// seed of the first shuffle that deals the posture groups into folds
    pub seed: u64,
    /// the candidate sets (default: the richest, `kinematic+compliance`)
    pub candidates: Vec<GenericSet>,
    /// the prior widths at ×1 (default [`PriorWidths::realistic`]); a kind with an infinite
    /// width is free
    pub widths: PriorWidths,
    /// a fixed prior scale (multiplies every width); `None` (default): chosen by
    /// cross-validation among [`CvOptions::prior_scales`]
    pub prior_scale: Option<f64>,
    /// the prior scales cross-validated when `prior_scale` is `None` (default 0.1, 0.3, 1, 3,
    /// 10, 30: 0.1 mm / 1 mrad joint zeros … 30 mm / 0.3 rad)
    pub prior_scales: Vec<f64>,
    /// also score every candidate without priors (default false: only sets whose parameters
    /// are all identifiable can be fitted without, and they extrapolate badly from few postures)
    pub unregularised: bool,
}

impl Default for CvOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            repeats: 3,
            seed: 1,
            candidates: vec![GenericSet::KinematicCompliance],
            widths: PriorWidths::realistic(),
            prior_scale: None,
            prior_scales: vec![0.1, 0.3, 1.0, 3.0, 10.0, 30.0],
            unregularised: false,
        }
    }
}

impl CvOptions {
    /// The options of a candidate's fits with the prior scale `prior_scale` (`None`: no
    /// priors): `options` with the priors of [`CvOptions::widths`] × the scale (weighed against
    /// the data's own σ̂: `prior_sigma_from_fit`), the iteration cap of [`cv_iteration_cap`]
    /// and without the condition-number cap — on this path the prediction error on held-out
    /// postures is the judge, and a combination the data barely see stays at its nominal value.
    pub fn fit_options(
        &self,
        prior_scale: Option<f64>,
        model: &Model,
        measurements: &[Measurement],
        params: &ParamSet,
        options: &IdentifyOptions,
    ) -> IdentifyOptions {
        let priors = prior_scale.map(|k| PriorSpec::new(self.widths, k).sigmas(model, measurements, params));
        IdentifyOptions {
            priors,
            prior_sigma_from_fit: true,
            max_condition_number: f64::INFINITY,
            max_iterations: cv_iteration_cap(options.max_iterations, params.len()),
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
    /// standard error of the fold mean squared residuals, `sd / √(R·K)` \[mm²\]
    pub cv_se_mm2: f64,
    /// mean over the R·K folds of the fold's mean squared residual \[mm²\]
    pub cv_mse_mm2: f64,
    /// RMS of the held-out residual norms of every fold \[mm\] (repeat by repeat)
    pub fold_rms_mm: Vec<f64>,
    /// fold fits that reached the iteration cap and were scored at their last iterate
    pub capped_fits: usize,
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
    /// one sentence: why it won (the lowest score, with the numbers)
    pub reason: String,
    /// folds used
    pub folds: usize,
    /// repetitions of the K-fold split
    pub repeats: usize,
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
    deal_folds(&posture_groups(measurements), measurements.len(), folds, seed)
}

/// [`posture_folds`] of posture groups already found (`rows` measurements in all).
fn deal_folds(groups: &[Vec<usize>], rows: usize, folds: usize, seed: u64) -> (Vec<usize>, usize) {
    let mut order: Vec<usize> = (0..groups.len()).collect();
    let mut state = seed;
    for i in (1..order.len()).rev() {
        let j = (splitmix(&mut state) % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    let k = folds.max(2).min(groups.len().max(1));
    let mut fold_of = vec![0; rows];
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
        let w = options.weights.of(&m.target);
        // a robust fit's per-row weights count in the score as in the fit (a down-weighted bad
        // row must not decide the choice)
        let row = options.row_weights.as_ref().and_then(|r| r.get(k)).copied().unwrap_or(1.0);
        sum += w * row * e.norm_squared();
    }
    Ok(sum / rows.len().max(1) as f64)
}

/// Scores every candidate (set × prior scale) by repeated K-fold cross-validation over
/// posture groups and picks the lowest score (module docs). `start` should already be
/// initialised ([`initialise`]): each fit starts from it, and the priors are centred on it.
/// `options` are those of the final fit; inside the folds the condition cap is not applied and
/// the iteration cap grows with the problem.
///
/// # Errors
/// [`IdentifyError::NoMeasurements`]; the errors of the identifiability analysis; an
/// [`IdentifyError::InvalidOptions`] when every candidate is rejected (the message lists the
/// reasons) or a prior scale is not a positive number.
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
    if let Some(k) = cv.prior_scale.iter().chain(&cv.prior_scales).find(|k| !(k.is_finite() && **k > 0.0)) {
        return Err(IdentifyError::InvalidOptions(format!("prior scale must be a positive number, got {k}")));
    }
    let posture = posture_groups(measurements);
    let groups = posture.len();
    let (first, k) = deal_folds(&posture, measurements.len(), cv.folds, cv.seed);
    let repeats = if k >= groups { 1 } else { cv.repeats.max(1) };
    let splits: Vec<Vec<usize>> = std::iter::once(first)
        .chain(
            (1..repeats as u64)
                .map(|r| deal_folds(&posture, measurements.len(), cv.folds, cv.seed.wrapping_add(r)).0),
        )
        .collect();
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
        // strongest priors first, then weaker, then (when asked) none
        let scales: Vec<Option<f64>> = match cv.prior_scale {
            Some(k) => vec![Some(k)],
            None if robot_params && unusable.is_none() => {
                let mut v: Vec<f64> = cv.prior_scales.clone();
                v.sort_by(f64::total_cmp);
                v.dedup();
                let none = (cv.unregularised || v.is_empty()).then_some(None);
                v.into_iter().map(Some).chain(none).collect()
            }
            None => vec![None],
        };
        for scale in scales {
            candidates.push(score_candidate(
                start,
                measurements,
                options,
                cv,
                *set,
                &params,
                scale,
                unusable.clone(),
                &splits,
                k,
            )?);
        }
    }
    choose(candidates, k, repeats, groups, cv.seed)
}

/// Fits one candidate on all rows and on every fold of every split.
#[allow(clippy::too_many_arguments)]
fn score_candidate(
    start: &Model,
    measurements: &[Measurement],
    options: &IdentifyOptions,
    cv: &CvOptions,
    set: GenericSet,
    params: &ParamSet,
    prior_scale: Option<f64>,
    unusable: Option<String>,
    splits: &[Vec<usize>],
    k: usize,
) -> Result<CandidateScore, IdentifyError> {
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
        capped_fits: 0,
        rejected: unusable,
    };
    if score.rejected.is_some() {
        return Ok(score);
    }
    let fold_options = IdentifyOptions {
        accept_iteration_cap: true,
        ..cv.fit_options(prior_scale, start, measurements, params, options)
    };
    match identify(start, measurements, params, &fold_options) {
        Ok(fit) => {
            score.train_rms_mm = fit.residual_stats.rms;
            score.condition_number = fit.condition_number;
        }
        Err(e) => {
            score.rejected = Some(format!("fit on all rows: {e}"));
            return Ok(score);
        }
    }
    let mut fold_mse = Vec::with_capacity(k * splits.len());
    'splits: for fold_of in splits {
        for fold in 0..k {
            let train: Vec<Measurement> =
                measurements.iter().zip(fold_of).filter(|(_, f)| **f != fold).map(|(m, _)| *m).collect();
            let test: Vec<usize> = (0..measurements.len()).filter(|i| fold_of[*i] == fold).collect();
            if test.is_empty() {
                continue;
            }
            let train_options = IdentifyOptions {
                row_weights: fold_options
                    .row_weights
                    .as_ref()
                    .map(|w| w.iter().zip(fold_of).filter(|(_, f)| **f != fold).map(|(w, _)| *w).collect()),
                ..fold_options.clone()
            };
            match identify(start, &train, params, &train_options) {
                Ok(fit) => {
                    score.capped_fits += usize::from(!fit.converged);
                    fold_mse.push(mean_squared(&fit.model, measurements, &test, options)?);
                }
                Err(e) => {
                    score.rejected = Some(format!("fold {}: {e}", fold + 1));
                    break 'splits;
                }
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

/// The lowest cross-validated score among the scored candidates.
fn choose(
    candidates: Vec<CandidateScore>,
    k: usize,
    repeats: usize,
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
    let c = &candidates[best];
    let runner_up = scored
        .iter()
        .copied()
        .filter(|i| *i != best)
        .min_by(|a, b| candidates[*a].cv_mse_mm2.total_cmp(&candidates[*b].cv_mse_mm2));
    let split = if k >= groups {
        format!("leave-one-posture-out over {groups} postures")
    } else {
        format!("{repeats} × {k}-fold")
    };
    let mut reason =
        format!("`{}` has the lowest cross-validated error ({:.4} mm RMS, {split})", c.label(), c.cv_rms_mm);
    if let Some(r) = runner_up {
        let r = &candidates[r];
        let within = r.cv_mse_mm2 - c.cv_mse_mm2 <= c.cv_se_mm2;
        reason.push_str(&format!(
            "; next `{}` {:.4} mm{}",
            r.label(),
            r.cv_rms_mm,
            if within {
                " (within one standard error: the data barely separate them; the lowest score is kept, never the smallest model)"
            } else {
                ""
            }
        ));
    }
    Ok(CvSelection { candidates, chosen: best, reason, folds: k, repeats, groups, seed })
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
    /// the prior standard deviation of every identified parameter (internal units, same order
    /// as `params`; infinite: free); empty when the fit had no priors
    pub prior_sigmas: Vec<f64>,
    /// the directions the data excite less than the prior widths do (the fit's own priors, or
    /// the realistic widths ×1 when it had none), weakest first
    pub weak_directions: Vec<crate::WeakDirection>,
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
    let options = IdentifyOptions {
        point_distances: design.distances.clone(),
        plane_distances: design.plane_distances.clone(),
        ..options.clone()
    };
    let trimmed = spec.trim();
    let canonical = nominal.is_meca500_on_guide();
    let canonical_fit = canonical
        && design.free_positions.is_empty()
        && (trimmed == "default" || vatcal_core::canonical::is_canonical_only_set(trimmed));
    if canonical_fit {
        let params = resolve_spec(spec, nominal, measurements, design)?;
        let fit_options = named_set_options(cv, nominal, measurements, &params, options);
        return Ok(CalibrationStart {
            init: None,
            start: nominal.clone(),
            params,
            selection: None,
            fit_options,
        });
    }
    // the registration set does not need the distances (and unknown points may still coincide
    // at their placeholder coordinates, where a distance row is undefined)
    let points_only = DataDesign {
        free_positions: design.free_positions.clone(),
        free_planes: design.free_planes.clone(),
        ..DataDesign::default()
    };
    let registration = generic_set(nominal, measurements, GenericSet::Registration, &points_only)?;
    let init = initialise(nominal, measurements, &InitOptions::for_params(&registration))?;
    let start = init.model.clone();
    let (params, selection, fit_options) = if trimmed == "default" {
        let sel = cross_validate_sets(&start, measurements, design, &options, cv)?;
        let params = sel.chosen().params.clone();
        let fit_options = IdentifyOptions {
            accept_iteration_cap: true,
            ..cv.fit_options(sel.chosen().prior_scale, &start, measurements, &params, &options)
        };
        (params, Some(sel), fit_options)
    } else {
        let params = resolve_spec(spec, &start, measurements, design)?;
        let fit_options = named_set_options(cv, &start, measurements, &params, options);
        (params, None, fit_options)
    };
    Ok(CalibrationStart { init: Some(init), start, params, selection, fit_options })
}

impl CalibrationStart {
    /// The [`Calibration`] of a final fit `fit` made from this start on `measurements`: its
    /// priors, and the weak directions against them (or against the realistic widths ×1 of `cv`
    /// when the fit had none) at the data σ `sigma_mm` (the fit's σ̂, or a robust one).
    ///
    /// # Errors
    /// The errors of [`crate::weak_directions`].
    pub fn finish(
        &self,
        fit: Identification,
        measurements: &[Measurement],
        cv: &CvOptions,
        sigma_mm: f64,
    ) -> Result<Calibration, IdentifyError> {
        let prior_sigmas = self.fit_options.priors.clone().unwrap_or_default();
        let reference = if prior_sigmas.is_empty() {
            PriorSpec::new(cv.widths, 1.0).sigmas(&self.start, measurements, &self.params)
        } else {
            prior_sigmas.clone()
        };
        let sigma_mm = if sigma_mm.is_finite() && sigma_mm > 0.0 { sigma_mm } else { fit.sigma_hat_mm };
        let weak_directions = crate::weak::weak_directions(
            &fit.model,
            measurements,
            &fit.params,
            &reference,
            &self.fit_options.weights,
            sigma_mm,
        )?;
        Ok(Calibration {
            init: self.init.clone(),
            params: self.params.clone(),
            selection: self.selection.clone(),
            fit,
            prior_sigmas,
            weak_directions,
        })
    }
}

/// The options of a named set's fit: `options` as given, or with the priors of `cv` when it
/// fixes a prior scale ([`CvOptions::prior_scale`]: `--prior-scale`, `--prior`) and then the
/// iteration cap of [`cv_iteration_cap`] (the first of the σ̂ re-weighting rounds weighs the
/// priors by the a-priori σ and can crawl along the weak directions).
fn named_set_options(
    cv: &CvOptions,
    start: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
    options: IdentifyOptions,
) -> IdentifyOptions {
    match cv.prior_scale {
        // the priors and the cap of the default path; the condition cap stays the caller's
        Some(k) => IdentifyOptions {
            max_condition_number: options.max_condition_number,
            ..cv.fit_options(Some(k), start, measurements, params, &options)
        },
        None => options,
    }
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
    let sigma_mm = fit.sigma_hat_mm;
    prepared.finish(fit, measurements, cv, sigma_mm)
}
