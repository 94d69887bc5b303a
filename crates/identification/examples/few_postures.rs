//! Few-posture benchmark of the identification default (issue 29): does the default fitted
//! from 35 postures in a sub-range of the joints extrapolate to the whole range?
//!
//! Per case (robot, seed) a hidden truth (joint-zero offsets of tens of mrad, mm of link
//! errors, mrad of twists, gravity compliance of a few mrad), an unknown instrument (a
//! motion-capture frame metres away at a random rotation, one marker 50–100 mm from the nominal
//! TCP, 0.1 mm of noise per axis), 35 training postures in the middle 50 % of every joint's
//! range and 300 noise-free held-out postures over the whole range. Scored through the public
//! API ([`vatcal_identification::calibrate`]): the default, each nested set without priors, and
//! `kinematic+compliance` with priors at a grid of fixed scales (the best of which, chosen with
//! hindsight on the held-out postures, is the yardstick). `docs/few-postures-benchmark.md`
//! describes the protocol and the measured numbers.
//!
//! ```text
//! cargo run --release -p vatcal-identification --example few_postures -- [cases] [seed_base] [out.json]
//! ```
//!
//! `cases` per robot (default 6), seeds `seed_base ..= seed_base + cases − 1` (default 1).

use std::time::Instant;

use nalgebra::{Rotation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use serde_json::{Value, json};
use vatcal_core::cell::{Inertials, LinkInertial, ToolInertial};
use vatcal_core::{Axis, CellFile, JointKind, JointVector, Measurement, ParamId};
use vatcal_identification::{CvOptions, IdentifyOptions, calibrate};
use vatcal_kinematics::Model;
use vatcal_observability::sets::{DataDesign, GenericSet};

// =============================================================================================
// FROZEN GENERATOR v1 — do not change; it scores the method.
//
// Everything from here to "END OF FROZEN GENERATOR v1" defines the benchmark's cases: the
// robots, the hidden truths, the instrument, the postures and the measurements. It uses only
// the model's own accessors (`param`, `set_param`, `tcp_position`, `gravity_torques`) and its
// own seeded streams (ChaCha8 + Box–Muller), not the simulator's perturbation helpers, so that
// a change elsewhere in the workspace cannot change the cases. A different generator is a new
// version (v2) with its own table of numbers, never an edit of this one.
// =============================================================================================

/// Version of the generator (reported in the JSON and the doc).
const GENERATOR_VERSION: &str = "v1";

/// Joint-zero offsets σ \[rad\].
const THETA_OFFSET_SIGMA_RAD: f64 = 0.015;
/// MDH lengths a, d σ \[mm\].
const LENGTH_SIGMA_MM: f64 = 1.0;
/// Twists alpha and Hayati beta σ \[rad\].
const TWIST_SIGMA_RAD: f64 = 0.003;
/// Target of the largest gravity deflection of any joint over the held-out range \[rad\]:
/// compliances are `u_j × TARGET / τ_max` with `u_j ~ U(0.5, 1.5)`.
const DEFLECTION_TARGET_RAD: f64 = 0.003;
/// Postures on which the largest gravity torque `τ_max` of the nominal is searched.
const TORQUE_SEARCH_POSTURES: usize = 500;
/// Marker distance from the nominal TCP 1 \[mm\]: uniform in this range, uniform direction.
const MARKER_RANGE_MM: (f64, f64) = (50.0, 100.0);
/// Instrument-frame distance \[mm\]: uniform in this range, uniform direction.
const FRAME_DISTANCE_MM: (f64, f64) = (1500.0, 3500.0);
/// Measurement noise per axis \[mm\] (motion capture).
const NOISE_SIGMA_MM: f64 = 0.1;
/// Training postures (middle 50 % of every joint's range, capped at one turn).
const TRAIN_POSTURES: usize = 35;
/// Fraction of the (one-turn-capped) range that the training postures span, centred.
const TRAIN_FRACTION: f64 = 0.5;
/// Held-out postures (whole range, limits shrunk by `HELD_OUT_MARGIN` of the range per side).
const HELD_OUT_POSTURES: usize = 300;
const HELD_OUT_MARGIN: f64 = 0.05;

/// The robots of the benchmark.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Robot {
    /// `fixtures/ur5e.toml` (6R, Universal Robots' DH table and masses)
    Ur5e,
    /// `fixtures/real/mukca/cells/iiwa14.toml` (7R, KUKA iiwa 14 from its URDF; the URDF has
    /// no inertials, the generator adds approximate ones: [`iiwa14_inertials`])
    Iiwa14,
}

impl Robot {
    const ALL: [Robot; 2] = [Robot::Ur5e, Robot::Iiwa14];

    fn name(self) -> &'static str {
        match self {
            Robot::Ur5e => "ur5e",
            Robot::Iiwa14 => "iiwa14",
        }
    }

    fn tag(self) -> u64 {
        match self {
            Robot::Ur5e => 1,
            Robot::Iiwa14 => 2,
        }
    }

    /// The nominal model the user has (and the truth is built from).
    fn nominal(self) -> Result<Model, Box<dyn std::error::Error>> {
        let path = match self {
            Robot::Ur5e => concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"),
            Robot::Iiwa14 => {
                concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/real/mukca/cells/iiwa14.toml")
            }
        };
        let mut cell = CellFile::load(path)?;
        if self == Robot::Iiwa14 {
            cell.inertials = iiwa14_inertials();
        }
        Ok(Model::from_cell(&cell)?)
    }
}

/// Approximate link masses of a KUKA LBR iiwa 14 R820 (about 30 kg in all, link 1..7:
/// 5.8, 6.4, 3.5, 3.5, 3.5, 1.8, 0.3 kg) with centres of mass placed by hand along the links
/// in the MDH frames of the imported cell (frame 3 and 5 origins at the elbow and the wrist,
/// the upper arm along +y2, the forearm along +y4), and a 0.5 kg marker mount on the flange.
/// Not the manufacturer's data: they only have to make the gravity torques (and so the
/// compliance deflections) of a 30 kg arm, the same for the nominal and the truth.
fn iiwa14_inertials() -> Inertials {
    let link =
        |frame: u8, mass_kg: f64, com_mm: [f64; 3]| LinkInertial { frame, urdf_link: None, mass_kg, com_mm };
    Inertials {
        links: vec![
            link(1, 5.8, [0.0, -30.0, -120.0]),
            link(2, 6.4, [0.0, 80.0, 0.0]),
            link(3, 3.5, [0.0, 30.0, -90.0]),
            link(4, 3.5, [0.0, 70.0, 0.0]),
            link(5, 3.5, [0.0, 20.0, -140.0]),
            link(6, 1.8, [0.0, -20.0, 0.0]),
            link(7, 0.3, [0.0, 0.0, -130.0]),
        ],
        tool: ToolInertial { frame: 7, mass_kg: 0.5, com_mm: [0.0, 0.0, -20.0] },
    }
}

/// One benchmark case: what the user has (nominal, training rows) and what judges the fit
/// (noise-free held-out points in the instrument frame).
struct Case {
    robot: Robot,
    seed: u64,
    nominal: Model,
    truth: Model,
    /// training rows: TCP 1 (the marker), instrument frame, noise
    train: Vec<Measurement>,
    /// held-out postures and the truth's marker position in the instrument frame (no noise)
    held_out: Vec<(JointVector, Vector3<f64>)>,
    /// the largest gravity deflection of the truth over the torque-search postures \[rad\]
    max_deflection_rad: f64,
    marker_offset_mm: f64,
    frame_distance_mm: f64,
    frame_angle_rad: f64,
}

/// An independent seeded stream per (robot, seed, purpose) (splitmix64 of the three).
fn stream(robot: Robot, seed: u64, purpose: u64) -> ChaCha8Rng {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(robot.tag().wrapping_mul(0xD1B5_4A32_D192_ED03))
        .wrapping_add(purpose.wrapping_mul(0x8CB9_2BA7_2F3D_8DD7));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ChaCha8Rng::seed_from_u64(z ^ (z >> 31))
}

/// A standard normal draw (Box–Muller, one value per pair of uniforms).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1 = 1.0 - rng.random::<f64>(); // (0, 1]
    let u2 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

fn unit_vector(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(normal(rng), normal(rng), normal(rng));
        if v.norm() > 1e-6 {
            return v.normalize();
        }
    }
}

/// Joint values uniform in `[lo, hi]` per joint.
fn posture(rng: &mut ChaCha8Rng, ranges: &[(f64, f64)]) -> JointVector {
    let mut q = JointVector::zeros(ranges.len());
    for (k, (lo, hi)) in ranges.iter().enumerate() {
        q[k] = uniform(rng, *lo, *hi);
    }
    q
}

/// The held-out ranges: the limits shrunk by `HELD_OUT_MARGIN` of the range on each side.
fn held_out_ranges(model: &Model) -> Vec<(f64, f64)> {
    model
        .joint_limits()
        .iter()
        .map(|(lo, hi)| (lo + HELD_OUT_MARGIN * (hi - lo), hi - HELD_OUT_MARGIN * (hi - lo)))
        .collect()
}

/// The training ranges: the middle `TRAIN_FRACTION` of every joint's range, where a revolute
/// joint's range is first capped at one turn around its centre (the UR5e's ±360° would
/// otherwise give ±180°, every angle, and nothing to extrapolate to).
fn train_ranges(model: &Model) -> Vec<(f64, f64)> {
    model
        .joint_limits()
        .iter()
        .zip(model.joint_kinds())
        .map(|((lo, hi), kind)| {
            let c = 0.5 * (lo + hi);
            let (lo, hi) = match kind {
                JointKind::Revolute => (lo.max(c - std::f64::consts::PI), hi.min(c + std::f64::consts::PI)),
                _ => (*lo, *hi),
            };
            let half = 0.5 * TRAIN_FRACTION * (hi - lo);
            (c - half, c + half)
        })
        .collect()
}

/// The largest gravity torque of any joint of `model` over `TORQUE_SEARCH_POSTURES` postures
/// of the held-out ranges \[N·m\].
fn largest_torque(model: &Model, rng: &mut ChaCha8Rng) -> f64 {
    let ranges = held_out_ranges(model);
    let mut largest = 0.0f64;
    for _ in 0..TORQUE_SEARCH_POSTURES {
        let q = posture(rng, &ranges);
        for t in model.gravity_torques(&q).iter().take(model.joint_count()) {
            largest = largest.max(t.abs());
        }
    }
    largest
}

/// Builds one case (deterministic in `robot` and `seed`).
fn generate(robot: Robot, seed: u64) -> Result<Case, Box<dyn std::error::Error>> {
    let nominal = robot.nominal()?;
    let n = nominal.joint_count() as u8;
    let mut truth = nominal.clone();

    // geometry: every MDH + Hayati row, in the order alpha, a, beta, theta_offset, d
    let mut rng = stream(robot, seed, 1);
    for i in 1..=n {
        for (id, sigma) in [
            (ParamId::Alpha(i), TWIST_SIGMA_RAD),
            (ParamId::A(i), LENGTH_SIGMA_MM),
            (ParamId::Beta(i), TWIST_SIGMA_RAD),
            (ParamId::ThetaOffset(i), THETA_OFFSET_SIGMA_RAD),
            (ParamId::D(i), LENGTH_SIGMA_MM),
        ] {
            let e = sigma * normal(&mut rng);
            truth.set_param(id, nominal.param(id)? + e)?;
        }
    }

    // compliance of every revolute joint: the largest deflection a few mrad
    let tau_max = largest_torque(&nominal, &mut stream(robot, seed, 2));
    let mut rng = stream(robot, seed, 3);
    for j in 1..=n {
        let u = uniform(&mut rng, 0.5, 1.5);
        if nominal.has_param(ParamId::Compliance(j)) && tau_max > 0.0 {
            truth.set_param(ParamId::Compliance(j), u * DEFLECTION_TARGET_RAD / tau_max)?;
        }
    }
    let mut max_deflection_rad = 0.0f64;
    {
        let ranges = held_out_ranges(&nominal);
        let mut rng = stream(robot, seed, 2);
        for _ in 0..TORQUE_SEARCH_POSTURES {
            let q = posture(&mut rng, &ranges);
            let tau = truth.gravity_torques(&q);
            for j in 1..=n {
                if let Ok(c) = truth.param(ParamId::Compliance(j)) {
                    max_deflection_rad = max_deflection_rad.max((c * tau[j as usize - 1]).abs());
                }
            }
        }
    }

    // the marker: 50–100 mm from the nominal TCP 1
    let mut rng = stream(robot, seed, 4);
    let marker_offset_mm = uniform(&mut rng, MARKER_RANGE_MM.0, MARKER_RANGE_MM.1);
    let offset = unit_vector(&mut rng) * marker_offset_mm;
    let tcp = nominal.tcp(1).ok_or("the nominal model has no TCP 1")? + offset;
    for (axis, v) in Axis::ALL.iter().zip(tcp.iter()) {
        truth.set_param(ParamId::Tcp { id: 1, axis: *axis }, *v)?;
    }

    // the instrument frame y = R x + t: uniform rotation, metres away
    let mut rng = stream(robot, seed, 5);
    let quat =
        nalgebra::Quaternion::new(normal(&mut rng), normal(&mut rng), normal(&mut rng), normal(&mut rng));
    let r: Rotation3<f64> = UnitQuaternion::from_quaternion(quat).to_rotation_matrix();
    let frame_distance_mm = uniform(&mut rng, FRAME_DISTANCE_MM.0, FRAME_DISTANCE_MM.1);
    let t = unit_vector(&mut rng) * frame_distance_mm;
    let frame_angle_rad = UnitQuaternion::from_rotation_matrix(&r).angle();

    // training rows: sub-range, noise in the instrument frame
    let ranges = train_ranges(&nominal);
    let mut rng = stream(robot, seed, 6);
    let mut train = Vec::with_capacity(TRAIN_POSTURES);
    for _ in 0..TRAIN_POSTURES {
        let q = posture(&mut rng, &ranges);
        let noise = Vector3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * NOISE_SIGMA_MM;
        let y = r * truth.tcp_position(&q, 1)? + t + noise;
        train.push(Measurement::tracker(1, q, y));
    }

    // held-out postures: whole range, noise-free
    let ranges = held_out_ranges(&nominal);
    let mut rng = stream(robot, seed, 7);
    let mut held_out = Vec::with_capacity(HELD_OUT_POSTURES);
    for _ in 0..HELD_OUT_POSTURES {
        let q = posture(&mut rng, &ranges);
        held_out.push((q, r * truth.tcp_position(&q, 1)? + t));
    }

    Ok(Case {
        robot,
        seed,
        nominal,
        truth,
        train,
        held_out,
        max_deflection_rad,
        marker_offset_mm,
        frame_distance_mm,
        frame_angle_rad,
    })
}

// =============================================================================================
// END OF FROZEN GENERATOR v1
// =============================================================================================

// The scoring below uses only the public API of vatcal-identification; it may follow changes
// of that API (option names), never change what is measured.

/// The prior scales of the hindsight grid.
const HINDSIGHT_GRID: [f64; 9] = [0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0];

/// Held-out error of one fitted candidate.
struct Scored {
    label: String,
    /// Err: the fit's error message
    outcome: Result<Outcome, String>,
}

struct Outcome {
    mean_mm: f64,
    rms_mm: f64,
    max_mm: f64,
    train_rms_mm: f64,
    n_params: usize,
    condition_number: f64,
    /// the label of the candidate the cross-validation chose (the default only)
    chosen: Option<String>,
    /// its CV table: (label, CV RMS, rejected?)
    cv_table: Vec<(String, f64, Option<String>)>,
}

fn score(case: &Case, label: &str, spec: &str, options: &IdentifyOptions, cv: &CvOptions) -> Scored {
    let outcome = (|| -> Result<Outcome, String> {
        let cal = calibrate(&case.nominal, &case.train, spec, &DataDesign::default(), options, cv)
            .map_err(|e| e.to_string())?;
        let mut sum = 0.0;
        let mut sum2 = 0.0;
        let mut max = 0.0f64;
        for (q, y) in &case.held_out {
            let e = (cal.fit.model.tcp_position(q, 1).map_err(|e| e.to_string())? - y).norm();
            sum += e;
            sum2 += e * e;
            max = max.max(e);
        }
        let n = case.held_out.len() as f64;
        let chosen = cal.selection.as_ref().map(|s| s.chosen().label());
        let cv_table = cal
            .selection
            .as_ref()
            .map(|s| s.candidates.iter().map(|c| (c.label(), c.cv_rms_mm, c.rejected.clone())).collect())
            .unwrap_or_default();
        Ok(Outcome {
            mean_mm: sum / n,
            rms_mm: (sum2 / n).sqrt(),
            max_mm: max,
            train_rms_mm: cal.fit.residual_stats.rms,
            n_params: cal.fit.params.len(),
            condition_number: cal.fit.condition_number,
            chosen,
            cv_table,
        })
    })();
    Scored { label: label.to_string(), outcome }
}

/// Every candidate of one case: `default`, the four nested sets, the hindsight grid.
fn score_case(case: &Case) -> Vec<Scored> {
    let mut out = Vec::new();
    // (a) the library's default, as `vatcal identify --params default` calls it
    out.push(score(case, "default", "default", &IdentifyOptions::default(), &CvOptions::default()));
    // (b) the nested sets, no priors: the fits the cross-validation scores as its candidates
    // without priors (no condition-number cap, which would refuse rather than score them)
    let plain = IdentifyOptions { max_condition_number: f64::INFINITY, ..IdentifyOptions::default() };
    let no_priors = CvOptions { prior_scale: None, prior_scales: Vec::new(), ..CvOptions::default() };
    for set in GenericSet::ALL {
        out.push(score(case, set.name(), set.name(), &plain, &no_priors));
    }
    // (c) kinematic+compliance with priors at fixed scales
    for k in HINDSIGHT_GRID {
        let cv = CvOptions {
            prior_scale: Some(k),
            candidates: vec![GenericSet::KinematicCompliance],
            ..CvOptions::default()
        };
        out.push(score(case, &format!("k+c priors x{k}"), "default", &IdentifyOptions::default(), &cv));
    }
    out
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 { v[m] } else { 0.5 * (v[m - 1] + v[m]) }
}

fn rms_of(s: &Scored) -> f64 {
    s.outcome.as_ref().map_or(f64::NAN, |o| o.rms_mm)
}

fn num(x: f64) -> Value {
    if x.is_finite() { json!(x) } else { Value::Null }
}

/// The names of the candidates compared against the default (the nested sets).
const NESTED: [&str; 4] = ["registration", "joint-offsets", "kinematic", "kinematic+compliance"];

/// What one robot's cases add up to: per candidate label the ratios to the hindsight best,
/// how often the default chose each set, and the two done-means checks counted over cases.
#[derive(Default)]
struct RobotTally {
    /// per candidate label: the ratios over cases
    ratios: Vec<(String, Vec<f64>)>,
    chosen_counts: Vec<(String, usize)>,
    within: usize,
    below: usize,
    n_cases: usize,
}

/// The best of the hindsight grid: its label and held-out RMS (`none`, NaN when all failed).
fn hindsight_best(scored: &[Scored]) -> (String, f64) {
    scored
        .iter()
        .filter(|s| s.label.starts_with("k+c priors"))
        .map(|s| (s.label.clone(), rms_of(s)))
        .filter(|(_, r)| r.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((String::from("none"), f64::NAN))
}

/// The largest distance between the truth's and the nominal's TCP 1 on the held-out postures.
fn truth_max_mm(case: &Case) -> f64 {
    case.held_out
        .iter()
        .filter_map(|(q, _)| {
            Some((case.truth.tcp_position(q, 1).ok()? - case.nominal.tcp_position(q, 1).ok()?).norm())
        })
        .fold(0.0f64, f64::max)
}

/// Prints the case's truth and sizes, and the header of its candidate table.
fn print_case_header(case: &Case, truth_max_mm: f64, seconds: f64) {
    println!(
        "\n{} seed {}: truth max deflection {:.2} mrad, marker {:.1} mm from TCP 1, frame {:.0} mm / {:.2} rad away; \
         {} train rows, {} held out; nominal-vs-truth (same frame) up to {:.1} mm; {:.1} s",
        case.robot.name(),
        case.seed,
        case.max_deflection_rad * 1e3,
        case.marker_offset_mm,
        case.frame_distance_mm,
        case.frame_angle_rad,
        case.train.len(),
        case.held_out.len(),
        truth_max_mm,
        seconds
    );
    println!(
        "  {:<22} {:>6} {:>10} {:>10} {:>10} {:>10} {:>9} {:>8}",
        "candidate", "params", "train RMS", "mean", "RMS", "max", "cond", "ratio"
    );
}

/// Prints one candidate's row of the table and returns its JSON.
fn candidate_row(s: &Scored, ratio: f64) -> Value {
    match &s.outcome {
        Ok(o) => println!(
            "  {:<22} {:>6} {:>10.4} {:>10.4} {:>10.4} {:>10.4} {:>9.2e} {:>8.3}{}",
            s.label,
            o.n_params,
            o.train_rms_mm,
            o.mean_mm,
            o.rms_mm,
            o.max_mm,
            o.condition_number,
            ratio,
            o.chosen.as_ref().map(|c| format!("  (chose `{c}`)")).unwrap_or_default()
        ),
        Err(e) => println!("  {:<22} FAILED: {e}", s.label),
    }
    match &s.outcome {
        Ok(o) => json!({
            "label": s.label, "ok": true, "n_params": o.n_params,
            "train_rms_mm": num(o.train_rms_mm), "held_out_mean_mm": num(o.mean_mm),
            "held_out_rms_mm": num(o.rms_mm), "held_out_max_mm": num(o.max_mm),
            "condition_number": num(o.condition_number), "ratio_to_hindsight_best": num(ratio),
            "chosen": o.chosen,
            "cv": o.cv_table.iter().map(|(l, r, rej)| json!({"label": l, "cv_rms_mm": num(*r), "rejected": rej})).collect::<Vec<_>>(),
        }),
        Err(e) => json!({"label": s.label, "ok": false, "error": e}),
    }
}

impl RobotTally {
    /// Adds one candidate's ratio to the hindsight best.
    fn add_ratio(&mut self, label: &str, ratio: f64) {
        match self.ratios.iter_mut().find(|(l, _)| l == label) {
            Some((_, v)) => v.push(ratio),
            None => self.ratios.push((label.to_string(), vec![ratio])),
        }
    }

    /// Counts the default's choice and its two checks on one case; returns the checks
    /// (default within 10 % of the hindsight best, default below every nested set).
    fn add_case(&mut self, scored: &[Scored], best_rms: f64) -> (bool, bool) {
        let default_rms = rms_of(&scored[0]);
        let chosen =
            scored[0].outcome.as_ref().ok().and_then(|o| o.chosen.clone()).unwrap_or_else(|| "failed".into());
        match self.chosen_counts.iter_mut().find(|(l, _)| *l == chosen) {
            Some((_, c)) => *c += 1,
            None => self.chosen_counts.push((chosen.clone(), 1)),
        }
        let ok_within = default_rms <= 1.1 * best_rms;
        let ok_below = NESTED.iter().all(|name| {
            let r = scored.iter().find(|s| s.label == *name).map_or(f64::NAN, rms_of);
            // a failed nested fit does not count against the default
            !r.is_finite() || default_rms < r
        }) && default_rms.is_finite();
        self.within += usize::from(ok_within);
        self.below += usize::from(ok_below);
        self.n_cases += 1;
        (ok_within, ok_below)
    }
}

/// Generates, scores and prints one case; adds it to `tally` and returns its JSON.
fn run_case(robot: Robot, seed: u64, tally: &mut RobotTally) -> Result<Value, Box<dyn std::error::Error>> {
    let case = generate(robot, seed)?;
    let t0 = Instant::now();
    let scored = score_case(&case);
    let seconds = t0.elapsed().as_secs_f64();
    let (best_label, best_rms) = hindsight_best(&scored);
    let truth_max_mm = truth_max_mm(&case);
    print_case_header(&case, truth_max_mm, seconds);
    let mut cands = Vec::new();
    for s in &scored {
        let ratio = rms_of(s) / best_rms;
        cands.push(candidate_row(s, ratio));
        tally.add_ratio(&s.label, ratio);
    }
    let (ok_within, ok_below) = tally.add_case(&scored, best_rms);
    println!(
        "  hindsight best: {best_label} ({best_rms:.4} mm RMS); default within 10 %: {ok_within}; default below every nested set: {ok_below}"
    );
    Ok(json!({
        "seed": seed, "seconds": seconds,
        "truth": {
            "max_deflection_mrad": case.max_deflection_rad * 1e3,
            "marker_offset_mm": case.marker_offset_mm,
            "frame_distance_mm": case.frame_distance_mm,
            "frame_angle_rad": case.frame_angle_rad,
            "nominal_vs_truth_max_mm": truth_max_mm,
        },
        "hindsight_best": {"label": best_label, "held_out_rms_mm": num(best_rms)},
        "default_within_10_percent": ok_within,
        "default_below_every_nested_set": ok_below,
        "candidates": cands,
    }))
}

/// Runs `cases` cases of `robot` from `seed_base`, prints the medians and the done-means
/// checks; returns the robot's JSON and whether both checks pass on the medians.
fn run_robot(robot: Robot, seed_base: u64, cases: u64) -> Result<(Value, bool), Box<dyn std::error::Error>> {
    let mut tally = RobotTally::default();
    let mut case_json = Vec::new();
    for seed in seed_base..seed_base + cases {
        case_json.push(run_case(robot, seed, &mut tally)?);
    }
    let RobotTally { ratios, chosen_counts, within, below, n_cases } = tally;
    println!("\n{}: median over {n_cases} cases of held-out RMS / hindsight-best RMS", robot.name());
    let medians: Vec<(String, f64)> = ratios.iter().map(|(l, v)| (l.clone(), median(v.clone()))).collect();
    for (l, m) in &medians {
        println!("  {l:<22} {m:>8.3}");
    }
    let default_median = medians[0].1;
    let median_within = default_median <= 1.1;
    let median_below = NESTED.iter().all(|name| {
        medians.iter().find(|(l, _)| l == name).is_none_or(|(_, m)| !m.is_finite() || default_median < *m)
    });
    println!("  default chose: {chosen_counts:?}");
    println!(
        "  done-means checks: default within 10 % of hindsight best: median {median_within}, cases {within}/{n_cases}; \
         default below every nested set: median {median_below}, cases {below}/{n_cases}"
    );
    let json = json!({
        "robot": robot.name(),
        "cases": case_json,
        "median_ratio_to_hindsight_best": medians.iter().map(|(l, m)| json!({"label": l, "median_ratio": num(*m)})).collect::<Vec<_>>(),
        "default_chose": chosen_counts.iter().map(|(l, c)| json!({"label": l, "cases": c})).collect::<Vec<_>>(),
        "checks": {
            "default_within_10_percent_median": median_within,
            "default_within_10_percent_cases": within,
            "default_below_every_nested_set_median": median_below,
            "default_below_every_nested_set_cases": below,
            "cases": n_cases,
        },
    });
    Ok((json, median_within && median_below))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let cases: u64 = args.first().map(|s| s.parse()).transpose()?.unwrap_or(6);
    let seed_base: u64 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(1);
    let out_path = args.get(2).cloned();
    let started = Instant::now();

    println!(
        "few-posture benchmark, generator {GENERATOR_VERSION}: {cases} case(s) per robot, seeds {seed_base}..={}",
        seed_base + cases - 1
    );
    let mut robots_json = Vec::new();
    let mut all_checks = true;
    for robot in Robot::ALL {
        let (json, checks) = run_robot(robot, seed_base, cases)?;
        all_checks &= checks;
        robots_json.push(json);
    }
    let seconds = started.elapsed().as_secs_f64();
    println!("\nboth done-means checks pass on the medians of both robots: {all_checks}; {seconds:.1} s");
    if let Some(path) = out_path {
        let doc = json!({
            "benchmark": "few-postures",
            "generator": GENERATOR_VERSION,
            "cases_per_robot": cases,
            "seed_base": seed_base,
            "hindsight_grid": HINDSIGHT_GRID,
            "robots": robots_json,
            "all_checks_pass": all_checks,
            "seconds": seconds,
        });
        std::fs::write(&path, serde_json::to_string_pretty(&doc)?)?;
        println!("wrote {path}");
    }
    Ok(())
}
