//! The progress bars of the commands that run pipeline stages (`vatcal demo`, `vatcal
//! calibrate`, `vatcal campaign`).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use vatcal_pipeline::{Progress, Stage, StepProgress};

/// Draws the pipeline's progress with indicatif on stderr: a spinner for stages without
/// steps, a bar with measurements done / planned and the time left for campaigns; prints
/// the summary line of every finished stage on stdout.
#[derive(Debug)]
pub struct BarProgress {
    draw: bool,
    bar: Option<ProgressBar>,
}

impl BarProgress {
    /// Bars only if `draw` (normally: stderr is a terminal and `--quiet` is not given).
    pub fn new(draw: bool) -> Self {
        Self { draw, bar: None }
    }

    /// Removes the current bar.
    pub fn clear(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

impl Progress for BarProgress {
    fn stage_started(&mut self, stage: Stage, steps: Option<usize>) {
        self.clear();
        if !self.draw {
            return;
        }
        let bar = match steps {
            Some(n) => {
                let bar = ProgressBar::with_draw_target(Some(n as u64), ProgressDrawTarget::stderr());
                if let Ok(style) =
                    ProgressStyle::with_template("{prefix} [{elapsed_precise}] {wide_bar} {msg}")
                {
                    bar.set_style(style);
                }
                bar
            }
            None => {
                let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
                bar.enable_steady_tick(std::time::Duration::from_millis(120));
                bar
            }
        };
        bar.set_prefix(stage.name());
        self.bar = Some(bar);
    }

    fn step_done(&mut self, _stage: Stage, p: &StepProgress) {
        if let Some(bar) = &self.bar {
            bar.set_position(p.steps_done as u64);
            let eta = p.eta.map_or("?".to_string(), |d| indicatif::HumanDuration(d).to_string());
            bar.set_message(format!(
                "{}/{} measurements, {}/{} steps, {eta} left",
                p.measurements_done, p.measurements_planned, p.steps_done, p.steps_planned
            ));
        }
    }

    fn stage_finished(&mut self, _stage: Stage, summary: &str, _seconds: f64) {
        self.clear();
        if !summary.is_empty() {
            println!("  {summary}");
        }
    }
}
