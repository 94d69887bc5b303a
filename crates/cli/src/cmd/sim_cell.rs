//! `vatcal sim-cell`: the whole virtual cell over TCP — Meca500 control/monitoring, Zaber
//! ASCII (when the cell has a guide), three Sylvac gauges, the laser tracker and the
//! cell-control port — driven by
//! one hidden true cell, until Ctrl-C or SIGTERM. The cell is the canonical one or, with
//! `--model`, any arm of six revolute joints (with or without a guide) behind the Meca500
//! protocol. The work is done by `vatcal_sim_cell::SimCell`; see `docs/drivers.md`.

use std::io::Write;
use std::net::IpAddr;
use std::path::PathBuf;

use anyhow::Context;
use vatcal_sim_cell::{Ports, SimCell, SimCellOptions};

/// Arguments of `vatcal sim-cell`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Address every port listens on (loopback unless told otherwise).
    #[arg(long, default_value = "127.0.0.1")]
    pub bind: IpAddr,
    /// Seed of the hidden true cell, the probe imperfections and the noise (the same hidden
    /// truth as `vatcal demo --seed S`).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Nominal cell file: what the robot controller believes (default: the built-in
    /// fixtures/meca500-zaber.toml, as `vatcal demo`). Any arm of six revolute joints, with or
    /// without a prismatic guide as joint 1, served behind the Meca500 protocol (joint-space
    /// and relative linear moves); without a guide there is no Zaber port.
    #[arg(long, value_name = "CELL.toml")]
    pub model: Option<PathBuf>,
    /// The hidden true cell: `ideal` (errors of the 34 parameters only), `paper-like` (plus the
    /// physics they miss, docs/virtual-cell.md) or a cell file of the truth — the same truth as
    /// `vatcal demo --seed S --truth T`.
    #[arg(long, default_value = "paper-like", value_name = "ideal|paper-like|FILE")]
    pub truth: vatcal_sim::truth::TruthSpec,
    /// Every duration is divided by K (1000: a 25-minute campaign in a few seconds).
    #[arg(long, default_value_t = 1.0, value_name = "K")]
    pub time_scale: f64,
    /// Switch the simulated device noise off (robot, guide, tool-changer and gauge
    /// repeatability); the probe's imperfections stay.
    #[arg(long)]
    pub no_noise: bool,
    /// Decimals of the gauges' display in mm (the S_Dial WORK Nano shows 4).
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub gauge_decimals: usize,
    /// Meca500 control port (0: any free port).
    #[arg(long, default_value_t = Ports::default().meca500_control, value_name = "P")]
    pub meca500_control_port: u16,
    /// Meca500 monitoring port.
    #[arg(long, default_value_t = Ports::default().meca500_monitoring, value_name = "P")]
    pub meca500_monitoring_port: u16,
    /// Zaber ASCII port (unused when the cell has no guide).
    #[arg(long, default_value_t = Ports::default().zaber, value_name = "P")]
    pub zaber_port: u16,
    /// Sylvac gauge 1 port.
    #[arg(long, default_value_t = Ports::default().gauges[0], value_name = "P")]
    pub gauge1_port: u16,
    /// Sylvac gauge 2 port.
    #[arg(long, default_value_t = Ports::default().gauges[1], value_name = "P")]
    pub gauge2_port: u16,
    /// Sylvac gauge 3 port.
    #[arg(long, default_value_t = Ports::default().gauges[2], value_name = "P")]
    pub gauge3_port: u16,
    /// Cell-control port (the operator: `PLACE <n>`, `PLACEMENT?`, `MASTER <n>`, `MASTER OFF`).
    #[arg(long, default_value_t = Ports::default().control, value_name = "P")]
    pub control_port: u16,
    /// Laser-tracker port (the tracker line protocol, docs/drivers.md).
    #[arg(long, default_value_t = Ports::default().tracker, value_name = "P")]
    pub tracker_port: u16,
    /// The tracker reports in the tank (world) frame, as a tracker whose software is
    /// registered already; by default it reports in its own frame (standing 2.5 m away) and the
    /// validation's registration step finds its pose.
    #[arg(long)]
    pub tracker_registered: bool,
    /// Probability that a tracker measurement loses the line of sight to its SMR (`ERR LOS`).
    #[arg(long, default_value_t = 0.0, value_name = "P")]
    pub tracker_los_loss: f64,
}

/// Runs the subcommand until Ctrl-C or SIGTERM.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut options = SimCellOptions::paper(args.seed)?;
    if let Some(path) = &args.model {
        options.nominal = super::load_model(path)?;
    }
    options.set_truth(&args.truth).with_context(|| format!("--truth {}", args.truth))?;
    options.bind = args.bind;
    options.noise = !args.no_noise;
    options.time_scale = args.time_scale;
    options.gauge_decimals = args.gauge_decimals;
    options.ports = Ports {
        meca500_control: args.meca500_control_port,
        meca500_monitoring: args.meca500_monitoring_port,
        zaber: args.zaber_port,
        gauges: [args.gauge1_port, args.gauge2_port, args.gauge3_port],
        control: args.control_port,
        tracker: args.tracker_port,
    };
    if args.tracker_registered {
        options.tracker_pose = vatcal_core::Frame::identity();
    }
    options.tracker_line_of_sight_loss = args.tracker_los_loss;

    let (stop_tx, stop_rx) = std::sync::mpsc::channel();
    ctrlc::set_handler(move || {
        let _ = stop_tx.send(());
    })
    .context("cannot install the Ctrl-C/SIGTERM handler")?;

    let cell = SimCell::start(options)?;
    let mut out = std::io::stdout().lock();
    for (name, addr) in cell.addrs().named() {
        writeln!(out, "listening {name} {addr}")?;
    }
    writeln!(
        out,
        "vatcal sim-cell: seed {}, truth {}, noise {}, time scale {}; Ctrl-C to stop",
        args.seed,
        args.truth,
        if args.no_noise { "off" } else { "on" },
        args.time_scale
    )?;
    out.flush()?;
    drop(out);

    let _ = stop_rx.recv();
    drop(cell);
    println!("vatcal sim-cell: stopped");
    Ok(())
}
