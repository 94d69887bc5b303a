//! End-to-end tests of `vatcal select` and `vatcal observability` (issue 3): happy paths and
//! the bad inputs that must fail with a clear message.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use vatcal_core::{CellFile, Measurement};
use vatcal_kinematics::Model;

fn fixture() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
}

fn model() -> Model {
    Model::from_cell(&CellFile::load(fixture()).expect("fixture")).expect("model")
}

/// Probe poses of the canonical cell (IK onto the calibration positions), optionally only at
/// some positions.
fn poses(count: usize, seed: u64, positions: &[u32]) -> Vec<Measurement> {
    let m = model();
    vatcal_sim::truth::probe_start_poses(&m, 3 * count, seed)
        .into_iter()
        .filter(|p| p.position().is_some_and(|id| positions.contains(&id)))
        .take(count)
        .collect()
}

/// Writes `position,tcp,q1..q7,label` rows (q1 mm, q2..q7 degrees).
fn write_candidates(path: &Path, rows: &[Measurement]) {
    let mut text = String::from("position,tcp,q1,q2,q3,q4,q5,q6,q7,label\n");
    for (i, m) in rows.iter().enumerate() {
        let q: Vec<String> = m.q.to_mm_deg().iter().map(|v| v.to_string()).collect();
        text.push_str(&format!("{},{},{},row{i}\n", m.position().unwrap_or(0), m.tcp, q.join(",")));
    }
    std::fs::write(path, text).expect("write candidates");
}

pub(super) fn vatcal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vatcal")).args(args).output().expect("run vatcal")
}

pub(super) fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn select_writes_the_chosen_rows_and_reports_indices_and_ablation() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cands = dir.path().join("cands.csv");
    let out = dir.path().join("selected.csv");
    write_candidates(&cands, &poses(240, 1, &[1, 2, 3]));
    let fixture = fixture();
    let o = vatcal(&[
        "select",
        "--model",
        fixture.to_str().expect("path"),
        "--candidates",
        cands.to_str().expect("path"),
        "--count",
        "40",
        "--restarts",
        "2",
        "--seed",
        "3",
        "--fixed",
        "5,17",
        "--out",
        out.to_str().expect("path"),
    ]);
    let stdout = text(&o.stdout);
    assert!(o.status.success(), "stderr: {}\nstdout: {stdout}", text(&o.stderr));
    let written = std::fs::read_to_string(&out).expect("output");
    let lines: Vec<&str> = written.lines().collect();
    assert_eq!(lines[0], "position,tcp,q1,q2,q3,q4,q5,q6,q7,label");
    assert_eq!(lines.len(), 41);
    // rows are copied verbatim from the input, and the fixed rows are there
    let input = std::fs::read_to_string(&cands).expect("input");
    for l in &lines[1..] {
        assert!(input.lines().any(|i| i == *l), "{l} not an input row");
    }
    assert!(lines.iter().any(|l| l.ends_with(",row4")) && lines.iter().any(|l| l.ends_with(",row16")));
    assert!(stdout.contains("selection: O1"), "{stdout}");
    assert!(stdout.contains("rank 34/34"), "{stdout}");
    // ablation: one position loses 3 directions, two lose 1
    assert!(stdout.contains("positions {1} ("), "{stdout}");
    assert!(stdout.contains("rank 31/34"), "{stdout}");
    assert!(stdout.contains("positions {1,2} ("), "{stdout}");
    assert!(stdout.contains("rank 33/34"), "{stdout}");
    assert!(stdout.contains("best with 2 position(s)"), "{stdout}");
}

fn select_error(cands: &Path, count: &str) -> String {
    let fixture = fixture();
    let out = cands.with_file_name("out.csv");
    let o = vatcal(&[
        "select",
        "--model",
        fixture.to_str().expect("path"),
        "--candidates",
        cands.to_str().expect("path"),
        "--count",
        count,
        "--restarts",
        "1",
        "--no-ablation",
        "--out",
        out.to_str().expect("path"),
    ]);
    assert!(!o.status.success(), "expected failure, stdout: {}", text(&o.stdout));
    text(&o.stderr)
}

#[test]
fn select_refuses_bad_input_with_clear_messages() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cands = dir.path().join("cands.csv");
    let rows = poses(30, 2, &[1, 2, 3]);
    write_candidates(&cands, &rows);

    let e = select_error(&cands, "40");
    assert!(e.contains("30 candidate poses, fewer than --count 40"), "{e}");

    // unknown TCP on data row 3 (file line 4)
    let mut bad = rows.clone();
    bad[2].tcp = 9;
    write_candidates(&cands, &bad);
    let e = select_error(&cands, "20");
    assert!(e.contains("cands.csv:4") && e.contains("tcp"), "{e}");

    // unknown calibration position
    let mut text_rows = std::fs::read_to_string(&cands).expect("read");
    text_rows = text_rows.replacen("\n1,", "\n7,", 1);
    std::fs::write(&cands, text_rows).expect("write");
    let e = select_error(&cands, "20");
    assert!(e.contains("position"), "{e}");

    // candidates at one calibration position cannot identify the world frame
    write_candidates(&cands, &poses(60, 3, &[2]));
    let e = select_error(&cands, "40");
    assert!(e.contains("cannot identify"), "{e}");
    assert!(e.contains("base_"), "{e}");
}

#[test]
fn observability_prints_rank_and_redundant_parameters() {
    let dir = tempfile::tempdir().expect("tempdir");
    let meas = dir.path().join("meas.csv");
    write_candidates(&meas, &poses(60, 4, &[1, 2, 3]));
    let fixture = fixture();
    let o = vatcal(&[
        "observability",
        "--model",
        fixture.to_str().expect("path"),
        "--measurements",
        meas.to_str().expect("path"),
    ]);
    let stdout = text(&o.stdout);
    assert!(o.status.success(), "stderr: {}", text(&o.stderr));
    assert!(stdout.contains("rank 34 of"), "{stdout}");
    assert!(stdout.contains("d_3 is absorbed by d_4"), "{stdout}");
    assert!(stdout.contains("a_1 is absorbed by base_y"), "{stdout}");
    assert!(stdout.contains("O1"), "{stdout}");

    // paper34 with one position: rank 31, strict mode fails naming base parameters
    write_candidates(&meas, &poses(40, 5, &[1]));
    let o = vatcal(&[
        "observability",
        "--model",
        fixture.to_str().expect("path"),
        "--measurements",
        meas.to_str().expect("path"),
        "--params",
        "paper34",
        "--strict",
    ]);
    assert!(!o.status.success());
    let stdout = text(&o.stdout);
    assert!(stdout.contains("rank 31 of 34"), "{stdout}");
    assert!(text(&o.stderr).contains("rank-deficient"), "{}", text(&o.stderr));
}

/// The selections of `vatcal select` did not change with the speed-up of issue 12 (parallel
/// CSV conversion and candidate Jacobians): the expected rows were written by the binary
/// before that change on the same candidates (seeded poses, the same as
/// `cargo run -p vatcal-benches --example candidates_csv -- 2000 11 FILE`).
#[test]
fn select_picks_the_same_rows_as_before_the_speed_up() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cands = dir.path().join("cands.csv");
    write_candidates(&cands, &poses(2000, 11, &[1, 2, 3]));
    let fixture = fixture();
    let one_restart: &[&str] = &["--restarts", "1", "--excursions", "0"];
    let expected_one_restart = [
        19, 30, 53, 70, 76, 80, 131, 312, 327, 336, 338, 359, 379, 380, 390, 475, 504, 525, 579, 620, 625,
        646, 655, 683, 776, 791, 811, 865, 917, 920, 1124, 1132, 1207, 1230, 1375, 1530, 1670, 1827, 1846,
        1926,
    ];
    let expected_defaults = [
        19, 30, 53, 80, 125, 131, 250, 327, 338, 359, 379, 390, 475, 525, 646, 655, 800, 811, 828, 865, 900,
        920, 932, 1025, 1061, 1119, 1124, 1132, 1162, 1202, 1207, 1236, 1375, 1419, 1474, 1530, 1594, 1826,
        1827, 1953,
    ];
    for (extra, expected) in [(one_restart, &expected_one_restart), (&[][..], &expected_defaults)] {
        let out = dir.path().join("selected.csv");
        let mut args = vec![
            "select",
            "--model",
            fixture.to_str().expect("path"),
            "--candidates",
            cands.to_str().expect("path"),
            "--count",
            "40",
            "--seed",
            "7",
            "--no-ablation",
            "--out",
            out.to_str().expect("path"),
        ];
        args.extend_from_slice(extra);
        let o = vatcal(&args);
        assert!(o.status.success(), "stderr: {}", text(&o.stderr));
        let written = std::fs::read_to_string(&out).expect("output");
        let rows: Vec<usize> = written
            .lines()
            .skip(1)
            .map(|l| {
                l.rsplit(',').next().and_then(|s| s.strip_prefix("row")).expect("label").parse().expect("row")
            })
            .collect();
        assert_eq!(rows, expected.to_vec(), "selection with {extra:?}");
    }
}
