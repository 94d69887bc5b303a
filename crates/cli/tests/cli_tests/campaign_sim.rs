//! `vatcal campaign` as a real child process against the simulated cell served over TCP
//! (ephemeral ports on 127.0.0.1, time scale 1000):
//!
//! * the "done means" with real child processes only, as a user types it: `vatcal plan
//!   --seed 3`, `vatcal sim-cell --seed 3` (default, paper-like truth; its `listening …` lines give the
//!   ports; the devices file is `fixtures/sim-cell-devices.toml` with those ports), campaign
//!   `--operator auto` → every planned measurement in `measurements.csv` → `vatcal identify`
//!   → predictions agree with the in-process demo of the same seed within 10 µm mean;
//! * `kill -9` in the middle, then `--resume`: the same measurements as an uninterrupted run;
//! * device faults injected through the `vatcal-sim-cell` library's hooks (dropped connection,
//!   stalled gauge, robot error mode, E-stop, gauge out of range): a one-line error naming the
//!   device, and `--resume` loses nothing and repeats nothing;
//! * probe zeroing with `--operator auto`: the master ball is seated and removed through the
//!   cell-control port (`MASTER <n>`, `MASTER OFF`).
//!
//! Small plan sizes (40 orientations × 4 guide steps, 40 measurements) keep each test short.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Output, Stdio};
use std::time::{Duration, Instant};

use vatcal_core::CellFile;
use vatcal_demo::{DemoOptions, DemoSizes, run_demo};
use vatcal_kinematics::Model;
use vatcal_sim_cell::{Device, Ports, SimCell, SimCellOptions};

const FIXTURE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml");

pub(crate) fn vatcal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vatcal")).args(args).output().expect("run vatcal")
}

pub(crate) fn ok(o: &Output) -> String {
    let stdout = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(o.status.success(), "stdout:\n{stdout}\nstderr:\n{}", String::from_utf8_lossy(&o.stderr));
    stdout
}

pub(crate) fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

pub(crate) fn start_cell(seed: u64) -> SimCell {
    let options = SimCellOptions {
        ports: Ports::ephemeral(),
        time_scale: 1000.0,
        ..SimCellOptions::paper(seed).expect("built-in cell")
    };
    SimCell::start(options).expect("sim-cell")
}

/// `vatcal sim-cell` as a child process on ephemeral ports; killed when dropped.
pub(crate) struct SimCellProcess {
    child: Child,
    /// `(name, address)` from its `listening NAME ADDRESS` lines
    listening: Vec<(String, String)>,
    _stdout: BufReader<ChildStdout>,
}

impl SimCellProcess {
    pub(crate) fn start(args: &[&str]) -> Self {
        let mut all = vec!["sim-cell", "--bind", "127.0.0.1"];
        all.extend_from_slice(args);
        for flag in [
            "--meca500-control-port",
            "--meca500-monitoring-port",
            "--zaber-port",
            "--gauge1-port",
            "--gauge2-port",
            "--gauge3-port",
            "--control-port",
            "--tracker-port",
        ] {
            all.extend([flag, "0"]);
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_vatcal"))
            .args(&all)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("spawn vatcal sim-cell");
        let mut stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut listening = Vec::new();
        loop {
            let mut line = String::new();
            let n = stdout.read_line(&mut line).expect("read sim-cell stdout");
            assert!(n > 0, "vatcal sim-cell ended before it was ready: {:?}", child.wait());
            if let Some(rest) = line.trim().strip_prefix("listening ") {
                let (name, addr) = rest.split_once(' ').expect("`listening NAME ADDRESS`");
                listening.push((name.to_string(), addr.to_string()));
            } else if line.starts_with("vatcal sim-cell:") {
                break;
            }
        }
        Self { child, listening, _stdout: stdout }
    }

    fn addr(&self, name: &str) -> &str {
        self.listening
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, a)| a.as_str())
            .unwrap_or_else(|| panic!("no `listening {name}` line in {:?}", self.listening))
    }

    /// `fixtures/sim-cell-devices.toml` with the default ports replaced by the actual ones.
    pub(crate) fn devices_file(&self, dir: &Path) -> PathBuf {
        let fixture = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/sim-cell-devices.toml");
        let mut text = std::fs::read_to_string(fixture).expect("fixture");
        for (default, name) in [
            ("127.0.0.1:10000", "meca500-control"),
            ("127.0.0.1:10001", "meca500-monitoring"),
            ("127.0.0.1:55550", "zaber"),
            ("127.0.0.1:55561", "gauge-1"),
            ("127.0.0.1:55562", "gauge-2"),
            ("127.0.0.1:55563", "gauge-3"),
            ("127.0.0.1:55570", "cell-control"),
            ("127.0.0.1:55580", "tracker"),
        ] {
            let quoted = format!("\"{default}\"");
            assert_eq!(text.matches(&quoted).count(), 1, "{fixture} names {default} once");
            text = text.replace(&quoted, &format!("\"{}\"", self.addr(name)));
        }
        let path = dir.join("sim-cell-devices.toml");
        std::fs::write(&path, text).expect("write devices file");
        path
    }
}

impl Drop for SimCellProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A devices file pointing at the running in-process cell.
pub(crate) fn devices_file(cell: &SimCell, dir: &Path) -> PathBuf {
    let a = cell.addrs();
    let text = format!(
        "arm = {{ kind = \"meca500\", address = \"{}\", monitoring = \"{}\" }}\n\
         guide = {{ kind = \"zaber\", tcp = \"{}\" }}\n\
         gauges = [\n  {{ kind = \"sylvac\", tcp = \"{}\" }},\n  {{ kind = \"sylvac\", tcp = \"{}\" }},\n  {{ kind = \"sylvac\", tcp = \"{}\" }},\n]\n\
         sim_control = {{ tcp = \"{}\" }}\n",
        a.meca500_control,
        a.meca500_monitoring,
        a.zaber.expect("the canonical cell has a guide"),
        a.gauges[0],
        a.gauges[1],
        a.gauges[2],
        a.control
    );
    let path = dir.join("devices.toml");
    std::fs::write(&path, text).expect("write devices file");
    path
}

/// `vatcal plan` of the canonical cell at small sizes into `dir/plan`.
pub(crate) fn plan(seed: u64, dir: &Path) -> PathBuf {
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

pub(crate) fn campaign_args<'a>(devices: &'a Path, plan: &'a Path, out: &'a Path) -> Vec<&'a str> {
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

/// Data rows of a measurements CSV without the `time_s` column (the simulated cell's clock
/// also counts the moves that put the cell back after a crash, so a resumed run's times are
/// later; everything else must not differ).
pub(crate) fn rows_without_time(csv: &Path) -> Vec<String> {
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

/// `(position, tcp, q2..q7 [deg], time_s, dir2..dir7)` of every row of a measurements CSV.
fn measurement_rows(csv: &Path) -> Vec<(String, String, Vec<f64>, f64, String)> {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col =
        |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name} column"));
    let (t, q2, d2) = (col("time_s"), col("q2"), col("dir2"));
    lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            let q = v[q2..q2 + 6].iter().map(|x| x.parse().expect("joint")).collect();
            (v[0].to_string(), v[1].to_string(), q, v[t].parse().expect("time_s"), v[d2..d2 + 6].join(","))
        })
        .collect()
}

/// The `temperature_c` column of a measurements CSV.
fn temperatures(csv: &Path) -> Vec<f64> {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let t = header.iter().position(|h| *h == "temperature_c").expect("temperature_c column");
    lines.map(|l| l.split(',').nth(t).and_then(|v| v.parse().ok()).expect("temperature")).collect()
}

/// Measurement records in a journal so far.
pub(crate) fn journaled_measurements(journal: &Path) -> usize {
    std::fs::read_to_string(journal).map_or(0, |t| t.matches("\"outcome\":\"measured\"").count())
}

#[test]
fn done_means_plan_sim_cell_campaign_identify_agree_with_the_demo() {
    let dir = tempfile::tempdir().expect("tmp");
    let plan = plan(3, dir.path());
    // the default (paper-like) truth: backlash, thermal drift on the cell's virtual clock, …
    let cell = SimCellProcess::start(&["--seed", "3", "--time-scale", "1000"]);
    let devices = cell.devices_file(dir.path());
    // with the simulator's thermometer (`TEMP?`): every measurement records `temperature_c`
    let mut text = std::fs::read_to_string(&devices).expect("devices file");
    text.push_str("thermometer = { kind = \"sim-cell\" }\n");
    std::fs::write(&devices, text).expect("devices file");
    let run = dir.path().join("run");
    let t0 = Instant::now();
    let stdout = ok(&vatcal(&campaign_args(&devices, &plan, &run)));
    let campaign_s = t0.elapsed().as_secs_f64();
    eprintln!("{stdout}campaign wall time {campaign_s:.1} s");
    assert!(stdout.contains("arm: meca500 at") && stdout.contains("gauge 3: sylvac over tcp"), "{stdout}");
    assert!(stdout.contains("guide: homed"), "{stdout}");
    assert!(stdout.contains("thermometer: sim-cell TEMP?: "), "{stdout}");
    let planned = planned_measurements(&plan);
    assert_eq!(rows_without_time(&run.join("measurements.csv")).len(), planned, "every planned measurement");
    assert!(campaign_s < 60.0, "the campaign took {campaign_s:.1} s");

    let calibrated = identify_run(&run);
    let over_tcp = Model::from_cell(&CellFile::load(&calibrated).expect("toml")).expect("model");

    let demo_dir = dir.path().join("demo");
    let mut opts = DemoOptions::new(3).expect("built-in cell");
    opts.sizes = DemoSizes { orientations: 40, guide_steps: 4, count: 40, random_poses: 60, slices: 20 };
    opts.truth = vatcal_demo::TruthSpec::PaperLike;
    opts.discovery = false; // the 34-parameter calibration is what is compared
    let demo = run_demo(&opts, &demo_dir, &mut |_| {}).expect("demo");
    // the same measurements, measured twice: joints and time stamps side by side
    let (a, b) = (
        measurement_rows(&run.join("measurements.csv")),
        measurement_rows(&demo_dir.join("measurements.csv")),
    );
    assert_eq!(a.len(), b.len(), "the demo recorded every planned measurement too");
    let (mut dq_max_deg, mut dt_max_s) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!((&x.0, &x.1), (&y.0, &y.1), "same (position, tcp) order");
        assert_eq!(x.4, y.4, "same approach directions dir2..dir7");
        dq_max_deg = x.2.iter().zip(&y.2).map(|(p, q)| (p - q).abs()).fold(dq_max_deg, f64::max);
        dt_max_s = dt_max_s.max((x.3 - y.3).abs());
    }
    eprintln!(
        "over TCP vs in process: joints differ by at most {dq_max_deg:.5}° (arm), time_s by at most {dt_max_s:.1} s (last {:.1} / {:.1} s)",
        a.last().map_or(0.0, |r| r.3),
        b.last().map_or(0.0, |r| r.3)
    );
    // one time base: `time_s` is the simulated cell's virtual time in both (over TCP read with
    // `TIME?`); they differ only by the arm's homing (inside the demo's journal, before the
    // campaign's) and by the number of corrective moves each centring takes (its noise draws
    // differ with the wire's rounding): measured ≤ 18 s over ~10 min (wall clock: 600 s)
    assert!(dt_max_s < 60.0, "time_s differs by {dt_max_s:.1} s");
    // the same temperature channel: over TCP read with `TEMP?`, in process by the simulated
    // thermometer; within the warm-up's change over those seconds plus the sensor's noise
    let (ta, tb) =
        (temperatures(&run.join("measurements.csv")), temperatures(&demo_dir.join("measurements.csv")));
    assert_eq!(ta.len(), a.len(), "every measurement over TCP has temperature_c");
    let dtemp_max = ta.iter().zip(&tb).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    eprintln!("temperature_c over TCP vs in process: at most {dtemp_max:.3} K apart");
    assert!(dtemp_max < 0.2, "temperatures differ by {dtemp_max} K");
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

    let cell = start_cell(5);
    let devices = devices_file(&cell, dir.path());
    let out = dir.path().join("killed");
    // the uninterrupted reference, on its own fresh cell, runs beside the killed and resumed run
    let reference = std::thread::scope(|scope| {
        let reference = scope.spawn(|| {
            let cell = start_cell(5);
            let cell_dir = dir.path().join("reference-cell");
            std::fs::create_dir_all(&cell_dir).expect("create dir");
            let devices = devices_file(&cell, &cell_dir);
            let out = dir.path().join("reference");
            ok(&vatcal(&campaign_args(&devices, &plan, &out)));
            rows_without_time(&out.join("measurements.csv"))
        });
        let mut child = campaign_child(&campaign_args(&devices, &plan, &out), Stdio::null);
        let journal = out.join("campaign.journal");
        wait_for_measurements(&journal, planned / 3, Some(&mut child));
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
        reference.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic))
    });
    assert_eq!(reference.len(), planned);
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
    let child = campaign_child(&campaign_args(&devices, &plan, &out), Stdio::piped);
    let journal = out.join("campaign.journal");
    wait_for_measurements(&journal, planned / 2, None);
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
    let measured_ids: Vec<String> =
        rows.iter().map(|r| r.split(',').take(2).collect::<Vec<_>>().join(",")).collect();
    assert_eq!(measured_ids, planned_ids(&plan));
}

/// `vatcal` with `args` as a child process, its stdout and stderr made by `stdio`.
fn campaign_child<A: AsRef<std::ffi::OsStr>>(args: &[A], stdio: fn() -> Stdio) -> Child {
    Command::new(env!("CARGO_BIN_EXE_vatcal"))
        .args(args)
        .stdout(stdio())
        .stderr(stdio())
        .spawn()
        .expect("spawn")
}

/// Waits (at most 120 s) until `journal` holds `at_least` measurements; with `child`, fails
/// when it ends first.
fn wait_for_measurements(journal: &Path, at_least: usize, mut child: Option<&mut Child>) {
    let deadline = Instant::now() + Duration::from_secs(120);
    while journaled_measurements(journal) < at_least {
        assert!(Instant::now() < deadline, "the child recorded too few measurements");
        if let Some(c) = child.as_mut() {
            assert!(c.try_wait().expect("wait").is_none(), "the child ended before it was killed");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Waits at most `limit` for `child` to end and returns its output (killed and failed after).
fn wait_output(mut child: Child, limit: Duration) -> Output {
    let deadline = Instant::now() + limit;
    while child.try_wait().expect("try_wait").is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            let o = child.wait_with_output().expect("reap");
            panic!(
                "the campaign did not stop within {limit:?}; stderr:\n{}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().expect("output")
}

/// `(position, tcp)` of every planned measurement, in order.
fn planned_ids(plan: &Path) -> Vec<String> {
    let tour = std::fs::read_to_string(plan.join("tour.csv")).expect("tour");
    tour.lines()
        .filter(|l| l.split(',').nth(1) == Some("measure"))
        .map(|l| l.split(',').skip(2).take(2).collect::<Vec<_>>().join(","))
        .collect()
}

/// Runs a campaign on a fresh in-process cell, calls `inject` once a third of the plan is
/// measured, and requires the campaign to stop with exactly one `error:` line that contains
/// every string of `names`. Then `clear` removes the cause and `--resume` must finish the
/// plan: the journal written before the fault is kept as it was (append-only), and the
/// measurements are the plan's, each exactly once. Returns the error line.
fn fault_then_resume(
    seed: u64,
    inject: impl Fn(&SimCell),
    clear: impl Fn(&SimCell),
    names: &[&str],
) -> String {
    let dir = tempfile::tempdir().expect("tmp");
    let plan = plan(seed, dir.path());
    let planned = planned_measurements(&plan);
    let cell = start_cell(seed);
    let devices = devices_file(&cell, dir.path());
    let out = dir.path().join("run");
    let child = campaign_child(&campaign_args(&devices, &plan, &out), Stdio::piped);
    let journal = out.join("campaign.journal");
    wait_for_measurements(&journal, planned / 3, None);
    let t0 = Instant::now();
    inject(&cell);
    let o = wait_output(child, Duration::from_secs(30));
    let stop_s = t0.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "the campaign must stop");
    let error: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error: ")).collect();
    assert_eq!(error.len(), 1, "{stderr}");
    assert!(!error[0].contains('\n'));
    for name in names {
        assert!(error[0].contains(name), "`{name}` missing from: {}", error[0]);
    }
    assert!(error[0].contains("--resume"), "{}", error[0]);
    assert_eq!(error[0].matches(names[0]).count(), 1, "no cause repeated: {}", error[0]);
    let before_text = std::fs::read_to_string(&journal).expect("journal");
    let before = journaled_measurements(&journal);
    assert!(before < planned, "the fault came after the end");
    eprintln!("stopped {stop_s:.2} s after the fault, {before} of {planned} measured: {}", error[0]);

    clear(&cell);
    let mut args = campaign_args(&devices, &plan, &out);
    args.push("--resume");
    let stdout = ok(&vatcal(&args));
    assert!(stdout.contains("resumed at step"), "{stdout}");
    let after_text = std::fs::read_to_string(&journal).expect("journal");
    assert!(after_text.starts_with(&before_text), "the resume rewrote the journal written before the fault");
    let rows = rows_without_time(&out.join("measurements.csv"));
    let measured_ids: Vec<String> =
        rows.iter().map(|r| r.split(',').take(2).collect::<Vec<_>>().join(",")).collect();
    assert_eq!(measured_ids, planned_ids(&plan), "nothing lost, nothing duplicated");
    error[0].to_string()
}

#[test]
fn a_stalled_gauge_stops_with_one_line_naming_it_and_resume_loses_nothing() {
    fault_then_resume(
        11,
        |c| c.set_stalled(Device::Gauge(1), true),
        |c| c.set_stalled(Device::Gauge(1), false),
        &["gauge 2 at 127.0.0.1"],
    );
}

#[test]
fn a_robot_error_stops_with_one_line_naming_the_arm_and_resume_loses_nothing() {
    fault_then_resume(
        12,
        |c| c.robot_error(3005, "Motion error."),
        |_| {}, // the resume resets the arm's error
        &["meca500 at 127.0.0.1", "3005"],
    );
}

#[test]
fn an_estop_stops_with_one_line_naming_the_arm_and_resume_loses_nothing() {
    fault_then_resume(13, |c| c.set_estop(true), |c| c.set_estop(false), &["meca500 at 127.0.0.1", "3070"]);
}

#[test]
fn a_gauge_out_of_range_stops_with_one_line_naming_it_and_resume_loses_nothing() {
    fault_then_resume(
        14,
        |c| c.set_gauge_out_of_range(2, true),
        |c| c.set_gauge_out_of_range(2, false),
        &["gauge 3 at 127.0.0.1"],
    );
}

#[test]
fn probe_zeroing_with_the_auto_operator_seats_the_master_ball_through_the_control_port() {
    use vatcal_campaign::{Campaign, CampaignConfig, CampaignPlan, CampaignStep, CellDevices, StepOutcome};
    use vatcal_core::Target;
    use vatcal_devices::{ConnectedDevices, DevicesFile, SimControlOperator};
    use vatcal_hardware_traits::{ProbePlacement, SystemClock, TriCal};

    let dir = tempfile::tempdir().expect("tmp");
    let plan_dir = plan(9, dir.path());
    let cell = start_cell(9);
    let devices = DevicesFile::load(devices_file(&cell, dir.path())).expect("devices file");
    // the tour's first placement with a zeroing step, and its first three measurements
    let tour = CampaignPlan::read_tour(plan_dir.join("tour.csv")).expect("tour");
    let mut steps = Vec::new();
    for step in tour.steps {
        let measure = matches!(step, CampaignStep::Measure { .. });
        let place = match step {
            CampaignStep::PlaceProbe { position } => Some(position),
            _ => None,
        };
        steps.push(step);
        if let Some(position) = place {
            steps.push(CampaignStep::ZeroProbe { position });
        }
        if measure && steps.iter().filter(|s| matches!(s, CampaignStep::Measure { .. })).count() == 3 {
            break;
        }
    }
    let plan = CampaignPlan { steps };
    let nominal = Model::from_cell(&CellFile::load(FIXTURE).expect("cell")).expect("model");
    plan.validate(&nominal).expect("a valid plan");

    let ConnectedDevices { mut arm, mut guide, gauges, sim_control, .. } =
        devices.connect().expect("connect");
    let positions: Vec<_> =
        nominal.position_ids().into_iter().filter_map(|id| nominal.position(id).map(|p| (id, p))).collect();
    let mut probe = TriCal::new(gauges, devices.probe_config(ProbePlacement::radial_placements(&positions)))
        .expect("probe");
    let mut operator = SimControlOperator::new(sim_control.expect("sim_control"));
    let clock = SystemClock;
    let cell_devices = CellDevices {
        arm: &mut arm,
        guide: guide.as_mut().map(|g| g as &mut dyn vatcal_hardware_traits::LinearAxis),
        probe: &mut probe,
        tracker: None,
        operator: &mut operator,
        clock: &clock,
        thermometer: None,
    };
    let config = CampaignConfig { show_progress: false, ..CampaignConfig::default() };
    let report = Campaign::new(cell_devices, &nominal, config)
        .run(&plan, dir.path().join("zeroing.journal"))
        .expect("the campaign with zeroing steps");
    let log = operator.log().join("; ");
    assert!(log.contains("seat the master ball") && log.contains("remove the master ball"), "{log}");
    assert!(report.records.iter().any(|r| matches!(r.outcome, StepOutcome::ProbeZeroed { .. })));
    assert_eq!(report.measurements.len(), 3);
    // the probe was zeroed on the master ball (not on whatever the plungers touched): every
    // recorded pose puts the hidden true ball on the true probe origin, to the simulated
    // repeatability and probe imperfections
    let truth = cell.cell().truth();
    for m in &report.measurements {
        let Target::Probe { position } = m.target else { panic!("a probe measurement") };
        let ball = truth.tcp_position(&m.q, m.tcp).expect("fk");
        let miss_mm = (ball - truth.position(position).expect("position")).norm();
        eprintln!("zeroed probe: true ball {:.1} µm from the true probe origin", miss_mm * 1e3);
        assert!(miss_mm < 0.05, "{:.1} µm", miss_mm * 1e3);
    }
}

/// `vatcal identify` of a campaign's run folder (`measurements.csv` → `calibrated.toml`, the
/// paper's parameters from the canonical fixture); returns the calibrated cell's path.
pub(crate) fn identify_run(run: &Path) -> PathBuf {
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
    calibrated
}
