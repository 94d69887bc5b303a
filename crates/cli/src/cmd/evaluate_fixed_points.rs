//! `vatcal evaluate-fixed-points`: consistency and distance errors of one or more models on
//! fixed points at unknown places (MUKCa-style sockets), one evaluation per file (placement).
//! Each file's points are fitted from its own rows (their places are unknown); nothing of the
//! robot is fitted (`vatcal_identification::evaluate_fixed_points`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use vatcal_core::PointDistance;
use vatcal_identification::{FixedPointEvaluation, evaluate_fixed_points};

/// Arguments of `vatcal evaluate-fixed-points`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Cell model file(s) to evaluate (repeat the option: e.g. the nominal, another
    /// calibration and vatcal's calibration, side by side).
    #[arg(long, required = true)]
    pub model: Vec<PathBuf>,
    /// Fixed-point rows, one file per placement of the fixture (repeat the option): probe rows
    /// `position,tcp,q1..qN` whose `position` names the fixed point (any id; the places are
    /// unknown and fitted per file).
    #[arg(long, required = true)]
    pub measurements: Vec<PathBuf>,
    /// A known distance between two points, `a,b,distance_mm` (e.g. `1,2,50` for MUKCa's two
    /// sockets; a fourth field, the distance's sigma for `identify`, is accepted and not used);
    /// repeat for more.
    #[arg(long, value_parser = PointDistance::parse)]
    pub point_distance: Vec<PointDistance>,
    /// Write every evaluation (per file and model: per point centre and spread, distances) as
    /// JSON here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Units, limit tolerance and directions of the measurement files.
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
}

/// One model on one file in the JSON report.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EvaluatedFile {
    /// the measurement file (placement)
    pub measurements: String,
    /// the cell file
    pub model: String,
    /// consistency and distances
    pub evaluation: FixedPointEvaluation,
}

/// Evaluates every model on every file, prints the table and a summary per model.
pub fn run(args: Args) -> anyhow::Result<()> {
    let models = args
        .model
        .iter()
        .map(|p| super::load_model(p).map(|m| (p, m)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut results: Vec<EvaluatedFile> = Vec::new();
    for file in &args.measurements {
        for (k, (path, model)) in models.iter().enumerate() {
            // read with each model (its TCPs and limits); warnings once per file
            let rows = if k == 0 {
                args.read.fixed_points(file, model)?
            } else {
                let options = vatcal_io::ReadOptions { any_position_id: true, ..args.read.options()? };
                vatcal_io::read_probe_measurements_with(file, model, &options)?.rows
            };
            let evaluation = evaluate_fixed_points(model, &rows, &args.point_distance)
                .with_context(|| format!("evaluating {} on {}", path.display(), file.display()))?;
            results.push(EvaluatedFile {
                measurements: file.display().to_string(),
                model: path.display().to_string(),
                evaluation,
            });
        }
    }
    print_table(&args, &results);
    if let Some(path) = &args.report {
        let text = serde_json::to_string_pretty(&results)?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
        println!("report written to {}", path.display());
    }
    Ok(())
}

/// `dir/stem` of a path: enough to tell placements (and models) of several sets apart.
fn short(path: &str) -> String {
    let p = Path::new(path);
    let stem = p.file_stem().map_or_else(|| path.to_string(), |s| s.to_string_lossy().into_owned());
    match p.parent().and_then(Path::file_name) {
        Some(dir) => format!("{}/{stem}", dir.to_string_lossy()),
        None => stem,
    }
}

fn print_table(args: &Args, results: &[EvaluatedFile]) {
    let distance_heads: Vec<String> =
        args.point_distance.iter().map(|d| format!("d{}-{} err", d.a, d.b)).collect();
    print!("{:<28} {:<32} {:>4} {:>9} {:>9} {:>9}", "[mm]", "model", "n", "RMS", "mean", "max");
    for h in &distance_heads {
        print!(" {h:>11}");
    }
    println!();
    for r in results {
        let e = &r.evaluation;
        let n: usize = e.points.iter().map(|p| p.n).sum();
        print!(
            "{:<28} {:<32} {:>4} {:>9.4} {:>9.4} {:>9.4}",
            short(&r.measurements),
            short(&r.model),
            n,
            e.rms_mm,
            e.mean_mm,
            e.max_mm
        );
        for d in &e.distances {
            print!(" {:>+11.4}", d.error_mm);
        }
        println!();
    }
    if args.measurements.len() > 1 {
        println!("over the {} files (mean of the per-file values):", args.measurements.len());
        for path in &args.model {
            let label = path.display().to_string();
            let mine: Vec<&FixedPointEvaluation> =
                results.iter().filter(|r| r.model == label).map(|r| &r.evaluation).collect();
            let k = mine.len().max(1) as f64;
            let rms = mine.iter().map(|e| e.rms_mm).sum::<f64>() / k;
            let mean = mine.iter().map(|e| e.mean_mm).sum::<f64>() / k;
            let dist =
                mine.iter().flat_map(|e| e.distances.iter().map(|d| d.error_mm.abs())).collect::<Vec<_>>();
            let dist_mean = dist.iter().sum::<f64>() / dist.len().max(1) as f64;
            println!(
                "  {:<32} RMS {rms:.4}  mean {mean:.4}{}",
                short(&label),
                if dist.is_empty() { String::new() } else { format!("  |distance error| {dist_mean:.4}") }
            );
        }
    }
}
