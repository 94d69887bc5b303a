//! Which collision pairs reject the candidate poses of a chain that is not the canonical cell
//! (the check of docs/ARCHITECTURE.md "add a robot"): runs stages 1–3 of the candidate pipeline
//! (the planner's IK — a closed form where the chain has one, else the numerical IK —, limits,
//! singularities) with the `vatcal plan` defaults and, for every solution
//! that reaches the collision stage, counts its first contact (what rejects it), every contact
//! with its depth ([`CollisionChecker::contacts`]) and a class (end effector vs an obstacle —
//! a property of the sampled tool pose, whatever the robot —, arm vs floor, arm vs the other
//! obstacles, self-collision). `SHOW` rejected solutions are printed with their contacts;
//! `PAIRS=1` lists the self-collision pairs tested; `Q_DEG="q1,..,qN;..."` prints the contacts
//! of given joint vectors (degrees, no probe) instead. Meant for all-revolute chains: a
//! prismatic joint is held at 0 mm (the real pipeline steps it over its stroke).
//!
//! ```text
//! cargo run -p vatcal-planning --example collision_breakdown -- fixtures/ur5e.toml 100 [SHOW]
//! ```

use std::collections::BTreeMap;

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use vatcal_core::{CellFile, JointVector, deg_to_rad};
use vatcal_kinematics::{Chain, Model};
use vatcal_planning::candidates::{CandidateOptions, sample_orientation};
use vatcal_planning::collision::{CollisionChecker, Contact, ProbeState};
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::ik::{ModelIk, tool_pose_for_tcp};
use vatcal_planning::motion::JointBounds;

/// Prints the contacts of the joint vectors in `qs` (deg, comma-separated joints,
/// `;`-separated vectors).
fn print_given_joints(
    model: &Model,
    checker: &CollisionChecker<'_>,
    qs: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    for row in qs.split(';') {
        let v: Vec<f64> = row.split(',').map(|x| x.trim().parse::<f64>()).collect::<Result<_, _>>()?;
        let mut q = JointVector::zeros(model.joint_count());
        for (k, x) in v.iter().enumerate() {
            q[k] = x.to_radians();
        }
        let chain = model.chain(&q);
        println!("q = {row}: tool at {:?}", chain.tool.p.as_slice());
        for (c, d) in checker.contacts(&chain, ProbeState::Absent) {
            println!("    {c}: depth {d:.1} mm");
        }
    }
    Ok(())
}

/// The class of a rejected solution from its contacts.
fn contact_class(contacts: &[(Contact, f64)]) -> &'static str {
    let ee = |b: &str| b == "plate" || b == "tool changer" || b.starts_with("ball");
    let obstacle = |o: &str| o == "floor" || o == "tank" || o.starts_with("TriCal") || o == "guide";
    if contacts.iter().any(|(c, _)| ee(&c.body) && obstacle(&c.other)) {
        "end effector vs obstacle (pose-level, any robot)"
    } else if contacts.iter().any(|(c, _)| c.other == "floor") {
        "arm vs floor"
    } else if contacts.iter().any(|(c, _)| obstacle(&c.other)) {
        "arm vs probe / tank / guide"
    } else {
        "self-collision only"
    }
}

/// The counts over every solution that reaches the collision stage.
#[derive(Default)]
struct Tally {
    reached: usize,
    free: usize,
    first: BTreeMap<String, usize>,
    any: BTreeMap<String, usize>,
    depth_max: BTreeMap<String, f64>,
    classes: BTreeMap<&'static str, usize>,
    /// "arm vs floor" solutions whose frame-3 origin (the elbow of a 6R arm) is below z = 0
    elbow_below: usize,
    shown: usize,
}

impl Tally {
    /// Counts one solution `q` (its chain and contacts); prints it while fewer than `show`
    /// rejected solutions have been shown.
    fn add(
        &mut self,
        q: &JointVector,
        chain: &Chain,
        contacts: &[(Contact, f64)],
        at: (u32, u32),
        show: usize,
    ) {
        self.reached += 1;
        if contacts.is_empty() {
            self.free += 1;
            return;
        }
        *self.first.entry(contacts[0].0.to_string()).or_default() += 1;
        let class = contact_class(contacts);
        *self.classes.entry(class).or_default() += 1;
        if class == "arm vs floor" && chain.frames[3].p.z < 0.0 {
            self.elbow_below += 1;
        }
        for (c, d) in contacts {
            *self.any.entry(c.to_string()).or_default() += 1;
            let e = self.depth_max.entry(c.to_string()).or_insert(0.0);
            *e = e.max(*d);
        }
        if self.shown < show {
            self.shown += 1;
            let deg: Vec<String> = q.as_slice().iter().map(|v| format!("{:.1}", v.to_degrees())).collect();
            println!("q = [{}] (position {}, tcp {})", deg.join(", "), at.0, at.1);
            for (c, d) in contacts {
                println!("    {c}: depth {d:.1} mm");
            }
        }
    }

    /// Prints the breakdown.
    fn print(self, path: &str, checker: &CollisionChecker<'_>) {
        println!(
            "{path}: {} solutions reach the collision stage, {} collision-free",
            self.reached, self.free
        );
        println!("rejected solutions by class:");
        for (k, n) in &self.classes {
            println!("  {n:6}  {k}");
        }
        println!("  ({} of the arm-vs-floor ones have frame 3 below z = 0)", self.elbow_below);
        println!("self-collision pairs tested: {}", checker.self_collision_pairs().len());
        if std::env::var("PAIRS").is_ok() {
            for (a, b) in checker.self_collision_pairs() {
                println!("    {a} / {b}");
            }
        }
        let mut rows: Vec<_> = self.first.into_iter().collect();
        rows.sort_by_key(|r| std::cmp::Reverse(r.1));
        println!("first contact (rejects):");
        for (k, n) in rows {
            println!("  {n:6}  {k}");
        }
        let mut rows: Vec<_> = self.any.into_iter().collect();
        rows.sort_by_key(|r| std::cmp::Reverse(r.1));
        println!("any contact:");
        for (k, n) in rows {
            println!("  {n:6}  {k}  (deepest {:.1} mm)", self.depth_max[&k]);
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).map_or("fixtures/ur5e.toml", String::as_str);
    let orientations: usize = args.get(2).map_or(Ok(100), |s| s.parse())?;
    let show: usize = args.get(3).map_or(Ok(0), |s| s.parse())?;
    let cell = CellFile::load(path)?;
    let model = Model::from_cell(&cell)?;
    let geometry = CellGeometry::from_cell(&cell)?;
    let opts = CandidateOptions { orientations, ..CandidateOptions::default() };
    let checker = CollisionChecker::new(&model, &geometry, opts.collision_margin_mm)?;
    if let Ok(qs) = std::env::var("Q_DEG") {
        return print_given_joints(&model, &checker, &qs);
    }
    let ik = ModelIk::closed_form_first(&model, opts.refine, opts.numeric)?;
    let bounds = JointBounds::new(&model, opts.joint_margin_deg, 0.0)?;
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let cone = deg_to_rad(opts.cone_half_angle_deg);
    let mut tally = Tally::default();
    for position in model.position_ids() {
        let p = model.position(position).ok_or("position")?;
        for tcp in model.tcp_ids() {
            let t = model.tcp(tcp).ok_or("tcp")?;
            for _ in 0..orientations {
                let r = sample_orientation(&mut rng, &(-t), cone);
                let target = tool_pose_for_tcp(&r, &t, &p);
                for q in ik.solve_at_guide(0.0, &target) {
                    if !bounds.contains(&q) {
                        continue;
                    }
                    let chain = model.chain(&q);
                    if !opts.singularity.clear(&model, &chain) {
                        continue;
                    }
                    let contacts = checker.contacts(&chain, ProbeState::Measuring { position, tcp });
                    tally.add(&q, &chain, &contacts, (position, tcp), show);
                }
            }
        }
    }
    tally.print(path, &checker);
    Ok(())
}
