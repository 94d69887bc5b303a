//! The `vatcal` command: every pipeline stage of the calibration as a subcommand.
//!
//! Each subcommand lives in its own module under `cmd/` with an `Args` struct and a `run`
//! function; this file only dispatches.

use clap::{Parser, Subcommand};

mod cmd;

/// vatcal — calibrate a robot-held-part vat printer (Meca500 on a Zaber guide) with a TriCal
/// probe. Units at this boundary: mm and degrees.
#[derive(Debug, Parser)]
#[command(name = "vatcal", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Forward kinematics: world x,y,z \[mm\] of each row's TCP.
    Fk(cmd::fk::Args),
    /// Gravity torques tau{i} \[N·m\] of every revolute joint i, for each row (tau2..tau7 on the
    /// canonical cell).
    Torque(cmd::torque::Args),
    /// Identifiability report (rank, redundant parameters, O1..O5) of a measurement set.
    Observability(cmd::observability::Args),
    /// Detmax selection of N measurement poses from a candidate set.
    Select(cmd::select::Args),
    /// Identify model parameters from probe (and/or tracker) measurements.
    Identify(cmd::identify::Args),
    /// Validate one or two models against tracker measurements.
    Validate(cmd::validate::Args),
    /// Plan a measurement campaign: IK candidates, collisions, Detmax, tour, paths.
    Plan(cmd::plan::Args),
    /// Run the whole simulated calibration on the virtual cell and write a report.
    Demo(cmd::demo::Args),
    /// Find missing physical effects in the model, add them, and show the gap shrink.
    Discover(cmd::discover::Args),
    /// Joint targets (and corrected poses / Meca500 programs) that make the cell reach
    /// requested world poses under the calibrated model.
    Compensate(cmd::compensate::Args),
    /// Run a planned measurement campaign on the cell named by a devices file.
    Campaign(cmd::campaign::Args),
    /// The whole calibration (plan, campaign, identify, discovery, validation, compensation,
    /// report) on the devices of a devices file, as resumable stages of one run folder.
    Calibrate(cmd::calibrate::Args),
    /// Serve the whole virtual cell over TCP (Meca500, Zaber, Sylvac gauges, cell control).
    SimCell(cmd::sim_cell::Args),
    /// Write a cell file (format version 2) from the serial chain between two links of a URDF.
    ImportUrdf(cmd::import_urdf::Args),
    /// Consistency and distance errors of models on fixed points at unknown places (e.g. a
    /// sphere seated in the sockets of a fixture), per file (placement).
    EvaluateFixedPoints(cmd::evaluate_fixed_points::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Fk(a) => cmd::fk::run(a),
        Command::Torque(a) => cmd::torque::run(a),
        Command::Observability(a) => cmd::observability::run(a),
        Command::Select(a) => cmd::select::run(a),
        Command::Identify(a) => cmd::identify::run(a),
        Command::Validate(a) => cmd::validate::run(a),
        Command::Plan(a) => cmd::plan::run(a),
        Command::Demo(a) => cmd::demo::run(a),
        Command::Discover(a) => cmd::discover::run(a),
        Command::Compensate(a) => cmd::compensate::run(a),
        Command::Campaign(a) => cmd::campaign::run(a),
        Command::Calibrate(a) => cmd::calibrate::run(a),
        Command::SimCell(a) => cmd::sim_cell::run(a),
        Command::ImportUrdf(a) => cmd::import_urdf::run(a),
        Command::EvaluateFixedPoints(a) => cmd::evaluate_fixed_points::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_text(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes joined by `": "` (as `{:#}` does), leaving out a cause whose text
/// already ends the message: many library errors show their source at the end of their own
/// message (`"invalid plan: {0}"`) as well as returning it from `source()`, and the chain
/// would print it twice.
fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let message = cause.to_string();
        if message.is_empty() || text.ends_with(&message) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&message);
    }
    text
}

#[cfg(test)]
mod tests {
    use super::error_text;
    use std::fmt;

    #[derive(Debug)]
    struct Inner;
    impl fmt::Display for Inner {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "the plan has no steps")
        }
    }
    impl std::error::Error for Inner {}

    /// An error with a source, showing it in its own message (`shown`) or not.
    #[derive(Debug)]
    struct Plan {
        shown: bool,
        source: Inner,
    }
    impl fmt::Display for Plan {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            if self.shown { write!(f, "invalid plan: {}", self.source) } else { write!(f, "invalid plan") }
        }
    }
    impl std::error::Error for Plan {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.source)
        }
    }

    #[test]
    fn a_source_shown_in_its_message_is_printed_once() {
        let e = anyhow::Error::new(Plan { shown: true, source: Inner }).context("campaign.toml");
        assert_eq!(error_text(&e), "campaign.toml: invalid plan: the plan has no steps");
        // `{:#}` repeats it
        assert_eq!(
            format!("{e:#}"),
            "campaign.toml: invalid plan: the plan has no steps: the plan has no steps"
        );
    }

    #[test]
    fn a_source_not_in_its_message_is_printed_after_it() {
        let e = anyhow::Error::new(Plan { shown: false, source: Inner }).context("campaign.toml");
        assert_eq!(error_text(&e), "campaign.toml: invalid plan: the plan has no steps");
        assert_eq!(error_text(&anyhow::anyhow!("plain")), "plain");
        // a cause that only occurs inside the message is still printed
        let e = anyhow::Error::new(Plan { shown: false, source: Inner })
            .context("the plan has no steps (1 of 2)");
        assert_eq!(error_text(&e), "the plan has no steps (1 of 2): invalid plan: the plan has no steps");
    }
}
