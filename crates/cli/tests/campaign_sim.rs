//! `vatcal campaign` as a real child process against the simulated cell served over TCP by
//! `vatcal-sim-cell` (ephemeral ports on 127.0.0.1, time scale 1000):
//!
//! * the "done means": `vatcal plan --seed 3` → campaign `--operator auto` → every
//!   planned measurement in `measurements.csv` → `vatcal identify` → predictions agree with
//!   the in-process demo of the same seed within 10 µm mean;
//! * `kill -9` in the middle, then `--resume`: the same measurements as an uninterrupted run;
//! * a dropped connection: a one-line error naming the device, and `--resume` loses nothing.
//!
//! Small plan sizes (40 orientations × 4 guide steps, 40 measurements) keep each test short.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use vatcal_core::CellFile;
use vatcal_demo::{DemoOptions, DemoSizes, run_demo};
use vatcal_kinematics::Model;
use vatcal_sim_cell::{Device, Ports, SimCell, SimCellOptions};

const FIXTURE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml");

fn vatcal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vatcal")).args(args).output().expect("run vatcal")
}

fn ok(o: &Output) -> String {
    let stdout = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(o.status.success(), "stdout:\n{stdout}\nstderr:\n{}", String::from_utf8_lossy(&o.stderr));
    stdout
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn start_cell(seed: u64) -> SimCell {
    let options = SimCellOptions {
        ports: Ports::ephemeral(),
        time_scale: 1000.0,
        ..SimCellOptions::paper(seed).expect("built-in cell")
    };
    SimCell::start(options).expect("sim-cell")
}

/// A devices file pointing at the running cell.
fn devices_file(cell: &SimCell, dir: &Path) -> PathBuf {
    let a = cell.addrs();
    let text = format!(
        "arm = {{ kind = \"meca500\", address = \"{}\", monitoring = \"{}\" }}\n\
         guide = {{ kind = \"zaber\", tcp = \"{}\" }}\n\
         gauges = [\n  {{ kind = \"sylvac\", tcp = \"{}\" }},\n  {{ kind = \"sylvac\", tcp = \"{}\" }},\n  {{ kind = \"sylvac\", tcp = \"{}\" }},\n]\n\
         sim_control = {{ tcp = \"{}\" }}\n",
        a.meca500_control, a.meca500_monitoring, a.zaber, a.gauges[0], a.gauges[1], a.gauges[2], a.control
    );
    let path = dir.join("devices.toml");
    std::fs::write(&path, text).expect("write devices file");
    path
}

fn plan(seed: u64, dir: &Path) -> PathBuf {
    let out = dir.join("plan");
    let seed = seed.to_string();
    ok(&vatcal(&[
        "plan",
        "--model",
        FIXTURE,
        "--seed",
        &seed,
        "--orientations",
        "40",
        "--guide-steps",
        "4",
        "--count",
        "40",
        "--out",
        s(&out),
        "--quiet",
    ]));
    out
}

/// Number of `measure` rows of the plan's tour.
fn planned_measurements(plan: &Path) -> usize {
    let tour = std::fs::read_to_string(plan.join("tour.csv")).expect("tour");
    tour.lines().filter(|l| l.split(',').nth(1) == Some("measure")).count()
}

fn campaign_args<'a>(devices: &'a Path, plan: &'a Path, out: &'a Path) -> Vec<&'a str> {
    vec![
        "campaign",
        "--devices",
        s(devices),
        "--plan",
        s(plan),
        "--out",
        s(out),
        "--operator",
        "auto",
        "--quiet",
    ]
}

/// Data rows of a measurements CSV without the `time_s` column (wall-clock time differs from
/// run to run; everything else must not).
fn rows_without_time(csv: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let t = header.iter().position(|h| *h == "time_s").expect("time_s column");
    lines
        .map(|l| {
            l.split(',').enumerate().filter(|(k, _)| *k != t).map(|(_, v)| v).collect::<Vec<_>>().join(",")
        })
        .collect()
}

/// Measurement records in a journal so far.
fn journaled_measurements(journal: &Path) -> usize {
    std::fs::read_to_string(journal).map_or(0, |t| t.matches("\"outcome\":\"measured\"").count())
}

#[test]
fn campaign_over_tcp_identifies_the_same_cell_as_the_demo() {
    let dir = tempfile::tempdir().expect("tmp");
    let cell = start_cell(3);
    let devices = devices_file(&cell, dir.path());
    let plan = plan(3, dir.path());
    let run = dir.path().join("run");
    let t0 = Instant::now();
    let stdout = ok(&vatcal(&campaign_args(&devices, &plan, &run)));
    let campaign_s = t0.elapsed().as_secs_f64();
    eprintln!("{stdout}campaign wall time {campaign_s:.1} s");
    assert!(stdout.contains("arm: meca500 at") && stdout.contains("gauge 3: sylvac over tcp"), "{stdout}");
    assert!(stdout.contains("guide: homed"), "{stdout}");
    let planned = planned_measurements(&plan);
    assert_eq!(rows_without_time(&run.join("measurements.csv")).len(), planned, "every planned measurement");
    assert!(campaign_s < 60.0, "the campaign took {campaign_s:.1} s");

    let calibrated = run.join("calibrated.toml");
    ok(&vatcal(&[
        "identify",
        "--model",
        FIXTURE,
        "--measurements",
        s(&run.join("measurements.csv")),
        "--out",
        s(&calibrated),
    ]));
    let over_tcp = Model::from_cell(&CellFile::load(&calibrated).expect("toml")).expect("model");

    let demo_dir = dir.path().join("demo");
    let mut opts = DemoOptions::new(3).expect("built-in cell");
    opts.sizes = DemoSizes { orientations: 40, guide_steps: 4, count: 40, random_poses: 60, slices: 20 };
    // the sim-cell above runs `SimCellOptions::paper` = the `ideal` truth: the paper-like
    // truth's thermal channel follows wall-clock time × K over TCP but virtual time in process
    opts.truth = vatcal_demo::TruthSpec::Ideal;
    let demo = run_demo(&opts, &demo_dir, &mut |_| {}).expect("demo");
    let in_process = &demo.identification.model;
    // predictions over the workspace: the demo's random validation poses, every TCP
    let poses = vatcal_io::read_tracker_measurements(demo_dir.join("validation_random.csv"), in_process)
        .expect("validation poses");
    let mut diffs = Vec::new();
    for m in &poses {
        for tcp in in_process.tcp_ids() {
            let a = over_tcp.tcp_position(&m.q, tcp).expect("fk");
            let b = in_process.tcp_position(&m.q, tcp).expect("fk");
            diffs.push((a - b).norm());
        }
    }
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let max = diffs.iter().copied().fold(0.0, f64::max);
    eprintln!("over TCP vs in-process demo (seed 3): mean {:.2} µm, max {:.2} µm", mean * 1e3, max * 1e3);
    assert!(mean < 0.010, "predictions differ by {:.2} µm on average", mean * 1e3);
}

#[test]
fn kill_9_then_resume_gives_the_measurements_of_an_uninterrupted_run() {
    let dir = tempfile::tempdir().expect("tmp");
    let plan = plan(5, dir.path());
    let planned = planned_measurements(&plan);

    // uninterrupted, on its own fresh cell
    let reference = {
        let cell = start_cell(5);
        let devices = devices_file(&cell, &dir.path().join("."));
        let out = dir.path().join("reference");
        ok(&vatcal(&campaign_args(&devices, &plan, &out)));
        rows_without_time(&out.join("measurements.csv"))
    };
    assert_eq!(reference.len(), planned);

    let cell = start_cell(5);
    let devices = devices_file(&cell, dir.path());
    let out = dir.path().join("killed");
    let mut child = Command::new(env!("CARGO_BIN_EXE_vatcal"))
        .args(campaign_args(&devices, &plan, &out))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    let journal = out.join("campaign.journal");
    let deadline = Instant::now() + Duration::from_secs(120);
    while journaled_measurements(&journal) < planned / 3 {
        assert!(Instant::now() < deadline, "the child recorded too few measurements");
        assert!(child.try_wait().expect("wait").is_none(), "the child ended before it was killed");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().expect("SIGKILL");
    child.wait().expect("reap");
    let before = journaled_measurements(&journal);
    assert!(before < planned, "killed after the end ({before} of {planned})");
    eprintln!("killed after {before} of {planned} measurements");

    let mut args = campaign_args(&devices, &plan, &out);
    let fresh = vatcal(&args);
    assert!(!fresh.status.success(), "an existing journal without --resume must be refused");
    assert!(String::from_utf8_lossy(&fresh.stderr).contains("--resume"));
    args.push("--resume");
    let stdout = ok(&vatcal(&args));
    assert!(stdout.contains("resumed at step"), "{stdout}");
    assert_eq!(rows_without_time(&out.join("measurements.csv")), reference);
}

#[test]
fn a_dropped_connection_stops_with_one_line_naming_the_device_and_resume_loses_nothing() {
    let dir = tempfile::tempdir().expect("tmp");
    let plan = plan(7, dir.path());
    let planned = planned_measurements(&plan);
    let cell = start_cell(7);
    let devices = devices_file(&cell, dir.path());
    let out = dir.path().join("run");
    let child = Command::new(env!("CARGO_BIN_EXE_vatcal"))
        .args(campaign_args(&devices, &plan, &out))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let journal = out.join("campaign.journal");
    let deadline = Instant::now() + Duration::from_secs(120);
    while journaled_measurements(&journal) < planned / 2 {
        assert!(Instant::now() < deadline, "the child recorded too few measurements");
        std::thread::sleep(Duration::from_millis(5));
    }
    cell.drop_connections(Device::Guide);
    let o = child.wait_with_output().expect("wait");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "the campaign must stop");
    let error: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error: ")).collect();
    assert_eq!(error.len(), 1, "{stderr}");
    assert!(error[0].contains("zaber guide") && error[0].contains("--resume"), "{}", error[0]);
    let before = journaled_measurements(&journal);
    assert!(before < planned);

    let mut args = campaign_args(&devices, &plan, &out);
    args.push("--resume");
    ok(&vatcal(&args));
    let rows = rows_without_time(&out.join("measurements.csv"));
    assert_eq!(rows.len(), planned, "nothing lost, nothing duplicated");
    // the measured (position, tcp) sequence is the plan's
    let tour = std::fs::read_to_string(plan.join("tour.csv")).expect("tour");
    let planned_ids: Vec<String> = tour
        .lines()
        .filter(|l| l.split(',').nth(1) == Some("measure"))
        .map(|l| l.split(',').skip(2).take(2).collect::<Vec<_>>().join(","))
        .collect();
    let measured_ids: Vec<String> =
        rows.iter().map(|r| r.split(',').take(2).collect::<Vec<_>>().join(",")).collect();
    assert_eq!(measured_ids, planned_ids);
}
