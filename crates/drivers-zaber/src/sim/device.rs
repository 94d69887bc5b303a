//! The simulated device: a pure state machine fed with parsed commands and the current time.

use std::collections::BTreeSet;
use std::time::Duration;

use super::SimConfig;
use crate::codec::{Alert, Command, Message, Reply, Status, Warning, format_warning_list, top_warning};

/// Device units → physical units (protocols.md §2.6, \[UNC\]): microsteps/s = maxspeed / 1.6384,
/// microsteps/s² = accel × 10000 / 1.6384.
pub const SPEED_UNIT_DIVISOR: f64 = 1.6384;
/// See [`SPEED_UNIT_DIVISOR`].
pub const ACCEL_UNIT_FACTOR: f64 = 10_000.0 / 1.6384;

/// A trapezoidal move.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Profile {
    from: f64,
    to: f64,
    start: Duration,
    /// cruise speed [µsteps/s]
    v: f64,
    /// acceleration [µsteps/s²]
    a: f64,
    homing: bool,
}

impl Profile {
    fn distance(&self) -> f64 {
        (self.to - self.from).abs()
    }

    /// (accel time, cruise time) \[s\].
    fn phases(&self) -> (f64, f64) {
        let d = self.distance();
        if d * self.a < self.v * self.v {
            ((d / self.a).sqrt(), 0.0)
        } else {
            (self.v / self.a, (d - self.v * self.v / self.a) / self.v)
        }
    }

    fn duration_s(&self) -> f64 {
        let (ta, tc) = self.phases();
        2.0 * ta + tc
    }

    /// Position after `t` seconds of motion.
    fn position(&self, t: f64) -> f64 {
        let (ta, tc) = self.phases();
        let total = 2.0 * ta + tc;
        let d = self.distance();
        let s = if t <= 0.0 {
            0.0
        } else if t < ta {
            0.5 * self.a * t * t
        } else if t < ta + tc {
            0.5 * self.a * ta * ta + self.a * ta * (t - ta)
        } else if t < total {
            d - 0.5 * self.a * (total - t) * (total - t)
        } else {
            d
        };
        self.from + s.min(d) * (self.to - self.from).signum()
    }
}

/// A snapshot of the simulated device.
#[derive(Debug, Clone, PartialEq)]
pub struct SimState {
    /// position now \[microsteps\]
    pub pos_microsteps: f64,
    /// moving
    pub busy: bool,
    /// homed since power-up
    pub homed: bool,
    /// active flags
    pub flags: Vec<Warning>,
    /// `maxspeed` [device units]
    pub maxspeed: i64,
    /// `accel` [device units]
    pub accel: i64,
    /// travel limits \[microsteps\]
    pub limits: (i64, i64),
}

/// The simulated device (one axis).
#[derive(Debug)]
pub struct SimDevice {
    config: SimConfig,
    pos: f64,
    motion: Option<Profile>,
    homed: bool,
    flags: BTreeSet<Warning>,
    limit_min: i64,
    limit_max: i64,
    maxspeed: i64,
    accel: i64,
    comm_alert: bool,
    driver_enabled: bool,
}

impl SimDevice {
    /// A freshly powered-up device: unhomed (`WR`), at `config.power_up_microsteps`.
    pub fn new(config: SimConfig) -> Self {
        let mut d = Self {
            pos: config.power_up_microsteps as f64,
            limit_min: 0,
            limit_max: config.limit_max_microsteps(),
            maxspeed: config.maxspeed,
            accel: config.accel,
            motion: None,
            homed: false,
            flags: BTreeSet::new(),
            comm_alert: false,
            driver_enabled: true,
            config,
        };
        d.power_up();
        if d.config.start_homed {
            d.homed = true;
            d.flags.clear();
        }
        d
    }

    fn power_up(&mut self) {
        self.motion = None;
        self.homed = false;
        self.flags.clear();
        self.flags.insert(Warning::NO_REFERENCE);
        self.pos = self.config.power_up_microsteps as f64;
        self.driver_enabled = true;
    }

    /// Position now \[microsteps\].
    pub fn position(&self, now: Duration) -> f64 {
        match &self.motion {
            Some(p) => p.position(self.elapsed_s(p, now)),
            None => self.pos,
        }
    }

    fn elapsed_s(&self, p: &Profile, now: Duration) -> f64 {
        now.saturating_sub(p.start).as_secs_f64() * self.config.time_scale
    }

    /// A snapshot.
    pub fn snapshot(&self, now: Duration) -> SimState {
        let mut flags: Vec<Warning> = self.flags.iter().copied().collect();
        flags.sort_by_key(|w| (w.priority(), w.0));
        SimState {
            pos_microsteps: self.position(now),
            busy: self.motion.is_some(),
            homed: self.homed,
            flags,
            maxspeed: self.maxspeed,
            accel: self.accel,
            limits: (self.limit_min, self.limit_max),
        }
    }

    /// Handles a command; `None` if it is addressed to another device.
    pub fn handle(&mut self, cmd: &Command, now: Duration) -> Option<Message> {
        if cmd.address != 0 && cmd.address != self.config.address {
            return None;
        }
        self.tick(now);
        let result = if cmd.axis > 1 { Err("BADAXIS".to_owned()) } else { self.execute(cmd, now) };
        let (accepted, data) = match result {
            Ok(data) => (true, data),
            Err(reason) => (false, reason),
        };
        Some(Message::Reply(Reply {
            address: self.config.address,
            axis: cmd.axis,
            id: cmd.id,
            accepted,
            status: if self.motion.is_some() { Status::Busy } else { Status::Idle },
            warning: top_warning(&self.flags),
            data,
        }))
    }

    /// Runs one command; `Ok(data)` or `Err(rejection reason)`.
    fn execute(&mut self, cmd: &Command, now: Duration) -> Result<String, String> {
        let words: Vec<&str> = cmd.text.split_whitespace().collect();
        let ok = || Ok("0".to_owned());
        match words.as_slice() {
            [] => ok(),
            ["home"] => {
                self.start(self.limit_min as f64, true, now)?;
                ok()
            }
            ["move", "abs", n] => {
                let target = parse_i64(n)?;
                self.check_target(target)?;
                self.start(target as f64, false, now)?;
                ok()
            }
            ["move", "rel", n] => {
                let target = (self.position(now).round() as i64)
                    .checked_add(parse_i64(n)?)
                    .ok_or_else(|| "BADDATA".to_owned())?;
                self.check_target(target)?;
                self.start(target as f64, false, now)?;
                ok()
            }
            ["stop"] | ["estop"] => {
                self.halt(now, Warning::INTERRUPTED);
                ok()
            }
            ["get", setting] => self.get(setting, now),
            ["set", setting, value] => {
                self.set(setting, value)?;
                ok()
            }
            ["warnings"] => Ok(self.warning_list()),
            ["warnings", "clear"] => {
                let list = self.warning_list();
                let keep = [Warning::NO_REFERENCE, Warning::NOT_HOMED, Warning::DRIVER_DISABLED];
                self.flags.retain(|f| keep.contains(f));
                Ok(list)
            }
            ["system", "reset"] => {
                self.power_up();
                ok()
            }
            ["driver", "disable"] => {
                self.halt(now, Warning::INTERRUPTED);
                self.driver_enabled = false;
                self.flags.insert(Warning::DRIVER_DISABLED);
                ok()
            }
            ["driver", "enable"] => {
                self.driver_enabled = true;
                self.flags.remove(&Warning::DRIVER_DISABLED);
                ok()
            }
            _ => Err("BADCOMMAND".to_owned()),
        }
    }

    fn check_target(&self, target: i64) -> Result<(), String> {
        if !self.homed && self.config.reject_move_before_home {
            return Err("BADDATA".to_owned());
        }
        if target < self.limit_min || target > self.limit_max {
            return Err("BADDATA".to_owned());
        }
        Ok(())
    }

    fn start(&mut self, target: f64, homing: bool, now: Duration) -> Result<(), String> {
        if !self.driver_enabled {
            return Err("DRIVERDISABLED".to_owned());
        }
        if self.motion.is_some() {
            self.flags.insert(Warning::INTERRUPTED);
        }
        let from = self.position(now);
        if let Some(backend) = &self.config.backend {
            backend.motion_started_at(from, target, self.maxspeed);
        }
        self.motion = Some(Profile {
            from,
            to: target,
            start: now,
            v: (self.maxspeed as f64 / SPEED_UNIT_DIVISOR).max(1.0),
            a: (self.accel as f64 * ACCEL_UNIT_FACTOR).max(1.0),
            homing,
        });
        self.pos = from;
        Ok(())
    }

    /// Stops at the current position, raising `flag` if a motion was running.
    fn halt(&mut self, now: Duration, flag: Warning) {
        if self.motion.is_some() {
            self.pos = self.position(now).round();
            self.motion = None;
            self.flags.insert(flag);
        }
    }

    fn warning_list(&self) -> String {
        let mut flags: Vec<Warning> = self.flags.iter().copied().collect();
        flags.sort_by_key(|w| (w.priority(), w.0));
        format_warning_list(&flags)
    }

    fn get(&self, setting: &str, now: Duration) -> Result<String, String> {
        let c = &self.config;
        Ok(match setting {
            "pos" | "encoder.pos" => format!("{}", self.position(now).round() as i64),
            "limit.min" => self.limit_min.to_string(),
            "limit.max" => self.limit_max.to_string(),
            "maxspeed" => self.maxspeed.to_string(),
            "accel" => self.accel.to_string(),
            "resolution" => c.resolution.to_string(),
            "comm.alert" => u8::from(self.comm_alert).to_string(),
            "deviceid" => c.device_id.to_string(),
            "system.serial" => c.serial.to_string(),
            "version" => c.version.clone(),
            "version.build" => c.version_build.to_string(),
            "system.axiscount" => "1".to_owned(),
            "peripheralid" => "0".to_owned(),
            _ => return Err("BADCOMMAND".to_owned()),
        })
    }

    fn set(&mut self, setting: &str, value: &str) -> Result<(), String> {
        let v = parse_i64(value)?;
        match setting {
            "maxspeed" if v > 0 => self.maxspeed = v,
            "accel" if v > 0 => self.accel = v,
            "comm.alert" if v == 0 || v == 1 => self.comm_alert = v == 1,
            "limit.min" if v <= self.limit_max => self.limit_min = v,
            "limit.max" if v >= self.limit_min => self.limit_max = v,
            "maxspeed" | "accel" | "comm.alert" | "limit.min" | "limit.max" => {
                return Err("BADDATA".to_owned());
            }
            _ => return Err("BADCOMMAND".to_owned()),
        }
        Ok(())
    }

    /// Advances to `now`; returns alerts (`!AA X IDLE WARN`) for finished moves if
    /// `comm.alert` is 1.
    pub fn tick(&mut self, now: Duration) -> Vec<Message> {
        let Some(p) = self.motion else { return Vec::new() };
        if self.elapsed_s(&p, now) < p.duration_s() {
            return Vec::new();
        }
        self.pos = p.to;
        self.motion = None;
        if p.homing {
            self.homed = true;
            self.flags.remove(&Warning::NO_REFERENCE);
            self.flags.remove(&Warning::NOT_HOMED);
        }
        if self.comm_alert { vec![self.alert()] } else { Vec::new() }
    }

    fn alert(&self) -> Message {
        Message::Alert(Alert {
            address: self.config.address,
            axis: 1,
            status: if self.motion.is_some() { Status::Busy } else { Status::Idle },
            warning: top_warning(&self.flags),
            data: String::new(),
        })
    }

    /// Fault injection: the motor stalls (`FS`), the move stops where it is.
    pub fn inject_stall(&mut self, now: Duration) -> Vec<Message> {
        self.inject(now, Warning::STALL)
    }

    /// Fault injection: a limit switch triggers unexpectedly (`WL`), the move stops.
    pub fn inject_limit_hit(&mut self, now: Duration) -> Vec<Message> {
        self.inject(now, Warning::LIMIT)
    }

    fn inject(&mut self, now: Duration, flag: Warning) -> Vec<Message> {
        if self.motion.is_some() {
            self.pos = self.position(now).round();
            self.motion = None;
        }
        self.flags.insert(flag);
        if self.comm_alert { vec![self.alert()] } else { Vec::new() }
    }
}

fn parse_i64(s: &str) -> Result<i64, String> {
    s.parse::<i64>().map_err(|_| "BADDATA".to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Duration {
        Duration::from_millis(v)
    }

    fn send(d: &mut SimDevice, line: &str, now: Duration) -> String {
        let (cmd, checksum) = Command::parse(line).unwrap_or_else(|e| panic!("{e}"));
        d.handle(&cmd, now).map(|m| m.to_line(checksum)).unwrap_or_default()
    }

    #[test]
    fn lifecycle_of_the_reference() {
        // after power-up every reply shows WR; after home it becomes --
        let mut d = SimDevice::new(SimConfig::default());
        assert_eq!(send(&mut d, "/1 1 00 get pos:2C", ms(0)), "@01 1 00 OK IDLE WR 0:BD");
        assert_eq!(send(&mut d, "/1 0 warnings", ms(0)), "@01 0 OK IDLE WR 01 WR");
        assert_eq!(send(&mut d, "/1 1 move abs 1000", ms(0)), "@01 1 RJ IDLE WR BADDATA");
        assert_eq!(send(&mut d, "/1 1 home", ms(0)), "@01 1 OK BUSY WR 0");
        assert_eq!(send(&mut d, "/1 1", ms(0)), "@01 1 OK IDLE -- 0");
        assert_eq!(send(&mut d, "/1 1 06 move abs 100000", ms(0)), "@01 1 06 OK BUSY -- 0");
        assert_eq!(send(&mut d, "/2 1 get pos", ms(0)), "", "other address: silent");
        assert_eq!(send(&mut d, "/1 5 get pos", ms(0)), "@01 5 RJ BUSY -- BADAXIS");
        assert_eq!(send(&mut d, "/1 1 dance", ms(0)), "@01 1 RJ BUSY -- BADCOMMAND");
        let t = Duration::from_secs(10);
        assert_eq!(send(&mut d, "/1 1 09 get pos", t), "@01 1 09 OK IDLE -- 100000");
        assert_eq!(
            send(&mut d, "/0 0 get deviceid", t),
            format!("@01 0 OK IDLE -- {}", SimConfig::default().device_id)
        );
    }

    #[test]
    fn trapezoid_timing() {
        let p = Profile { from: 0.0, to: 1000.0, start: ms(0), v: 100.0, a: 100.0, homing: false };
        // accelerate 1 s (50 steps), cruise 9 s, decelerate 1 s
        assert!((p.duration_s() - 11.0).abs() < 1e-12);
        assert!((p.position(1.0) - 50.0).abs() < 1e-9);
        assert!((p.position(5.5) - 500.0).abs() < 1e-9);
        assert!((p.position(11.0) - 1000.0).abs() < 1e-9);
        let tri = Profile { to: -50.0, ..p };
        assert!((tri.duration_s() - 2.0 * (0.5f64).sqrt()).abs() < 1e-12);
        assert!((tri.position(10.0) + 50.0).abs() < 1e-12);
    }

    #[test]
    fn interruptions_and_faults_raise_flags() {
        let mut d = SimDevice::new(SimConfig { start_homed: true, ..SimConfig::default() });
        send(&mut d, "/1 1 move abs 500000", ms(0));
        send(&mut d, "/1 1 move abs 1000", ms(10));
        assert_eq!(send(&mut d, "/1 0 warnings", ms(10)), "@01 0 OK BUSY NI 01 NI");
        send(&mut d, "/1 0 warnings clear", ms(10));
        d.inject_stall(ms(20));
        assert_eq!(send(&mut d, "/1 1", ms(20)), "@01 1 OK IDLE FS 0");
        assert_eq!(send(&mut d, "/1 0 warnings clear", ms(20)), "@01 0 OK IDLE -- 01 FS");
        assert_eq!(send(&mut d, "/1 0 warnings", ms(20)), "@01 0 OK IDLE -- 00");
        assert_eq!(send(&mut d, "/1 1 move abs 99999999999", ms(20)), "@01 1 RJ IDLE -- BADDATA");
        assert_eq!(send(&mut d, "/1 1 move rel 9223372036854775807", ms(20)), "@01 1 RJ IDLE -- BADDATA");
        assert_eq!(send(&mut d, "/1 1 set maxspeed 0", ms(20)), "@01 1 RJ IDLE -- BADDATA");
        assert_eq!(send(&mut d, "/1 1 driver disable", ms(20)), "@01 1 OK IDLE FO 0");
        assert_eq!(send(&mut d, "/1 1 home", ms(20)), "@01 1 RJ IDLE FO DRIVERDISABLED");
        send(&mut d, "/1 1 driver enable", ms(20));
        assert_eq!(send(&mut d, "/1 0 system reset", ms(20)), "@01 0 OK IDLE WR 0");
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_commands_never_panic(
            lines in proptest::collection::vec(
                proptest::prelude::prop_oneof![
                    "/[0-9]{0,3} [0-9]{0,2} (home|stop|estop|move abs|move rel|get pos|set maxspeed|set accel|set limit.max|warnings|warnings clear|system reset|driver disable|driver enable) ?-?[0-9]{0,20}",
                    "[ -~]{0,40}",
                ],
                0..30,
            ),
        ) {
            let mut d = SimDevice::new(SimConfig { start_homed: true, ..SimConfig::default() });
            for (i, line) in lines.iter().enumerate() {
                let now = ms(7 * i as u64);
                if let Ok((cmd, _)) = Command::parse(line) {
                    let _ = d.handle(&cmd, now);
                }
                let _ = d.tick(now);
            }
            let s = d.snapshot(Duration::from_secs(100_000));
            proptest::prop_assert!(s.pos_microsteps.is_finite());
        }
    }

    #[test]
    fn alerts_when_enabled() {
        let mut d = SimDevice::new(SimConfig { start_homed: true, ..SimConfig::default() });
        send(&mut d, "/1 0 set comm.alert 1", ms(0));
        send(&mut d, "/1 1 move abs 100", ms(0));
        let alerts: Vec<String> = d.tick(Duration::from_secs(1)).iter().map(|m| m.to_line(false)).collect();
        assert_eq!(alerts, ["!01 1 IDLE --"]);
    }
}
