//! **Plausibility**: an identified value beyond its bound (the user's, or the canonical one
//! scaled to the chain) refuses the candidate.

use vatcal_core::ParamId;
use vatcal_core::canonical::bounds::{ScaledBound, scaled_bound};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::ParamUnit;

use super::context::Context;

/// The plausibility bound of `id`: the user's override of its effect, else the larger of
/// the canonical bound and the one scaled to the chain.
fn bound(ctx: &Context<'_>, id: &ParamId) -> Option<ScaledBound> {
    let kind = vatcal_core::effects::kind_of_param(id)?;
    if let Some(v) = ctx.options.bound_overrides.get(kind.name()) {
        let (value, unit) = match id.unit() {
            ParamUnit::Rad => (v.to_radians(), "deg"),
            ParamUnit::Mm => (*v, "mm"),
            _ => (*v, ""),
        };
        return Some(ScaledBound { value, text: format!("{v} {unit} (set by the user)") });
    }
    scaled_bound(id, vatcal_core::effects::bound_of(id), &ctx.scale)
}

/// Checks the identified changes of an effect's parameters against their bounds (a
/// compliance must also be positive). Returns why it is implausible.
pub(super) fn plausibility(
    ctx: &Context<'_>,
    spec: &EffectSpec,
    changes: &[(ParamId, f64)],
) -> Result<(), String> {
    // a profile's bound applies to its excursion, not to its coefficients
    let named: Vec<(ParamId, f64, String)> =
        spec.effect().and_then(|e| e.bounded_magnitudes(spec, changes)).unwrap_or_else(|| {
            changes.iter().map(|(id, c)| (*id, *c, format!("{} of {}", id.name(), spec.label()))).collect()
        });
    for (id, change, name) in &named {
        if let ParamId::Compliance(j) = id
            && *change <= 0.0
        {
            return Err(format!("c_{j} came out {change:.3e} rad/(N*m): a joint cannot stiffen under load"));
        }
        if let Some(b) = bound(ctx, id)
            && change.abs() > b.value
        {
            let shown = if id.unit() == ParamUnit::Rad {
                format!("{:.3e} deg", change.to_degrees())
            } else {
                format!("{change:.3e}")
            };
            return Err(format!("{name} changed by {shown}: more than the plausible {}", b.text));
        }
    }
    Ok(())
}
