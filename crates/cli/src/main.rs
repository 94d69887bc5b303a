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
    /// Forward kinematics: world x,y,z [mm] of each row's TCP.
    Fk(cmd::fk::Args),
    /// Gravity torques tau{i} [N·m] of every revolute joint i, for each row (tau2..tau7 on the
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
    /// Serve the whole virtual cell over TCP (Meca500, Zaber, Sylvac gauges, cell control).
    SimCell(cmd::sim_cell::Args),
    /// Write a cell file (format version 2) from the serial chain between two links of a URDF.
    ImportUrdf(cmd::import_urdf::Args),
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
        Command::SimCell(a) => cmd::sim_cell::run(a),
        Command::ImportUrdf(a) => cmd::import_urdf::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
