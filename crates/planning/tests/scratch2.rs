use std::collections::BTreeMap;
use rand::SeedableRng;
use vatcal_core::CellFile;
use vatcal_kinematics::Model;
use vatcal_planning::candidates::*;
use vatcal_planning::collision::*;
use vatcal_planning::geometry::*;
use vatcal_planning::ik::*;
use vatcal_planning::motion::*;

#[test]
fn tally() {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml")).unwrap();
    let model = Model::from_cell(&cell).unwrap();
    let g = CellGeometry::from_cell(&cell).unwrap();
    let checker = CollisionChecker::new(&model, &g, 2.0).unwrap();
    let ik = ToolPoseIk::new(&model, RefineOptions::default()).unwrap();
    let bounds = JointBounds::new(&model, 5.0, 0.0).unwrap();
    let guide = guide_positions(&model, 10, 5.0).unwrap();
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(3);
    let mut tally: BTreeMap<String, usize> = BTreeMap::new();
    for pos in [1u32,2,3] { for tcp in [1u32,2,3] {
        let t = model.tcp(tcp).unwrap(); let p = model.position(pos).unwrap();
        for _ in 0..30 {
            let r = sample_orientation(&mut rng, &(-t), 60f64.to_radians());
            let target = tool_pose_for_tcp(&r, &t, &p);
            for q in ik.solve(&guide, &target) {
                if !bounds.contains(&q) { continue; }
                let c = checker.check(&q, ProbeState::Measuring{position: pos, tcp});
                if c.is_some() { continue; }
                let mut tt = target; tt.p.z += 30.0;
                let key = match refine_tool_pose(&model, &q, &tt, &RefineOptions::default()) {
                    Err(e) => { let n = ik.solve_at_guide(q.0[0], &tt).len(); let near = ik.solve_at_guide(q.0[0], &tt).iter().map(|a| (a.0.iter().zip(&q.0).map(|(x,y)| (x-y).abs()).fold(0.0,f64::max)).to_degrees()).fold(1e9,f64::min); println!("{e} analytic sols {n} nearest {near:.2} deg; q {:?}", q.to_mm_deg()); "noconv".to_string() },
                    Ok(r) => { let a = r.q;
                        if !bounds.contains(&a) { "limits".into() }
                        else if let Some(c) = checker.check(&a, ProbeState::At{position: pos}) { format!("own {} / {}", c.body, c.other) }
                        else if let Some(c) = checker.check(&a, ProbeState::Everywhere) { format!("other {} / {}", c.body, c.other) }
                        else if !vatcal_planning::paths::segment_is_free(&checker, &a, &q, ProbeState::Measuring{position: pos, tcp}, &Resolution::default()) { "descent".into() }
                        else { "ok".into() } }
                };
                *tally.entry(key).or_default() += 1;
            }
        }
    }}
    for (k, v) in tally { println!("{v:6} {k}"); }
}
