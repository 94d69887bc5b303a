//! The whole simulated calibration, end to end. The first test runs the paper's sizes (500
//! orientations × 10 guide steps, 40 measurements, 573 random validation poses, 300 slices:
//! about 4 s in the dev profile); the determinism test runs small ones four times.

use std::path::Path;

use vatcal_core::CellFile;
use vatcal_demo::{DemoOptions, DemoOutcome, DemoSizes, run_demo};
use vatcal_kinematics::Model;

fn options(seed: u64, sizes: DemoSizes) -> DemoOptions {
    let mut o = DemoOptions::new(seed).expect("built-in cell");
    o.sizes = sizes;
    // these tests check the noise floor: a truth with nothing outside the 34 parameters
    o.truth = vatcal_demo::TruthSpec::Ideal;
    // the discovery stage is tested on the paper-like truth in `discovery.rs`
    o.discovery = false;
    o
}

fn run(seed: u64, sizes: DemoSizes, out: &Path) -> DemoOutcome {
    run_demo(&options(seed, sizes), out, &mut |_| {}).expect("demo")
}

#[test]
fn the_demo_calibrates_the_virtual_cell_to_the_noise_floor() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = run(11, DemoSizes::default(), dir.path());
    let nominal = out.validation("nominal").expect("nominal");
    let calibrated = out.validation("calibrated").expect("calibrated");
    let (nr, cr) = (&nominal.random.stats, &calibrated.random.stats);
    let (np, cp) = (
        &nominal.path.as_ref().expect("nominal path").tip_stats,
        &calibrated.path.as_ref().expect("calibrated path").tip_stats,
    );
    eprintln!("random poses: nominal {} | calibrated {}", nr.one_line(), cr.one_line());
    eprintln!("printing path: nominal {} | calibrated {}", np.one_line(), cp.one_line());
    assert_eq!((nr.n, np.n), (573, 300));
    // the nominal model is off by one or two millimetres, like the paper's cell ...
    assert!((0.5..3.5).contains(&nr.mean), "nominal random-pose mean {} mm", nr.mean);
    assert!((0.5..3.5).contains(&np.mean), "nominal path mean {} mm", np.mean);
    // ... the calibrated one is at the noise floor of the simulated tracker (20 µm, 3σ) and
    // robot (5 µm): ~12-15 µm mean
    assert!(cr.mean < 0.025 && cr.p95 < 0.04, "calibrated random-pose errors {}", cr.one_line());
    assert!(cp.mean < 0.03 && cp.p95 < 0.05, "calibrated path errors {}", cp.one_line());
    assert!(nr.mean / cr.mean > 30.0 && np.mean / cp.mean > 30.0);
    // oracle: the calibrated model predicts the true positions at the validation poses (no
    // tracker noise here: FK of the hidden truth)
    let cal = &out.identification.model;
    let poses = &out.report.validation.models[0].random.errors_mm;
    assert_eq!(poses.len(), 573);
    let report = std::fs::read_to_string(dir.path().join("validation_random.csv")).expect("csv");
    let tracker = vatcal_io::read_tracker_measurements(dir.path().join("validation_random.csv"), cal)
        .unwrap_or_else(|e| panic!("{e}\n{report}"));
    let worst = tracker
        .iter()
        .map(|m| {
            let p_cal = cal.tcp_position(&m.q, m.tcp).expect("fk");
            let p_true = out.truth.tcp_position(&m.q, m.tcp).expect("fk");
            (p_cal - p_true).norm()
        })
        .fold(0.0, f64::max);
    assert!(worst < 0.02, "calibrated vs true positions differ by up to {worst} mm");
    // the report folder
    for f in &out.files {
        assert!(dir.path().join(f).is_file(), "{} missing", f.display());
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).expect("json"))
            .expect("parse");
    assert_eq!(json["format"], "vatcal-demo-report/1");
    assert_eq!(json["validation"]["models"][1]["label"], "calibrated");
    let back =
        Model::from_cell(&CellFile::load(dir.path().join("calibrated.toml")).expect("toml")).expect("model");
    for m in tracker.iter().take(20) {
        let d = back.tcp_position(&m.q, m.tcp).expect("fk") - cal.tcp_position(&m.q, m.tcp).expect("fk");
        assert!(d.norm() < 1e-9, "calibrated.toml reproduces the identified model");
    }
    let probe =
        vatcal_io::read_probe_measurements(dir.path().join("measurements.csv"), cal).expect("measurements");
    assert_eq!(probe.len(), out.report.campaign.measurements);
    assert!(probe.len() >= 38, "{} probe measurements", probe.len());
    let summary = std::fs::read_to_string(dir.path().join("summary.md")).expect("summary");
    assert!(summary.contains("1.272") && summary.contains("0.220") && summary.contains("paper"), "{summary}");
}

#[test]
fn the_same_seed_gives_the_same_report() {
    let sizes = DemoSizes { orientations: 40, guide_steps: 4, count: 40, random_poses: 30, slices: 40 };
    let (a, b, c) = (
        tempfile::tempdir().expect("tmp"),
        tempfile::tempdir().expect("tmp"),
        tempfile::tempdir().expect("tmp"),
    );
    let first = run(5, sizes.clone(), a.path());
    let second = run(5, sizes.clone(), b.path());
    assert_eq!(first.report, second.report);
    let read = |d: &Path, f: &str| std::fs::read(d.join(f)).expect("read");
    for f in [
        "report.json",
        "measurements.csv",
        "validation_random.csv",
        "calibrated.toml",
        "printing_path_errors.csv",
    ] {
        assert!(read(a.path(), f) == read(b.path(), f), "{f} differs between two runs with the same seed");
    }
    // running again into the same folder starts afresh and gives the same numbers
    let again = run(5, sizes.clone(), a.path());
    assert_eq!(again.report, first.report);
    // another seed: another hidden truth, other numbers
    let other = run(6, sizes, c.path());
    assert_ne!(
        other.report.validation.models[0].random.stats,
        first.report.validation.models[0].random.stats
    );
}

/// Any chain through the same pipeline on its own virtual cell (`--quick` sizes, the ideal
/// truth, no discovery): a simulated arm with the chain's joints and no guide, every planned
/// measurement centred by the campaign, the calibrated model at the devices' noise floor on
/// the tracker's random poses, no printing path.
fn any_chain_demo(fixture: &str, seed: u64) {
    let path = format!("{}/../../fixtures/{fixture}", env!("CARGO_MANIFEST_DIR"));
    let mut o = DemoOptions::new(seed).expect("built-in cell");
    o.nominal = CellFile::load(&path).expect("fixture");
    o.nominal_source = fixture.into();
    o = o.quick();
    o.truth = vatcal_demo::TruthSpec::Ideal;
    o.discovery = false;
    let dir = tempfile::tempdir().expect("tmp");
    let out = run_demo(&o, dir.path(), &mut |line| eprintln!("{fixture}: {line}")).expect("demo");
    let r = &out.report;
    eprintln!("{fixture}:\n{}", out.comparison_table());
    assert_eq!((r.campaign.measurements, r.campaign.skipped), (40, 0), "every planned pose measured");
    assert!(r.campaign.final_offset_mean_mm < 0.005);
    assert!(r.compensation.is_none(), "no printing path on {fixture}");
    let nominal = out.validation("nominal").expect("nominal");
    let calibrated = out.validation("calibrated").expect("calibrated");
    assert!(nominal.path.is_none() && calibrated.path.is_none());
    let (nr, cr) = (&nominal.random.stats, &calibrated.random.stats);
    // at most one in twenty random poses dropped for want of a collision-free path
    assert!((190..=200).contains(&nr.n), "{} random poses", nr.n);
    // tracker noise 20 µm (3σ) per axis: a perfect model has a mean error of about 11 µm
    let floor = 0.02 / 3.0 * (8.0 / std::f64::consts::PI).sqrt();
    assert!(nr.mean > 0.3, "{fixture}: nominal {} mm", nr.mean);
    assert!(cr.mean < 3.0 * floor, "{fixture}: calibrated {} mm (floor {floor:.4})", cr.mean);
    let csv = std::fs::read_to_string(dir.path().join("measurements.csv")).expect("measurements.csv");
    let header = csv.lines().next().expect("header");
    assert!(header.starts_with("position,tcp,q1,q2,q3,q4,q5,q6,time_s"), "{header}");
    assert!(header.contains("dir1,dir2,dir3,dir4,dir5,dir6") && !header.contains("q7"), "{header}");
}

#[test]
fn any_chain_demo_calibrates_the_ur5e_fixture() {
    any_chain_demo("ur5e.toml", 1);
}

#[test]
fn any_chain_demo_calibrates_the_meca500_table_fixture() {
    any_chain_demo("meca500-table.toml", 1);
}
