//! The noise reference of the size rule (background.md §9.3).
//!
//! An effect that is real but moves the predictions by less than the measurement noise is not
//! worth a parameter. "The noise" must not contain the effects still missing: σ̂ of an
//! incomplete model does, and with several effects missing it calls real effects negligible.
//! In order of preference the reference is
//!
//! 1. **replicates** in the data ([`pure_error`]): measurements of the same TCP at the same
//!    pose and target, approached from the same side (equal `dir{i}`), repeated. The pure-error
//!    sum of squares `SS_PE = Σ_groups Σ_i ‖r_i − r̄_g‖²` on `3 Σ(m_g − 1)` degrees of freedom
//!    holds no model error at all (the model predicts the same point for every member of a
//!    group), and the **lack-of-fit test** `F = (SS_LOF/df_LOF)/(SS_PE/df_PE)` tells model
//!    error from noise before any candidate is named ([`LackOfFit`]);
//! 2. the instruments' **known noise**: recorded with the measurements (a `# vatcal-noise:`
//!    line, `vatcal_io::metadata`) or given by the caller
//!    ([`crate::DiscoverOptions::instrument_sigmas`]);
//! 3. **none**: σ̂ of each fit is the only number, an upper bound of the noise while effects
//!    are missing. The size rule then still compares with it, but an effect whose held-out
//!    improvement is far above its uncertainty (`z ≥ strong_z_factor · z_r`) is added
//!    whatever σ̂ says: it is real and it matters on data the fit never saw.

use nalgebra::Vector3;
use serde::Serialize;
use vatcal_core::{JointKind, Measurement, Target};
use vatcal_identification::KindSigmas;

use crate::distributions::f_ln_sf;

/// Where the noise the size rule compares with comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseSource {
    /// pure error of replicated measurements in the data
    Replicates,
    /// the instruments' known noise (recorded in the measurement file or given by the caller)
    Instrument,
    /// σ̂ of each fit (contains the effects still missing; the size rule is waived for effects
    /// whose held-out improvement is far above its uncertainty)
    Estimated,
}

/// Pure error of the replicated measurements.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PureError {
    /// replicate groups (two or more measurements each)
    pub groups: usize,
    /// measurements in them
    pub replicated: usize,
    /// degrees of freedom `3 Σ(m_g − 1)` (all kinds)
    pub dof: usize,
    /// σ per axis of the probe / tracker rows from their own groups \[mm\] (`None` when that
    /// kind has fewer than [`MIN_PURE_ERROR_DOF`] degrees of freedom)
    pub sigmas: KindSigmas,
}

/// Fewest degrees of freedom of pure error a kind's σ is estimated from (3 replicate pairs).
pub const MIN_PURE_ERROR_DOF: usize = 9;

/// Lack-of-fit test of a fit against the pure error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LackOfFit {
    /// `(SS_LOF/df_LOF) / (SS_PE/df_PE)`
    pub f: f64,
    /// degrees of freedom of lack of fit (`N − p − df_PE`)
    pub df_lof: usize,
    /// degrees of freedom of pure error
    pub df_pe: usize,
    /// `ln P(F_{df_LOF, df_PE} > F)`: very negative = the model misses something
    pub ln_p_value: f64,
}

/// The noise reference of a run and what follows from it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseReference {
    /// which reference the size rule used
    pub source: NoiseSource,
    /// the physical floor of every reference, σ per axis \[mm\]
    /// ([`crate::DiscoverOptions::noise_floor_mm`])
    pub floor_mm: f64,
    /// σ per axis of a probe / tracker row the size rule compares with \[mm\] (`None` with
    /// [`NoiseSource::Estimated`]: σ̂ of each refit)
    pub sigmas: KindSigmas,
    /// the pure error of the replicates, when the data has any
    pub pure_error: Option<PureError>,
    /// lack-of-fit test of the starting fit against the pure error
    pub lack_of_fit_start: Option<LackOfFit>,
    /// lack-of-fit test of the final fit against the pure error
    pub lack_of_fit_final: Option<LackOfFit>,
    /// the instruments' stated noise, when given (even if replicates were preferred)
    pub stated: Option<KindSigmas>,
    /// one paragraph for people: the reference and what follows from it
    pub explanation: String,
}

/// Tolerances below which two measurements count as the same pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplicateTolerance {
    /// revolute joints \[rad\]
    pub revolute_rad: f64,
    /// prismatic joints \[mm\]
    pub prismatic_mm: f64,
}

impl Default for ReplicateTolerance {
    /// 0.01° and 0.01 mm: a re-centred probe pose moves by µm, distinct poses by degrees.
    fn default() -> Self {
        Self { revolute_rad: 0.01f64.to_radians(), prismatic_mm: 0.01 }
    }
}

/// Groups of replicated measurements (indices, each group ≥ 2 members, in data order): same
/// TCP, same target (probe position; or tracker), same recorded approach directions, joint
/// values within `tol`. `kinds` are the chain's joint kinds.
pub fn replicate_groups(ms: &[Measurement], kinds: &[JointKind], tol: ReplicateTolerance) -> Vec<Vec<usize>> {
    let same = |a: &Measurement, b: &Measurement| {
        let target = match (a.target, b.target) {
            (Target::Probe { position: p }, Target::Probe { position: q }) => p == q,
            (Target::Tracker { .. }, Target::Tracker { .. }) => true,
            _ => false,
        };
        target
            && a.tcp == b.tcp
            && a.context.dir == b.context.dir
            && a.q.len() == b.q.len()
            && a.q.iter().zip(b.q.iter()).enumerate().all(|(k, (x, y))| {
                let t = match kinds.get(k) {
                    Some(JointKind::Prismatic) => tol.prismatic_mm,
                    _ => tol.revolute_rad,
                };
                (x - y).abs() <= t
            })
    };
    let mut group_of: Vec<Option<usize>> = vec![None; ms.len()];
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for i in 0..ms.len() {
        if group_of[i].is_some() {
            continue;
        }
        let mut g = vec![i];
        for j in i + 1..ms.len() {
            if group_of[j].is_none() && same(&ms[i], &ms[j]) {
                g.push(j);
            }
        }
        if g.len() >= 2 {
            for k in &g {
                group_of[*k] = Some(groups.len());
            }
            groups.push(g);
        }
    }
    groups
}

/// Pure-error sums of squares of `residuals` over `groups`: (probe SS [mm²], probe dof, tracker
/// SS, tracker dof).
fn pure_error_sums(
    ms: &[Measurement],
    residuals: &[Vector3<f64>],
    groups: &[Vec<usize>],
) -> [(f64, usize); 2] {
    let mut out = [(0.0, 0usize); 2];
    for g in groups {
        let mean = g.iter().map(|i| residuals[*i]).sum::<Vector3<f64>>() / g.len() as f64;
        let ss: f64 = g.iter().map(|i| (residuals[*i] - mean).norm_squared()).sum();
        let k = usize::from(matches!(ms[g[0]].target, Target::Tracker { .. }));
        out[k].0 += ss;
        out[k].1 += 3 * (g.len() - 1);
    }
    out
}

/// The pure error of the replicates in `ms` from the residuals of any fit (the members of a
/// group share their model error, so it cancels); `None` without replicates.
pub fn pure_error(
    ms: &[Measurement],
    residuals: &[Vector3<f64>],
    kinds: &[JointKind],
    tol: ReplicateTolerance,
) -> Option<PureError> {
    let groups = replicate_groups(ms, kinds, tol);
    if groups.is_empty() {
        return None;
    }
    let [(ss_p, df_p), (ss_t, df_t)] = pure_error_sums(ms, residuals, &groups);
    let sigma = |ss: f64, df: usize| (df >= MIN_PURE_ERROR_DOF).then(|| (ss / df as f64).sqrt());
    Some(PureError {
        groups: groups.len(),
        replicated: groups.iter().map(Vec::len).sum(),
        dof: df_p + df_t,
        sigmas: KindSigmas { probe_mm: sigma(ss_p, df_p), tracker_mm: sigma(ss_t, df_t) },
    })
}

/// Lack-of-fit test of a fit with `rank` identified directions whose residuals are
/// `residuals`, rows weighted by `weight(m)` (the kind weights of the fit); `None` without
/// enough pure error or lack-of-fit degrees of freedom.
pub fn lack_of_fit(
    ms: &[Measurement],
    residuals: &[Vector3<f64>],
    rank: usize,
    kinds: &[JointKind],
    tol: ReplicateTolerance,
    weight: impl Fn(&Measurement) -> f64,
) -> Option<LackOfFit> {
    let groups = replicate_groups(ms, kinds, tol);
    let weighted: Vec<Vector3<f64>> = ms.iter().zip(residuals).map(|(m, r)| r * weight(m).sqrt()).collect();
    let [(ss_p, df_p), (ss_t, df_t)] = pure_error_sums(ms, &weighted, &groups);
    let (ss_pe, df_pe) = (ss_p + ss_t, df_p + df_t);
    let rss: f64 = weighted.iter().map(|r| r.norm_squared()).sum();
    let df_lof = (3 * ms.len()).checked_sub(rank + df_pe)?;
    if df_pe < MIN_PURE_ERROR_DOF || df_lof == 0 || ss_pe <= 0.0 {
        return None;
    }
    let f = ((rss - ss_pe).max(0.0) / df_lof as f64) / (ss_pe / df_pe as f64);
    Some(LackOfFit { f, df_lof, df_pe, ln_p_value: f_ln_sf(f, df_lof, df_pe) })
}

/// The sigma of the kinds `ms` holds from `k` when every such kind has one.
pub fn covers(k: &KindSigmas, ms: &[Measurement]) -> bool {
    let probe = ms.iter().any(|m| matches!(m.target, Target::Probe { .. }));
    let tracker = ms.iter().any(|m| matches!(m.target, Target::Tracker { .. }));
    let ok = |s: Option<f64>| s.is_some_and(|v| v.is_finite() && v > 0.0);
    (!probe || ok(k.probe_mm)) && (!tracker || ok(k.tracker_mm))
}

/// `1 − P` said in words for a lack-of-fit test.
pub fn lack_of_fit_sentence(l: &LackOfFit) -> String {
    let log10p = l.ln_p_value / std::f64::consts::LN_10;
    let verdict = if log10p < -3.0 {
        "the model misses something the noise cannot explain"
    } else if log10p < -1.3 {
        "borderline: the model may miss something"
    } else {
        "the residual is as small as the noise: nothing systematic is left"
    };
    format!("lack-of-fit F = {:.2} on ({}, {}) dof, log10 p = {log10p:.1}: {verdict}", l.f, l.df_lof, l.df_pe)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::JointVector;

    fn probe(q: [f64; 6], dir: i8) -> Measurement {
        let mut m = Measurement::probe(2, 1, JointVector::from_mm_deg(100.0, q));
        let mut d = [0i8; vatcal_core::MAX_JOINTS];
        d[1..7].fill(dir);
        m.context.dir = Some(d);
        m
    }

    #[test]
    fn replicates_are_grouped_by_pose_target_and_direction() {
        let a = [10.0, 20.0, 30.0, 40.0, 50.0, 60.0];
        let mut a2 = a;
        a2[2] += 0.001; // re-centred: a thousandth of a degree
        let mut far = a;
        far[2] += 1.0;
        let ms = vec![probe(a, 1), probe(far, 1), probe(a2, 1), probe(a, -1), probe(a, -1)];
        let kinds = vatcal_core::MECA500_ON_GUIDE_KINDS;
        let g = replicate_groups(&ms, &kinds, ReplicateTolerance::default());
        assert_eq!(g, vec![vec![0, 2], vec![3, 4]]);
    }

    #[test]
    fn pure_error_ignores_the_shared_model_error_and_lack_of_fit_sees_it() {
        // 12 pairs; each pair shares a model error of 50 µm, the members differ by noise
        let kinds = vatcal_core::MECA500_ON_GUIDE_KINDS;
        let mut ms = Vec::new();
        let mut r = Vec::new();
        let mut state = 7u64;
        let mut noise = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * 0.002 * 3f64.sqrt()
        };
        for k in 0..12 {
            let q = [k as f64 * 7.0, 10.0, 20.0, 30.0, 40.0, 50.0];
            let bias = Vector3::new(0.05, -0.03, 0.02) * if k % 2 == 0 { 1.0 } else { -1.0 };
            for _ in 0..2 {
                ms.push(probe(q, 1));
                r.push(bias + Vector3::new(noise(), noise(), noise()));
            }
        }
        let pe = pure_error(&ms, &r, &kinds, ReplicateTolerance::default()).expect("replicates");
        assert_eq!((pe.groups, pe.replicated, pe.dof), (12, 24, 36));
        let s = pe.sigmas.probe_mm.expect("probe sigma");
        assert!(s > 0.0012 && s < 0.003, "{s}");
        assert!(pe.sigmas.tracker_mm.is_none());
        let lof = lack_of_fit(&ms, &r, 6, &kinds, ReplicateTolerance::default(), |_| 1.0).expect("lof");
        assert!(lof.ln_p_value < -20.0, "{lof:?}");
        // without the shared error: no lack of fit
        let r0: Vec<Vector3<f64>> = (0..r.len()).map(|_| Vector3::new(noise(), noise(), noise())).collect();
        let lof0 = lack_of_fit(&ms, &r0, 0, &kinds, ReplicateTolerance::default(), |_| 1.0).expect("lof");
        assert!(lof0.ln_p_value > -5.0, "{lof0:?}");
    }
}
