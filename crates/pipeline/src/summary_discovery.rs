//! The discovery section of `summary.md`, from the discovery stage's outcome and the
//! validation of its models.

use std::fmt::Write as _;

use crate::discovery_stage::DiscoveryOutcome;
use crate::folders::{DISCOVERY_JOURNAL, DISCOVERY_MEASUREMENTS_CSV, LOOP_JOURNAL, LOOP_PLAN};
use crate::report::RunReport;
use crate::{CALIBRATED, DISCOVERED, NOMINAL, TRUE_STRUCTURE};

/// The discovery section of `summary.md`: the four-row comparison, each added effect and how
/// much of the gap it closed, the plots.
pub fn summary_section<S>(report: &RunReport<S>, o: &DiscoveryOutcome) -> String {
    let mut m = String::new();
    let d = &o.discovery;
    let _ = writeln!(m, "## 5. Discovery (`{DISCOVERY_JOURNAL}`, `{DISCOVERY_MEASUREMENTS_CSV}`)\n");
    let _ = writeln!(
        m,
        "{} extra probe measurements (Detmax for the {n} parameters and the candidate effects' directions, \
         {} of them two-sided repeats: a planned pose measured again right after, approached from the \
         opposite side on every revolute joint; `{}`, `time_s` and, with a thermometer, \
         `temperature_c` recorded) joined the calibration's; the discovery loop (screening \
         and held-out confirmation on separate splits) ran on all {} of them, starting from the calibrated \
         {n}-parameter model. Cross-validated gap on the probe data: {:.4} → {:.4} mm.\n",
        o.extra_measurements,
        o.two_sided_repeats,
        o.dir_columns,
        o.total_measurements,
        d.initial_gap_mm,
        d.final_gap_mm,
        n = o.base_params,
    );
    model_comparison(&mut m, report, o);
    let _ = writeln!(m, "True-structure fit: {}.\n", o.true_structure_note);
    added_effects_section(&mut m, o);
    if let Some(l) = &o.measurement_loop {
        let lines = l.lines();
        let _ = writeln!(
            m,
            "**Measurement loop** (`{LOOP_PLAN}/`, `{LOOP_JOURNAL}`): {}\n",
            lines.join("\n").trim_start_matches("measurement loop: ")
        );
    }
    for n in &d.negligible_effects {
        let _ = writeln!(m, "* detected, negligible ({:.1} µm): {} (not added)", n.change_um, n.label);
    }
    for x in &d.removed_effects {
        let _ = writeln!(m, "* removed by the backward check: {}", x.label);
    }
    for p in &o.plots {
        let _ = writeln!(m, "* `{}`: {}", p.file, p.caption);
    }
    let _ = writeln!(m);
    m
}

/// The four-row comparison of the validated models and the share of the gap closed.
fn model_comparison<S>(m: &mut String, report: &RunReport<S>, o: &DiscoveryOutcome) {
    let _ = writeln!(
        m,
        "| model (tracker validation) | random poses mean [mm] | random p95 [mm] | printing path mean [mm] | build plate mean [mm] |\n|---|---:|---:|---:|---:|"
    );
    for (label, name) in [
        (NOMINAL, "nominal"),
        (CALIBRATED, o.base_name.as_str()),
        (DISCOVERED, "discovered"),
        (TRUE_STRUCTURE, "true structure (floor)"),
    ] {
        let Some(v) = report.model(label) else {
            let _ = writeln!(m, "| {name} | - | - | - | - |");
            continue;
        };
        let path = v.path.as_ref();
        let _ = writeln!(
            m,
            "| {name} | {:.4} | {:.4} | {} | {} |",
            v.random.stats.mean,
            v.random.stats.p95,
            path.map_or("-".into(), |p| format!("{:.4}", p.tip_stats.mean)),
            path.map_or("-".into(), |p| format!("{:.4}", p.plate_stats.mean)),
        );
    }
    let mean = |l: &str| report.model(l).map(|v| v.random.stats.mean);
    if let (Some(c), Some(x)) = (mean(CALIBRATED), mean(DISCOVERED)) {
        let _ = write!(
            m,
            "\nDiscovered / {}-parameter mean random-pose error: **{:.0} %**",
            o.base_params,
            100.0 * x / c
        );
        if let Some(t) = mean(TRUE_STRUCTURE) {
            let closed = if c > t { 100.0 * (c - x) / (c - t) } else { f64::NAN };
            let _ = write!(m, "; share of the gap to the true structure closed: **{closed:.0} %**");
        }
        let _ = writeln!(m, ".\n");
    }
}

/// Each added effect and how much of the probe gap it closed (or why none was added).
fn added_effects_section(m: &mut String, o: &DiscoveryOutcome) {
    let d = &o.discovery;
    if d.added_effects.is_empty() {
        let _ = writeln!(
            m,
            "No effect was added: none passed the held-out confirmation and the negligibility check, so the \
             `discovered` row is {} refitted on all {} probe measurements (its gain over \
             the {}-parameter row comes from the extra measurements, not from a new effect).\n",
            o.base_name, o.total_measurements, o.base_params
        );
    } else {
        let _ = writeln!(
            m,
            "| step | effect added | meaning | held-out gap before → after [mm] | share of the probe gap closed |\n|---:|---|---|---:|---:|"
        );
        let span = (d.initial_gap_mm - d.final_gap_mm).max(f64::MIN_POSITIVE);
        for (k, a) in d.added_effects.iter().enumerate() {
            // effects added in the same round were confirmed together as one block
            let block = d.added_effects.iter().filter(|b| b.round == a.round).count();
            let first = k == 0 || d.added_effects[k - 1].round != a.round;
            let share = if first {
                format!("{:.0} %", 100.0 * (a.gap_before_mm - a.gap_after_mm) / span)
            } else {
                "(same block)".to_string()
            };
            let label = if block > 1 {
                format!("{} (block of {block}, round {})", a.label, a.round)
            } else {
                a.label.clone()
            };
            let _ = writeln!(
                m,
                "| {} | {label} | {} | {:.4} → {:.4} | {share} |",
                k + 1,
                a.meaning,
                a.gap_before_mm,
                a.gap_after_mm,
            );
        }
        let _ = writeln!(m);
    }
}
