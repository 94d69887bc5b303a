//! One run of the demo as a user gets it (`DemoOptions::new(SEED)`: the paper-like truth, the
//! paper's sizes, the discovery stage on with its 15-min device-time budget), shared by the tests of `paper_like.rs`,
//! `compensation.rs` and `discovery.rs`: the demo is the slowest thing the test suite runs
//! (the discovery stage most of all), so it runs once per test binary and each test checks its
//! own part of the outcome.
#![allow(dead_code)]

use std::sync::OnceLock;

use vatcal_demo::{DemoOptions, DemoOutcome, run_demo};

/// Seed of the shared run. Measured on it (release, the default 15-min discovery budget):
/// nominal → calibrated random-pose mean 1.085 → 0.266 mm, discovered 0.080 mm, true structure
/// 0.049 mm (earlier, dev profile, no budget: 1.255 → 0.243 mm, printing path 1.122 → 0.300 mm,
/// discovered 0.049 mm, true structure 0.051 mm).
pub const SEED: u64 = 1;

/// The shared run: its options, its outcome and the report files the tests read (the report
/// folder itself is a temporary directory removed once they are read).
#[derive(Debug)]
pub struct DefaultDemo {
    /// the options of the run (`DemoOptions::new(SEED)`, unchanged)
    pub opts: DemoOptions,
    /// what `run_demo` returned
    pub out: DemoOutcome,
    /// `report.json`
    pub report_json: serde_json::Value,
    /// `timing.json`
    pub timing_json: serde_json::Value,
    /// `summary.md`
    pub summary_md: String,
    /// `summary.html`
    pub summary_html: String,
}

/// The shared run (made by the first test that asks; the others wait for it).
pub fn default_demo() -> &'static DefaultDemo {
    static RUN: OnceLock<DefaultDemo> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tmp");
        let opts = DemoOptions::new(SEED).expect("built-in cell");
        let out = run_demo(&opts, dir.path(), &mut |_| {}).expect("demo");
        let read =
            |f: &str| std::fs::read_to_string(dir.path().join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        let report_json = serde_json::from_str(&read("report.json")).expect("report.json parses");
        DefaultDemo {
            opts,
            out,
            report_json,
            timing_json: serde_json::from_str(&read("timing.json")).expect("timing.json parses"),
            summary_md: read("summary.md"),
            summary_html: read("summary.html"),
        }
    })
}
