mod common;
use common::*;
use vatcal_core::ParamSet;
use vatcal_discovery::{DiscoverOptions, discover};
#[test]
fn dbg() {
    let s = scenario(11, &[], None, 180);
    for p in [ParamSet::paper34(), ParamSet::geometric()] {
        let d = discover(&nominal(), &s.probe, &p, None, &DiscoverOptions::default()).expect("runs");
        let r = &d.rounds[0];
        eprintln!("== {} params", p.len());
        let mut c: Vec<_> = r.candidates.iter().collect();
        c.sort_by(|a, b| a.label.cmp(&b.label));
        for c in c {
            eprintln!("{:42} novelty {:?} dof {:?} status {:?}", c.label, c.novelty.map(|x| (x * 100.0).round() / 100.0), c.score.map(|s| s.dof), c.status);
        }
    }
}
