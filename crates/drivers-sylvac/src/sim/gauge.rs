//! The simulated gauge: a pure state machine (plunger position, unit, preset, hold, noise).

use std::time::Duration;

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::SimConfig;
use crate::codec::{Command, GaugeError, MM_PER_INCH, Unit, format_value, parse_value};

/// A snapshot of the simulated gauge.
#[derive(Debug, Clone, PartialEq)]
pub struct SimState {
    /// plunger position \[mm\] (0 = fully extended)
    pub plunger_mm: f64,
    /// display unit
    pub unit: Unit,
    /// preset active
    pub preset_on: bool,
    /// preset value \[mm\]
    pub preset_mm: f64,
    /// noise-free displayed value \[mm\] (before quantisation), `None` out of range
    pub display_mm: Option<f64>,
    /// continuous output on (`OUT1`)
    pub continuous_output: bool,
}

/// The simulated gauge.
#[derive(Debug)]
pub struct SimGauge {
    config: SimConfig,
    plunger_mm: f64,
    unit: Unit,
    preset_on: bool,
    preset_mm: f64,
    /// plunger position at which the preset value was set \[mm\]
    anchor_mm: f64,
    hold: Option<String>,
    keypad: bool,
    unit_change_allowed: bool,
    continuous_output: bool,
    sensor_error: bool,
    rng: ChaCha8Rng,
}

impl SimGauge {
    /// A gauge with the plunger at `config.initial_plunger_mm`, in mm, no preset.
    pub fn new(config: SimConfig) -> Self {
        Self {
            plunger_mm: config.initial_plunger_mm,
            unit: Unit::Mm,
            preset_on: config.zeroed_at_mm.is_some(),
            preset_mm: 0.0,
            anchor_mm: config.zeroed_at_mm.unwrap_or(0.0),
            hold: None,
            keypad: true,
            unit_change_allowed: true,
            continuous_output: false,
            sensor_error: false,
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            config,
        }
    }

    /// Moves the plunger (test hook: the physical position, 0 = fully extended).
    pub fn set_plunger_mm(&mut self, mm: f64) {
        self.plunger_mm = mm;
    }

    /// Injects (or clears) a sensor fault: `?` answers `ERR0`.
    pub fn set_sensor_error(&mut self, on: bool) {
        self.sensor_error = on;
    }

    /// Whether continuous output (`OUT1`) is on.
    pub fn continuous_output(&self) -> bool {
        self.continuous_output
    }

    /// Where the plunger is now \[mm\]: the [`PlungerSource`](super::PlungerSource)'s answer
    /// if there is one, else the last [`SimGauge::set_plunger_mm`].
    fn plunger_now_mm(&self) -> f64 {
        self.config.plunger.as_ref().map_or(self.plunger_mm, |p| p.plunger_mm())
    }

    /// Noise-free displayed value \[mm\], `None` beyond the measuring range.
    fn display_mm(&self) -> Option<f64> {
        let plunger = self.plunger_now_mm();
        if !(0.0..=self.config.range_mm).contains(&plunger) {
            return None;
        }
        Some(if self.preset_on { plunger - self.anchor_mm + self.preset_mm } else { plunger })
    }

    /// A snapshot.
    pub fn snapshot(&self) -> SimState {
        SimState {
            plunger_mm: self.plunger_now_mm(),
            unit: self.unit,
            preset_on: self.preset_on,
            preset_mm: self.preset_mm,
            display_mm: self.display_mm(),
            continuous_output: self.continuous_output,
        }
    }

    fn decimals(&self) -> usize {
        match self.unit {
            Unit::Mm => self.config.decimals_mm,
            Unit::Inch => self.config.decimals_mm + 1,
        }
    }

    fn format_in_unit(&self, mm: f64) -> String {
        format_value(self.unit.from_mm(mm), 3, self.decimals())
    }

    /// The `?` answer: the displayed value (noise added, quantised to the resolution) or an
    /// error.
    pub fn value_answer(&mut self, _now: Duration) -> String {
        if self.sensor_error {
            return GaugeError::Sensor.to_text();
        }
        if let Some(frozen) = &self.hold {
            return frozen.clone();
        }
        match self.display_mm() {
            None => GaugeError::RangeExceeded.to_text(),
            Some(mm) => {
                let noisy = mm + self.noise_mm();
                let q = self.config.resolution_mm;
                let quantised = if q > 0.0 { (noisy / q).round() * q } else { noisy };
                self.format_in_unit(quantised)
            }
        }
    }

    fn noise_mm(&mut self) -> f64 {
        let world = self.config.plunger.as_ref().map_or(0.0, |p| p.reading_noise_mm());
        world
            + match Normal::new(0.0, self.config.noise_std_mm) {
                Ok(n) if self.config.noise_std_mm > 0.0 => n.sample(&mut self.rng),
                _ => 0.0,
            }
    }

    /// Handles one command line; returns the answer line, if any (setters are silent unless
    /// `config.ack_setters`).
    pub fn handle_line(&mut self, line: &str, now: Duration) -> Option<String> {
        let ack = |s: &Self| s.config.ack_setters.then(|| "OK".to_owned());
        let Some(command) = Command::parse(line) else {
            return Some(GaugeError::UnknownCommand.to_text());
        };
        match command {
            Command::Read => Some(self.value_answer(now)),
            Command::Id => Some(self.config.id.clone()),
            Command::Version => Some(self.config.version.clone()),
            Command::UnitQuery => Some(self.unit.as_str().to_owned()),
            Command::SetUnit(u) => {
                if !self.unit_change_allowed {
                    return Some(GaugeError::UnknownCommand.to_text());
                }
                self.unit = u;
                ack(self)
            }
            Command::UnitChangeAllowed(b) => {
                self.unit_change_allowed = b;
                ack(self)
            }
            Command::Settings => Some(format!(
                "{} STO{} KEY{} BAT1",
                self.unit.as_str(),
                u8::from(self.hold.is_some()),
                u8::from(self.keypad)
            )),
            Command::Battery => Some("BAT1".to_owned()),
            Command::PresetQuery => Some(self.format_in_unit(self.preset_mm)),
            Command::Preset(v) => {
                let mm = match self.unit {
                    Unit::Mm => v,
                    Unit::Inch => v * MM_PER_INCH,
                };
                if mm.abs() > crate::codec::MAX_PRESET_MM {
                    return Some(GaugeError::RangeExceeded.to_text());
                }
                self.preset_mm = mm;
                self.anchor_mm = self.plunger_now_mm();
                if !self.config.preset_requires_on {
                    self.preset_on = true;
                }
                ack(self)
            }
            Command::PresetMode(on) => {
                self.preset_on = on;
                ack(self)
            }
            Command::HoldQuery => Some(format!("STO{}", u8::from(self.hold.is_some()))),
            Command::Hold(on) => {
                self.hold = if on { Some(self.value_answer(now)) } else { None };
                ack(self)
            }
            Command::KeypadQuery => Some(format!("KEY{}", u8::from(self.keypad))),
            Command::Keypad(on) => {
                self.keypad = on;
                ack(self)
            }
            Command::ContinuousOutput(on) => {
                self.continuous_output = on;
                ack(self)
            }
            Command::NotifyOnChangeOnly(_) => ack(self),
        }
    }

    /// Parses a displayed value back to mm (for tests).
    pub fn answer_to_mm(&self, answer: &str) -> Option<f64> {
        parse_value(answer).ok().map(|v| self.unit.to_mm(v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn send(g: &mut SimGauge, line: &str) -> Option<String> {
        g.handle_line(line, Duration::ZERO)
    }

    #[test]
    fn reads_presets_and_range() {
        let mut g = SimGauge::new(SimConfig::default());
        g.set_plunger_mm(1.2345);
        assert_eq!(send(&mut g, "?").as_deref(), Some("+001.2345"));
        assert_eq!(send(&mut g, "PRE +006.3500"), None, "setters are silent by default");
        assert_eq!(send(&mut g, "?").as_deref(), Some("+006.3500"));
        g.set_plunger_mm(1.0);
        assert_eq!(send(&mut g, "?").as_deref(), Some("+006.1155"));
        assert_eq!(send(&mut g, "PRE?").as_deref(), Some("+006.3500"));
        assert_eq!(send(&mut g, "PRE OFF"), None);
        assert_eq!(send(&mut g, "?").as_deref(), Some("+001.0000"));
        g.set_plunger_mm(13.0);
        assert_eq!(send(&mut g, "?").as_deref(), Some("ERR3"));
        g.set_plunger_mm(-0.1);
        assert_eq!(send(&mut g, "?").as_deref(), Some("ERR3"));
        assert_eq!(send(&mut g, "FAC RST").as_deref(), Some("ERR1"));
        assert_eq!(send(&mut g, "ID?").as_deref(), Some("SY289"));
    }

    #[test]
    fn inch_mode_hold_and_sensor_fault() {
        let mut g = SimGauge::new(SimConfig::default());
        g.set_plunger_mm(2.54);
        send(&mut g, "IN");
        assert_eq!(send(&mut g, "UNI?").as_deref(), Some("IN"));
        assert_eq!(send(&mut g, "?").as_deref(), Some("+000.10000"));
        send(&mut g, "MM");
        send(&mut g, "STO1");
        g.set_plunger_mm(3.0);
        assert_eq!(send(&mut g, "?").as_deref(), Some("+002.5400"), "frozen display");
        send(&mut g, "STO0");
        assert_eq!(send(&mut g, "?").as_deref(), Some("+003.0000"));
        g.set_sensor_error(true);
        assert_eq!(send(&mut g, "?").as_deref(), Some("ERR0"));
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_lines_never_panic(
            lines in proptest::collection::vec("(PRE |STO|OUT|UNI|KEY|SVR|\\?|ID\\?|MM|IN)?[ -~]{0,20}", 0..20),
            plunger in -5.0f64..20.0,
        ) {
            let mut g = SimGauge::new(SimConfig { noise_std_mm: 0.001, ..SimConfig::default() });
            g.set_plunger_mm(plunger);
            for line in &lines {
                let _ = send(&mut g, line);
            }
            let _ = g.value_answer(Duration::ZERO);
        }
    }

    #[test]
    fn noise_is_seeded_and_quantised() {
        let cfg = SimConfig { noise_std_mm: 0.0003, seed: 7, ..SimConfig::default() };
        let read = |cfg: &SimConfig| {
            let mut g = SimGauge::new(cfg.clone());
            g.set_plunger_mm(5.0);
            (0..20).map(|_| g.value_answer(Duration::ZERO)).collect::<Vec<_>>()
        };
        let a = read(&cfg);
        assert_eq!(a, read(&cfg), "same seed, same readings");
        assert!(a.iter().any(|v| v != "+005.0000"), "noise present");
        for v in &a {
            let mm = parse_value(v).unwrap_or(f64::NAN);
            assert!((mm - 5.0).abs() < 0.003 && ((mm * 1e4).round() - mm * 1e4).abs() < 1e-6, "{v}");
        }
    }
}
