//! `vatcal calibrate` as a real child process against the simulated cell served over TCP
//! (`vatcal-sim-cell` on ephemeral ports, time scale 1000, seed 3) with the automatic
//! operator, quick sizes (`--quick`: 20 orientations × 3 guide steps, 40 measurements) and a
//! short discovery campaign:
//!
//! * `kill -9` during the measurement campaign, `--resume`, `kill -9` during the discovery
//!   campaign, `--resume`: both campaigns' measurements equal an uninterrupted run's (apart
//!   from `time_s`: the simulated clock also counts the moves that restore the cell), and the
//!   stage state counts two attempts of each;
//! * a stage on its own (`--stages identify`) recomputes from the run folder, a stage whose
//!   predecessor is not done is refused naming it, a resume of another seed is refused.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::campaign_sim::{
    devices_file, journaled_measurements, ok, rows_without_time, s, start_cell, vatcal,
};

fn calibrate_args<'a>(devices: &'a Path, out: &'a Path) -> Vec<&'a str> {
    vec![
        "calibrate",
        "--devices",
        s(devices),
        "--out",
        s(out),
        "--operator",
        "auto",
        "--seed",
        "3",
        "--quick",
        "--discovery-count",
        "24",
        "--stages",
        "plan,campaign,identify,discovery",
        "--quiet",
    ]
}

/// Starts `vatcal calibrate` with `args`, kills it with SIGKILL once `journal` holds
/// `measurements` measurements.
fn kill_when(args: &[&str], journal: &Path, measurements: usize) -> usize {
    let mut child = Command::new(env!("CARGO_BIN_EXE_vatcal"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    let deadline = Instant::now() + Duration::from_secs(180);
    while journaled_measurements(journal) < measurements {
        assert!(Instant::now() < deadline, "the child recorded too few measurements");
        assert!(child.try_wait().expect("wait").is_none(), "the child ended before it was killed");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().expect("SIGKILL");
    child.wait().expect("reap");
    journaled_measurements(journal)
}

fn attempts(out: &Path, stage: &str) -> u64 {
    let text = std::fs::read_to_string(out.join("stages.json")).expect("stages.json");
    let v: serde_json::Value = serde_json::from_str(&text).expect("json");
    let e = v["stages"].as_array().expect("stages").iter().find(|e| e["stage"] == stage).expect("stage");
    assert_eq!(e["status"], "done", "{stage}: {e}");
    e["attempts"].as_u64().expect("attempts")
}

#[test]
fn kill_9_during_the_campaign_and_the_discovery_then_resume_gives_an_uninterrupted_run() {
    let dir = tempfile::tempdir().expect("tmp");
    let reference = dir.path().join("reference");
    {
        let cell = start_cell(3);
        let devices = devices_file(&cell, dir.path());
        let stdout = ok(&vatcal(&calibrate_args(&devices, &reference)));
        assert!(stdout.contains("stages run: plan, campaign, identify, discovery"), "{stdout}");
    }
    let planned = rows_without_time(&reference.join("measurements.csv")).len();
    let extra = rows_without_time(&reference.join("discovery_measurements.csv")).len();
    assert_eq!(planned, 40);
    assert!(extra >= 24, "{extra} discovery measurements");

    let cell = start_cell(3);
    let devices = devices_file(&cell, dir.path());
    let out = dir.path().join("killed");
    let args = calibrate_args(&devices, &out);
    let at = kill_when(&args, &out.join("campaign.journal"), planned / 3);
    assert!(at < planned, "killed after the end of the campaign ({at} of {planned})");
    let mut resume = args.clone();
    resume.push("--resume");
    let at = kill_when(&resume, &out.join("discovery.journal"), extra / 3);
    assert!(at < extra, "killed after the end of the discovery campaign ({at} of {extra})");
    let stdout = ok(&vatcal(&resume));
    assert!(stdout.contains("stages run: discovery"), "{stdout}");
    assert!(stdout.contains("recomputed from the run folder: plan, campaign, identify"), "{stdout}");
    for csv in ["measurements.csv", "discovery_measurements.csv"] {
        assert_eq!(rows_without_time(&out.join(csv)), rows_without_time(&reference.join(csv)), "{csv}");
    }
    assert_eq!(attempts(&out, "campaign"), 2);
    assert_eq!(attempts(&out, "discovery"), 2);
    assert_eq!(attempts(&out, "plan"), 1);
    assert_eq!(
        std::fs::read_to_string(out.join("calibrated.toml")).expect("calibrated"),
        std::fs::read_to_string(reference.join("calibrated.toml")).expect("calibrated"),
        "the same measurements give the same calibrated model"
    );

    // a stage on its own: identification again from the journal, the discovery no longer done
    let mut only = args.clone();
    let k = only.iter().position(|a| *a == "plan,campaign,identify,discovery").expect("stages");
    only[k] = "identify";
    let stdout = ok(&vatcal(&only));
    assert!(
        stdout.contains("stages run: identify; recomputed from the run folder: plan, campaign"),
        "{stdout}"
    );
    let text = std::fs::read_to_string(out.join("stages.json")).expect("stages.json");
    assert!(!text.contains("\"discovery\""), "a re-run identification invalidates the discovery: {text}");
    only[k] = "validation";
    let refused = vatcal(&only);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("stage `discovery`") || err.contains("tracker"), "{err}");
    let mut other_seed = resume.clone();
    let k = other_seed.iter().position(|a| *a == "3").expect("seed");
    other_seed[k] = "4";
    let refused = vatcal(&other_seed);
    assert!(!refused.status.success());
    assert!(
        String::from_utf8_lossy(&refused.stderr).contains("seed 3"),
        "{}",
        String::from_utf8_lossy(&refused.stderr)
    );
}
