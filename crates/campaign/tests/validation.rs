//! The validation campaign on the virtual cell.

mod common;

use std::time::Instant;

use common::{SimDevices, nominal, paper_cell, quiet_config};
use vatcal_campaign::validation::{ValidationPlanOptions, build_validation_plan, evaluate};
use vatcal_campaign::Campaign;
use vatcal_core::CellFile;
use vatcal_planning::CellGeometry;

fn geometry() -> CellGeometry {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture");
    CellGeometry::from_cell(&cell).expect("geometry")
}

#[test]
fn explore() {
    let nominal = nominal();
    let cell = paper_cell(5);
    let truth = cell.truth();
    let t0 = Instant::now();
    let opts = ValidationPlanOptions::default();
    let plan = build_validation_plan(&nominal, &geometry(), &[("nominal", &nominal), ("truth", &truth)], &opts)
        .expect("plan");
    eprintln!("plan {:?} steps {} rrt {}", t0.elapsed(), plan.campaign.steps.len(), plan.rrt_legs);
    eprintln!("path start q {:?}", plan.path_runs[0].joints[0].to_mm_deg());
    let t0 = Instant::now();
    let dir = tempfile::tempdir().expect("tmp");
    let mut d = SimDevices::of(&cell);
    let config = vatcal_campaign::CampaignConfig { sync_journal_each_step: false, ..quiet_config() };
    let mut campaign = Campaign::new(d.devices(), &nominal, config);
    let records = plan.run(&mut campaign, dir.path().join("v.journal")).expect("run");
    eprintln!("run {:?}", t0.elapsed());
    let smrs: Vec<_> = nominal.tcp_ids().into_iter().map(|id| (id, nominal.tcp(id).expect("tcp"))).collect();
    let res = evaluate(&records, &plan.slices, &[("nominal", &nominal), ("truth", &truth)], &smrs).expect("eval");
    for r in &res {
        eprintln!("{} random {}", r.label, r.random.stats.one_line());
        if let Some(p) = &r.path {
            eprintln!("{} path tip {}", r.label, p.tip_stats.one_line());
            eprintln!("{} path plate {}", r.label, p.plate_stats.one_line());
        }
    }
}

#[test]
#[ignore]
fn diag() {
    use vatcal_campaign::validation::{PrintingPathOptions, printing_path};
    use vatcal_campaign::validation::printing::{PrintingJointRules, plan_printing_joints};
    use vatcal_planning::collision::{CollisionChecker, ProbeState};
    use vatcal_planning::ik::{RefineOptions, ToolPoseIk};
    use vatcal_planning::motion::{JointBounds, SingularityMargins};
    let nominal = nominal();
    let g = geometry();
    let checker = CollisionChecker::new(&nominal, &g, 2.0).expect("c");
    let bounds = JointBounds::new(&nominal, 5.0, 5.0).expect("b");
    let ik = ToolPoseIk::new(&nominal, RefineOptions::default()).expect("ik");
    let rules = PrintingJointRules { bounds: &bounds, singularity: SingularityMargins::default(), checker: &checker, max_joint_step_rad: 2f64.to_radians(), guide_candidates: 11 };
    for y in [-60.0, -30.0, 0.0, 30.0, 60.0] {
      for x in [-40.0, -15.0, 20.0] {
        for z in [20.0, 50.0] {
          for off in [130.0, 160.0, 200.0] {
            let opts = PrintingPathOptions { start_mm: [x, y, z], plate_offset_mm: off, ..Default::default() };
            let slices = printing_path(&opts).expect("p");
            let mut counts = [0; 4];
            for q1 in (0..=28).map(|k| 5.0 + 10.0 * k as f64) {
                for q in ik.solve_at_guide(q1, &slices[0].tool_pose) {
                    counts[0] += 1;
                    if !bounds.contains(&q) { continue; }
                    counts[1] += 1;
                    if !SingularityMargins::default().clear(&nominal, &nominal.chain(&q)) { continue; }
                    counts[2] += 1;
                    if checker.check(&q, ProbeState::Absent).is_none() { counts[3] += 1; }
                }
            }
            let t0 = std::time::Instant::now();
            let ok = plan_printing_joints(&nominal, &slices, &rules).map(|j| format!("{:?}", j[0].to_mm_deg().map(|v| v.round()))).unwrap_or_else(|e| e.to_string());
            eprintln!("x {x} y {y} z {z} off {off}: {counts:?} {:?} {ok}", t0.elapsed());
          }
        }
      }
    }
}
