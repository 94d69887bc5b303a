//! The start of a run: the first fit, the noise reference (replicates or the instruments), the
//! kind weights, the screening/confirmation split and the folds — the run's [`Context`].

use nalgebra::Vector3;
use vatcal_core::{Measurement, ParamSet};
use vatcal_identification::KindSigmas;
use vatcal_kinematics::Model;

use super::context::{Context, chain_scale};
use super::options::DiscoverOptions;
use super::size::noise_reference;
use crate::DiscoveryError;
use crate::fit::{Fit, fit};
use crate::folds::{screening_split, stratified_folds};
use crate::noise::{NoiseSource, PureError};

/// What the start of a run fixed.
pub(super) struct Setup<'a> {
    /// the run's fixed inputs
    pub(super) ctx: Context<'a>,
    /// the fit of the starting parameter set (weighted by kind when both kinds are present)
    pub(super) current: Fit,
    /// σ of probe and tracker residuals (the reference's, else estimated)
    pub(super) kind_sigmas: KindSigmas,
    /// where the noise reference came from
    pub(super) source: NoiseSource,
    /// the replicates' pure error, when the data has replicates
    pub(super) pure: Option<PureError>,
    /// residuals of the starting fit (lack of fit in the report)
    pub(super) start_residuals: Vec<Vector3<f64>>,
    /// measurements used for screening / for confirmation
    pub(super) split: [usize; 2],
    /// remarks so far
    pub(super) notes: Vec<String>,
}

/// Fits the starting parameter set, fixes the noise reference and the kind weights, splits
/// the data and draws the folds (module docs of [`super`]).
pub(super) fn prepare<'a>(
    start: &Model,
    measurements: &'a [Measurement],
    params: &ParamSet,
    validation: Option<&'a [Measurement]>,
    options: &DiscoverOptions,
) -> Result<Setup<'a>, DiscoveryError> {
    let mut notes = Vec::new();
    let mut options = options.clone();
    // separate σ for probe and tracker residuals (inverse-variance weights)
    let first = fit(start, measurements, params, &options.identify)?;
    let estimated = KindSigmas::estimate(measurements, &first.residuals, params.len());
    let kinds = start.joint_kinds().to_vec();
    let pure = if options.use_replicates {
        crate::noise::pure_error(measurements, &first.residuals, &kinds, options.replicate_tolerance)
    } else {
        None
    };
    let (reference, source) = noise_reference(pure.as_ref(), options.instrument_sigmas, measurements);
    let known = reference.filter(|k| k.probe_mm.is_some() && k.tracker_mm.is_some());
    let kind_sigmas = known.unwrap_or(estimated);
    let weighted =
        options.weight_by_kind && kind_sigmas.probe_mm.is_some() && kind_sigmas.tracker_mm.is_some();
    let current = if weighted {
        options.identify.weights = kind_sigmas.weights();
        notes.push(weights_note(known.is_some(), source, kind_sigmas));
        fit(start, measurements, params, &options.identify)?
    } else {
        first
    };
    let start_residuals = current.residuals.clone();
    let (screen, confirm_folds, all_folds) = split_and_folds(measurements, &options);
    let split = [screen.len(), measurements.len() - screen.len()];
    let ctx = Context {
        measurements,
        validation,
        all_folds,
        confirm_folds,
        screen,
        options,
        reference,
        saturated_bits: std::sync::atomic::AtomicU64::new(f64::NAN.to_bits()),
        scale: chain_scale(start, measurements)?,
    };
    Ok(Setup { ctx, current, kind_sigmas, source, pure, start_residuals, split, notes })
}

/// The note saying the fits weight probe and tracker rows by their σ.
fn weights_note(known: bool, source: NoiseSource, kind_sigmas: KindSigmas) -> String {
    format!(
        "probe and tracker residuals weighted by their {} sigma ({:.4} / {:.4} mm per axis)",
        match (known, source) {
            (true, NoiseSource::Replicates) => "replicates'",
            (true, _) => "instruments' known",
            (false, _) => "own estimated",
        },
        kind_sigmas.probe_mm.unwrap_or(0.0),
        kind_sigmas.tracker_mm.unwrap_or(0.0)
    )
}

/// The screening measurements, the fold of every confirmation measurement (`None` for
/// screening ones) and the fold of every measurement over all data.
fn split_and_folds(
    measurements: &[Measurement],
    options: &DiscoverOptions,
) -> (Vec<Measurement>, Vec<Option<usize>>, Vec<Option<usize>>) {
    let is_screen = screening_split(measurements, options.screen_fraction, options.seed);
    let screen: Vec<Measurement> =
        measurements.iter().zip(&is_screen).filter(|(_, s)| **s).map(|(m, _)| *m).collect();
    let confirm_idx: Vec<usize> = (0..measurements.len()).filter(|i| !is_screen[*i]).collect();
    let confirm_ms: Vec<Measurement> = confirm_idx.iter().map(|i| measurements[*i]).collect();
    let k = options.folds.max(2);
    let mut confirm_folds = vec![None; measurements.len()];
    for (i, f) in confirm_idx.iter().zip(stratified_folds(&confirm_ms, k, options.seed.wrapping_add(1))) {
        confirm_folds[*i] = Some(f);
    }
    let all_folds = stratified_folds(measurements, k, options.seed).into_iter().map(Some).collect();
    (screen, confirm_folds, all_folds)
}
