//! **The size rule** (module docs of [`super`], step 3): the noise a prediction change is
//! compared with — the noise reference (replicates or the instruments), else σ̂ of the refit or
//! of the round's saturated model, never below the physical floor — and the report's account
//! of it.

use nalgebra::Vector3;
use vatcal_core::effects::EffectSpec;
use vatcal_core::{Measurement, ParamId, ParamSet};
use vatcal_identification::KindSigmas;
use vatcal_observability::assemble_jacobian;

use super::candidate::Candidate;
use super::context::{Context, kind_weight, weigh_rows, weighted_residual};
use super::options::DiscoverOptions;
use crate::fit::Fit;
use crate::linear::{ColumnSpace, unit_columns};
use crate::noise::{NoiseReference, NoiseSource};

/// The held-out z from which the size rule is waived in a test at `z_required`: only
/// without a noise reference (module docs of [`crate::noise`]).
pub(super) fn strong_z(ctx: &Context<'_>, z_required: f64) -> Option<f64> {
    ctx.reference.is_none().then(|| ctx.options.strong_z_factor * z_required.max(1.0))
}

/// Per-axis noise the size rule compares a prediction change with: the noise reference of
/// a weight-1 row (probe σ when the data has probe rows, else tracker σ; from replicates
/// or the instruments, [`crate::noise`]) when there is one, else [`Context::sigma_hat`] of
/// the fit.
pub(super) fn noise_sigma(ctx: &Context<'_>, f: &Fit, ms: &[Measurement], rank: usize) -> f64 {
    let known = ctx.reference.and_then(|k| {
        let has_probe = ms.iter().any(|m| matches!(m.target, vatcal_core::Target::Probe { .. }));
        if has_probe { k.probe_mm } else { k.tracker_mm }
    });
    let sigma = match known {
        Some(s) if s > 0.0 && s.is_finite() => s,
        _ => {
            let own = ctx.sigma_hat(f, ms, rank);
            let sat = f64::from_bits(ctx.saturated_bits.load(std::sync::atomic::Ordering::Relaxed));
            if sat.is_finite() && sat > 0.0 { own.min(sat) } else { own }
        }
    };
    sigma.max(ctx.options.noise_floor_mm)
}

/// The physical floor of the noise for the size rule of `effects` \[mm per axis\]:
/// [`DiscoverOptions::noise_floor_mm`], and for corrections of fixture coordinates (effects
/// driven by the TCP or the calibration position: a ball or socket off its CMM value) at least
/// the fixtures' stated CMM uncertainty [`DiscoverOptions::cmm_sigma_mm`] — a coordinate
/// correction within the CMM's own uncertainty is not a missing physical effect (the reported
/// prediction uncertainty already includes it, `CmmUncertainty`).
pub(super) fn physical_floor_mm(effects: &[(EffectSpec, Vec<ParamId>)], opts: &DiscoverOptions) -> f64 {
    let fixture = !effects.is_empty()
        && effects.iter().all(|(s, _)| {
            matches!(
                crate::catalog::driver_of(s),
                crate::location::Driver::Tcp | crate::location::Driver::Position
            )
        });
    if fixture { opts.noise_floor_mm.max(opts.cmm_sigma_mm) } else { opts.noise_floor_mm }
}

/// σ̂ per axis of the saturated linear model: the residual of the current fit with the
/// current parameters' and every scored candidate's directions projected out, over its
/// degrees of freedom (`None` when fewer than a quarter of the residuals stay free).
pub(super) fn saturated_sigma(
    current: &Fit,
    candidates: &[Candidate],
    j0: &faer::Mat<f64>,
    ctx: &Context<'_>,
) -> Option<f64> {
    let mut all: Vec<ParamId> = Vec::new();
    for c in candidates.iter().filter(|c| c.score.is_some()) {
        for p in &c.new_params {
            if !all.contains(p) {
                all.push(*p);
            }
        }
    }
    let w = ctx.options.identify.weights;
    let mut z = assemble_jacobian(&current.model, ctx.measurements, &ParamSet(all)).ok()?;
    weigh_rows(&mut z, ctx.measurements, &w);
    let stacked = faer::Mat::from_fn(j0.nrows(), j0.ncols() + z.ncols(), |r, c| {
        if c < j0.ncols() { j0[(r, c)] } else { z[(r, c - j0.ncols())] }
    });
    let (unit, _) = unit_columns(stacked.as_ref());
    let space = ColumnSpace::of(unit.as_ref()).ok()?;
    let n = j0.nrows();
    let dof = n.checked_sub(space.rank())?;
    if 4 * dof < n {
        return None;
    }
    let r = weighted_residual(current, ctx.measurements, &w);
    let rss: f64 = space.project_out_vec(&r).iter().map(|v| v * v).sum();
    Some((rss / dof as f64).sqrt())
}

/// The noise reference per kind: the replicates' pure error where the data has enough of it,
/// else the instruments' stated noise; `None` unless every kind in the data has one.
pub(super) fn noise_reference(
    pure: Option<&crate::noise::PureError>,
    stated: Option<KindSigmas>,
    ms: &[Measurement],
) -> (Option<KindSigmas>, NoiseSource) {
    let from_pure = pure.map(|p| p.sigmas).unwrap_or_default();
    let stated = stated.unwrap_or_default();
    let merged = KindSigmas {
        probe_mm: from_pure.probe_mm.or(stated.probe_mm),
        tracker_mm: from_pure.tracker_mm.or(stated.tracker_mm),
    };
    if !crate::noise::covers(&merged, ms) {
        return (None, NoiseSource::Estimated);
    }
    let used_pure = from_pure.probe_mm.is_some() || from_pure.tracker_mm.is_some();
    (Some(merged), if used_pure { NoiseSource::Replicates } else { NoiseSource::Instrument })
}

/// The report's account of the noise reference (lack-of-fit tests of the starting and the
/// final fit when the data has replicates).
pub(super) fn describe_noise(
    source: NoiseSource,
    reference: Option<KindSigmas>,
    pure: Option<crate::noise::PureError>,
    start_residuals: &[Vector3<f64>],
    start_params: usize,
    last: &Fit,
    ctx: &Context<'_>,
) -> NoiseReference {
    use crate::noise::{lack_of_fit, lack_of_fit_sentence};
    let opts = &ctx.options;
    let ms = ctx.measurements;
    let kinds = last.model.joint_kinds().to_vec();
    let w = opts.identify.weights;
    let lof = |r: &[Vector3<f64>], p: usize| {
        lack_of_fit(ms, r, p, &kinds, opts.replicate_tolerance, |m| kind_weight(m, &w))
    };
    let lack_of_fit_start = lof(start_residuals, start_params);
    let lack_of_fit_final = lof(&last.residuals, last.params.len());
    let um = |s: Option<f64>| s.map_or("-".to_string(), |v| format!("{:.1} um", 1e3 * v));
    let sigmas = reference.unwrap_or_default();
    let per_kind = format!("probe {} / tracker {} per axis", um(sigmas.probe_mm), um(sigmas.tracker_mm));
    let mut text = match (source, &pure) {
        (NoiseSource::Replicates, Some(p)) => format!(
            "noise reference: pure error of {} replicate groups ({} measurements, {} dof): {per_kind}. It holds no model error, so the size rule (prediction change above sqrt(3) sigma) does not shrink while effects are missing.",
            p.groups, p.replicated, p.dof
        ),
        (NoiseSource::Instrument, _) | (NoiseSource::Replicates, None) => format!(
            "noise reference: the instruments' stated noise ({}): {per_kind}. The size rule compares prediction changes with sqrt(3) sigma of it; if the statement is too low, small real effects are added, if too high, they are called negligible.",
            opts.instrument_noise_origin.as_deref().unwrap_or("given by the caller")
        ),
        (NoiseSource::Estimated, _) => format!(
            "noise reference: none (no replicates in the data, no instrument noise recorded in the file or given): the size rule compares with sigma-hat, which contains the effects still missing: the lower of the refit's and that of the round's saturated linear model (every scored candidate's directions projected out, so only what no candidate describes is left in it), and the rule is waived for an effect whose held-out improvement is at least {} times the round's z. Effects that are real but only moderately significant may be called negligible; record the noise in the file (`# vatcal-noise: probe_sigma_mm=...`), repeat some poses, or pass --probe-sigma-mm / --tracker-sigma-mm.",
            opts.strong_z_factor
        ),
    };
    if let Some(p) = &pure
        && source != NoiseSource::Replicates
    {
        text.push_str(&format!(
            " ({} replicate groups with {} dof were found, too few to estimate every kind's sigma.)",
            p.groups, p.dof
        ));
    }
    if let (Some(stated), NoiseSource::Replicates) = (opts.instrument_sigmas, source) {
        text.push_str(&format!(
            " The stated instrument noise (probe {} / tracker {}) was not used: the replicates measure it on these data.",
            um(stated.probe_mm),
            um(stated.tracker_mm)
        ));
    }
    let floor = opts.noise_floor_mm;
    if floor > 0.0 {
        let below: Vec<&str> = [("probe", sigmas.probe_mm), ("tracker", sigmas.tracker_mm)]
            .into_iter()
            .filter(|(_, v)| v.is_some_and(|v| v < floor))
            .map(|(k, _)| k)
            .collect();
        text.push_str(&format!(
            " Physical floor: {:.2} um per axis (--noise-floor-mm): no reference, stated or estimated, is taken below it, and no effect whose predictions change by less than sqrt(3) times it is added{}.",
            1e3 * floor,
            if below.is_empty() {
                String::new()
            } else {
                format!(" (the {} reference is below it: the floor is used)", below.join(" and "))
            }
        ));
    }
    if let Some(l) = &lack_of_fit_start {
        text.push_str(&format!(" Starting model: {}.", lack_of_fit_sentence(l)));
    }
    if let Some(l) = &lack_of_fit_final {
        text.push_str(&format!(" Final model: {}.", lack_of_fit_sentence(l)));
    }
    NoiseReference {
        source,
        floor_mm: opts.noise_floor_mm,
        sigmas,
        pure_error: pure,
        lack_of_fit_start,
        lack_of_fit_final,
        stated: opts.instrument_sigmas,
        explanation: text,
    }
}
