//! `summary.md` of a run: one section per stage's output (setup, plan, measurement
//! campaign, identification, validation, the paper's figures, compensation, tracker
//! registration, discovery), then the files and the times.

use std::fmt::Write as _;

use vatcal_identification::ErrorStats;

use crate::outcome::RunOutcome;
use crate::report::{PAPER, ReportSetup, RunReport, stats_of};
use crate::{CALIBRATED, NOMINAL};

/// `summary.md`: setup, counts, identification log, before/after tables, the paper's figures,
/// files, wall-clock times.
pub(crate) fn summary_markdown<S: ReportSetup>(outcome: &RunOutcome<S>) -> String {
    let r = &outcome.report;
    let s = &r.setup;
    let mut m = String::new();
    let _ = writeln!(m, "{}\n", s.title(r.seed));
    let _ = writeln!(m, "{}\n", s.intro());
    let _ = writeln!(m, "## Setup\n");
    let _ = writeln!(m, "{}", s.setup_markdown(&r.validation));
    let _ = writeln!(m, "## 1. Plan (`plan/`)\n\n```text\n{}\n```\n", r.plan.text());
    campaign_section(&mut m, r);
    identification_section(&mut m, r);
    validation_section(&mut m, r);
    paper_section(&mut m, r);
    if let Some(c) = &r.compensation {
        m.push_str(&crate::compensation::summary_markdown(c));
    }
    if let Some(reg) = &r.tracker_registration {
        let _ = writeln!(m);
        m.push_str(&reg.markdown());
    }
    if let Some(d) = &outcome.discovery {
        m.push_str(&crate::summary_discovery::summary_section(r, d));
    }
    let note = outcome.report.setup.comparison_note();
    if !note.is_empty() {
        let _ = writeln!(m, "\n{note}\n");
    }

    files_and_times(&mut m, outcome);
    m
}

/// `## 2. Measurement campaign`.
fn campaign_section<S>(m: &mut String, r: &RunReport<S>) {
    let c = &r.campaign;
    let per: Vec<String> = c.per_position.iter().map(|(p, n)| format!("{n} at position {p}")).collect();
    let _ = writeln!(m, "## 2. Measurement campaign (`campaign.journal`, `measurements.csv`)\n");
    let _ = writeln!(
        m,
        "{} probe measurements ({}), {} skipped; auto-centering took {:.1} corrective moves on average \
         (at most {}), leaving {:.2} µm on average; {} campaign steps, {:.1} min of virtual time.\n",
        c.measurements,
        per.join(", "),
        c.skipped,
        c.centering_moves_mean,
        c.centering_moves_max,
        c.final_offset_mean_mm * 1000.0,
        c.plan_steps,
        c.virtual_time_s / 60.0
    );
}

/// `## 3. Identification`: the iterations and every parameter.
fn identification_section<S: ReportSetup>(m: &mut String, r: &RunReport<S>) {
    let s = &r.setup;
    let id = &r.identification;
    let _ = writeln!(m, "## 3. Identification (`calibrated.toml`)\n");
    let _ = writeln!(
        m,
        "{}, {} from {} probe measurements: {} ({:?}).\n",
        s.parameters(),
        s.method(),
        id.n_probe,
        if id.converged { "converged" } else { "not converged" },
        id.termination
    );
    let _ = writeln!(m, "| iteration | mean [mm] | RMS [mm] | max [mm] | λ |\n|---:|---:|---:|---:|---:|");
    for it in &id.iterations {
        let _ = writeln!(
            m,
            "| {} | {:.6} | {:.6} | {:.6} | {:.2e} |",
            it.iteration, it.mean_mm, it.rms_mm, it.max_mm, it.lambda
        );
    }
    let _ = writeln!(
        m,
        "\nConvergence: `identification_convergence.svg`. Residuals at the solution: {}; σ̂ = {:.4} mm (dof {}), condition number {:.1}.\n",
        id.residual_stats.one_line(),
        id.sigma_hat_mm,
        id.dof,
        id.condition_number
    );
    let _ = writeln!(m, "| parameter | unit | nominal | identified | Δ | σ |\n|---|---|---:|---:|---:|---:|");
    for p in &id.parameters {
        let _ = writeln!(
            m,
            "| {} | {} | {:.6} | {:.6} | {:+.3e} | {:.1e} |",
            p.name,
            p.unit,
            p.nominal_file_units,
            p.identified_file_units,
            p.delta_file_units,
            p.sigma_file_units
        );
    }
    let _ = writeln!(m);
}

fn stats_row(name: &str, s: &ErrorStats) -> String {
    format!(
        "| {name} | {} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} |\n",
        s.n, s.mean, s.rms, s.median, s.p95, s.max
    )
}

/// `## 4. Validation`: what was measured and each model's errors.
fn validation_section<S>(m: &mut String, r: &RunReport<S>) {
    let v = &r.validation;
    let _ = writeln!(m, "## 4. Validation with the simulated laser tracker (`validation.journal`)\n");
    let _ = writeln!(
        m,
        "* **random poses**: {} joint vectors over the whole workspace (≥ {}° inside the joint limits, \
         collision-free), one SMR measured at each; error = tracker − FK of the model \
         (`validation_random.csv`, `validation_random_errors.csv`, `random_errors_histogram.svg`, the paper's Fig. 8);",
        v.random_poses, v.random_options.joint_margin_deg
    );
    let p = &v.printing_path;
    if p.slices == 0 {
        let _ = writeln!(
            m,
            "* **printing path**: none (the tank path, lifted by the guide one layer per slice, exists for the \
             canonical Meca500-on-guide cell only);"
        );
    } else {
        let _ = writeln!(
            m,
            "* **printing path**: {} slices of {} mm; the part's end stays on the tank bottom (world z = {} mm) and \
         follows a half circle of radius {} mm while the plate tilts by up to {}° and turns by {}°; the guide \
         lifts by one layer per slice from {:.1} mm. Each model *commands* its own run through its IK; the three \
         SMRs measured at each slice give the end-effector pose, carried to the end of the part (lever effect). \
         Error = measured − intended there (`validation_path_*.csv`, `printing_path_errors.csv`, \
         `path_errors.svg`, `path_errors_calibrated.svg`, the paper's Figs. 9–10);",
            p.slices,
            p.layer_mm,
            p.start_mm[2],
            p.lateral_radius_mm,
            p.tilt_max_deg,
            p.spin_deg,
            v.guide_start_mm
        );
    }
    let _ = writeln!(
        m,
        "* {} tracker measurements in {} campaign steps ({} legs between random poses needed RRT-Connect), \
         {:.1} min of virtual time.\n",
        v.tracker_measurements,
        v.campaign_steps,
        v.rrt_legs,
        v.virtual_time_s / 60.0
    );
    let _ = writeln!(
        m,
        "| position error [mm] | n | mean | RMS | median | p95 | max |\n|---|---:|---:|---:|---:|---:|---:|"
    );
    for model in &v.models {
        m.push_str(&stats_row(&format!("random poses, {} model", model.label), &model.random.stats));
    }
    for model in &v.models {
        if let Some(path) = &model.path {
            m.push_str(&stats_row(
                &format!("printing path (part end), {} model", model.label),
                &path.tip_stats,
            ));
            m.push_str(&stats_row(
                &format!("printing path (build plate), {} model", model.label),
                &path.plate_stats,
            ));
        }
    }
}

/// `### Compared with the paper`.
fn paper_section<S>(m: &mut String, r: &RunReport<S>) {
    let v = &r.validation;
    let p = &v.printing_path;
    let _ = writeln!(m, "\n### Compared with the paper (their measurements, not ours)\n");
    let _ = writeln!(m, "| mean position error [mm] | nominal | calibrated |\n|---|---:|---:|");
    let (nr, np) = stats_of(r, NOMINAL);
    let (cr, cp) = stats_of(r, CALIBRATED);
    let f = |s: Option<&ErrorStats>| s.map_or("-".to_string(), |s| format!("{:.3}", s.mean));
    let _ = writeln!(m, "| this demo, random poses (n = {}) | {} | {} |", v.random_poses, f(nr), f(cr));
    let _ = writeln!(
        m,
        "| **paper**, random poses (n = {}, FARO Vantage E tracker) | {:.3} | {:.3} |",
        PAPER.random_poses, PAPER.random_nominal_mean_mm, PAPER.random_calibrated_mean_mm
    );
    if p.slices > 0 {
        let _ = writeln!(m, "| this demo, printing path ({} slices) | {} | {} |", p.slices, f(np), f(cp));
    }
    let _ = writeln!(
        m,
        "| **paper**, printing path ({} slices) | {:.3} | {:.3} |",
        PAPER.path_slices, PAPER.path_nominal_mean_mm, PAPER.path_calibrated_mean_mm
    );
}

/// `## Files` and `## Wall-clock time` (and the time on the devices).
fn files_and_times<S>(m: &mut String, outcome: &RunOutcome<S>) {
    let _ = writeln!(m, "## Files\n");
    for file in &outcome.files {
        let _ = writeln!(m, "* `{}`", file.display());
    }
    let _ = writeln!(m, "\n## Wall-clock time\n");
    let total: f64 = outcome.stage_seconds.iter().map(|(_, s)| s).sum();
    for (name, secs) in &outcome.stage_seconds {
        let _ = writeln!(m, "* {name}: {secs:.2} s");
    }
    let _ = writeln!(m, "* total: {total:.2} s");
    if let Some(t) = &outcome.timing {
        m.push_str(&t.markdown());
    }
}
