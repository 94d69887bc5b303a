//! The discovery benchmark (issue 21, item 5): hidden-effect cases unlike the demo's truth —
//! random mixtures of catalog effects and physics the catalog does not have, sizes from below
//! the noise to ten times above it, the canonical cell and the UR5e, probe-only, tracker-only
//! and mixed data, with and without replicates and noise metadata, null cases — generated from
//! a fixed seed, run through `discover` in parallel (rayon), and scored. See
//! `docs/discovery-benchmark.md` and `tests/common/benchmark.rs`.
//!
//! ```text
//! cargo run --release -p vatcal-discovery --example discovery_benchmark -- [CASES] [SEED] [JSON_OUT]
//! ```
//! (defaults: 100 cases, seed 21). Prints one line per case (with its category tags), then the
//! Markdown tables. The cases come from the current generator (`GENERATOR_VERSION`, frozen:
//! see the doc); `DISCOVERY_BENCHMARK_GENERATOR=v2` draws the previous version's. With
//! `DISCOVERY_BENCHMARK_REPORTS=DIR` it also writes each case's full discovery report
//! (`DIR/case-N.json`, as `vatcal discover --report` writes it), for reading a case in detail.

#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "../tests/common/mod.rs"]
mod common;

use common::benchmark::{GENERATOR_VERSION, Generator, generate_with, markdown, run_case};
use rayon::prelude::*;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let count: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(100);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(21);
    let version = std::env::var("DISCOVERY_BENCHMARK_GENERATOR").unwrap_or_else(|_| GENERATOR_VERSION.into());
    let Some(generator) = Generator::parse(&version) else {
        eprintln!("unknown generator version `{version}` (DISCOVERY_BENCHMARK_GENERATOR: v2 or v3)");
        std::process::exit(2);
    };
    let mut cases = generate_with(generator, count, seed);
    // DISCOVERY_BENCHMARK_CASES=5,51: only those cases of the stream (the same cases as in the
    // whole run: the stream is drawn first, then filtered)
    if let Ok(ids) = std::env::var("DISCOVERY_BENCHMARK_CASES") {
        let parsed: Result<Vec<usize>, _> = ids.split(',').map(|s| s.trim().parse::<usize>()).collect();
        let Ok(ids) = parsed else {
            eprintln!(
                "DISCOVERY_BENCHMARK_CASES=`{ids}`: expected case numbers separated by commas, e.g. 5,51"
            );
            std::process::exit(2);
        };
        cases.retain(|c| ids.contains(&c.id));
    }
    // DISCOVERY_BENCHMARK_ROWS=360: a robustness study, not the benchmark: every case fitted on
    // that many rows instead of the generator's (v3: 180); the cases are otherwise the same
    if let Ok(text) = std::env::var("DISCOVERY_BENCHMARK_ROWS") {
        let Ok(n) = text.trim().parse::<usize>() else {
            eprintln!("DISCOVERY_BENCHMARK_ROWS=`{text}`: expected a number of rows, e.g. 360");
            std::process::exit(2);
        };
        for c in &mut cases {
            for h in &mut c.hidden {
                if let common::benchmark::Shape::Campaign { rows, .. } = &mut h.shape {
                    *rows = n;
                }
            }
        }
    }
    if let Ok(dir) = std::env::var("DISCOVERY_BENCHMARK_REPORTS") {
        std::fs::create_dir_all(&dir).unwrap();
        cases.clone().into_par_iter().for_each(|mut c| {
            let Some(data) = common::benchmark::CaseData::build(&mut c) else { return };
            let options = common::benchmark::options_for(&c, &data);
            let path = std::path::Path::new(&dir);
            if let Ok(d) = vatcal_discovery::discover(
                &data.nominal,
                &data.measurements,
                &data.params,
                Some(&data.validation),
                &options,
            ) {
                std::fs::write(
                    path.join(format!("case-{}.json", c.id)),
                    serde_json::to_string_pretty(&d).unwrap(),
                )
                .unwrap();
            }
        });
    }
    let t0 = std::time::Instant::now();
    let results: Vec<_> = cases
        .into_par_iter()
        .map(|c| {
            let r = run_case(c);
            let hidden: Vec<String> = r
                .hidden
                .iter()
                .map(|h| format!("{} {:.1}x {}", h.label, h.multiple, if h.named_driver { "named" } else { "MISSED" }))
                .collect();
            eprintln!(
                "case {:3} [{}] {:?}/{:?} rep={} meta={} hidden=[{}] added=[{}] val {:.4}->{:.4} floor {} ({:.1} s){}",
                r.case.id,
                r.case.tags(),
                r.case.robot,
                r.case.data,
                r.case.replicates,
                r.case.noise_metadata,
                hidden.join("; "),
                r.added.join("; "),
                r.start_mm,
                r.discovered_mm,
                r.floor_mm.map_or("-".into(), |f| format!("{f:.4}")),
                r.seconds,
                r.error.as_ref().map_or(String::new(), |e| format!(" ERROR {e}"))
            );
            r
        })
        .collect();
    println!(
        "{} cases, generator {}, seed {seed}, {:.0} s wall\n",
        results.len(),
        generator.version(),
        t0.elapsed().as_secs_f64()
    );
    println!("{}", markdown(&results));
    if let Some(path) = args.get(3) {
        std::fs::write(path, serde_json::to_string_pretty(&results).unwrap()).unwrap();
    }
}
