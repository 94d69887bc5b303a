use vatcal_core::CellFile;
use vatcal_kinematics::Model;
use vatcal_planning::candidates::*;
use vatcal_planning::collision::*;
use vatcal_planning::geometry::*;

#[test]
fn scratch() {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml")).unwrap();
    let model = Model::from_cell(&cell).unwrap();
    let g = CellGeometry::from_cell(&cell).unwrap();
    let checker = CollisionChecker::new(&model, &g, 2.0).unwrap();
    let n: usize = std::env::var("NOR").ok().and_then(|s| s.parse().ok()).unwrap_or(50);
    let cone: f64 = std::env::var("CONE").ok().and_then(|s| s.parse().ok()).unwrap_or(60.0);
    let opts = CandidateOptions { orientations: n, cone_half_angle_deg: cone, ..Default::default() };
    let t = std::time::Instant::now();
    let set = generate_candidates(&model, &checker, &opts).unwrap();
    println!("{:?} in {:?}", set.counts, t.elapsed());
    for p in [1,2,3] { for tc in [1,2,3] {
        println!("pos {p} tcp {tc}: {}", set.candidates.iter().filter(|c| c.position==p && c.tcp==tc).count());
    }}
    let mut per_step = vec![0; 10];
    for c in &set.candidates { per_step[c.guide_step]+=1; }
    println!("per guide step {per_step:?}");
}
