mod common;
use common::*;
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::{Axis, EffectParam};
use vatcal_core::{ParamId, ParamSet};
use vatcal_discovery::{DiscoverOptions, discover};
#[test]
fn dbg() {
    let k = 42u64; // index of the case in the sweep? compute below
    let _ = k;
    for seed in [1000u64 + 34, 2000, 2001, 2002] {
        let hidden = [Hidden { spec: EffectSpec::GuideAngular { order: 1 }, values: vec![(ParamId::Effect(EffectParam::GuideAngular { axis: Axis::Y, order: 1 }), 15.0 * 1.5e-6)] }];
        let s = scenario(seed, &hidden, None, 180);
        let d = discover(&nominal(), &s.probe, &ParamSet::paper34(), Some(&s.validation), &DiscoverOptions::default()).expect("runs");
        for r in &d.rounds {
            eprintln!("seed {seed} round {} thr {:.2}: {}", r.index, r.ln_threshold / std::f64::consts::LN_10, r.decision);
            for c in r.candidates.iter().take(6) {
                eprintln!("   {:40} nov {:.2} LM {:?} status {:?} refit {:?}", c.label, c.novelty.unwrap_or(0.0), c.score.map(|s| (s.statistic, s.dof, s.ln_p_value / std::f64::consts::LN_10)), c.status, c.refit.as_ref().map(|e| (e.comparison.delta_bic, e.comparison.f_ln_p_value/ std::f64::consts::LN_10, e.cv_before.rms, e.cv_after.rms)));
            }
        }
    }
}
