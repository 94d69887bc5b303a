//! Sans-IO codec of the Sylvac ASCII command set (protocols.md §3.3–3.4): the same short
//! CR-terminated requests and answers travel over a duplex cable, a serial-to-TCP bridge, or
//! the BLE RemoteRequest/RemoteResponse characteristics.

use std::fmt;

/// Terminator of every command and answer.
pub const CR: u8 = b'\r';

/// Longest answer line accepted.
pub const MAX_LINE_LEN: usize = 256;

/// Largest preset magnitude the gauge accepts \[mm\].
pub const MAX_PRESET_MM: f64 = 199.999;

/// Millimetres per inch.
pub const MM_PER_INCH: f64 = 25.4;

/// Display unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Unit {
    /// millimetres (`MM`)
    Mm,
    /// inches (`IN`)
    Inch,
}

impl Unit {
    /// Converts a displayed value to mm.
    pub fn to_mm(self, value: f64) -> f64 {
        match self {
            Unit::Mm => value,
            Unit::Inch => value * MM_PER_INCH,
        }
    }

    /// Converts mm to this unit.
    pub fn from_mm(self, mm: f64) -> f64 {
        match self {
            Unit::Mm => mm,
            Unit::Inch => mm / MM_PER_INCH,
        }
    }

    /// `MM` / `IN`.
    pub fn as_str(self) -> &'static str {
        match self {
            Unit::Mm => "MM",
            Unit::Inch => "IN",
        }
    }
}

/// A command of the ASCII set.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// `?`: the displayed value.
    Read,
    /// `ID?`: instrument id.
    Id,
    /// `VER?`: firmware version and date.
    Version,
    /// `UNI?`: unit.
    UnitQuery,
    /// `MM` / `IN`: switch unit.
    SetUnit(Unit),
    /// `UNI0` (lock, false) / `UNI1` (unlock, true) the unit key.
    UnitChangeAllowed(bool),
    /// `SET?`: configuration summary.
    Settings,
    /// `BAT?`: battery state.
    Battery,
    /// `PRE?`: preset value.
    PresetQuery,
    /// `PRE ±XXX.YYYY`: preset value (in the current unit).
    Preset(f64),
    /// `PRE ON` / `PRE OFF`.
    PresetMode(bool),
    /// `STO?`.
    HoldQuery,
    /// `STO0` live (false) / `STO1` frozen (true).
    Hold(bool),
    /// `KEY?`.
    KeypadQuery,
    /// `KEY0` locked (false) / `KEY1` enabled (true).
    Keypad(bool),
    /// `OUT0` / `OUT1`: continuous output off / on.
    ContinuousOutput(bool),
    /// `SVR0` notify always / `SVR1` only on change.
    NotifyOnChangeOnly(bool),
}

impl Command {
    /// The command text without terminator.
    pub fn to_text(&self) -> String {
        let bit = |b: bool| u8::from(b);
        match self {
            Command::Read => "?".to_owned(),
            Command::Id => "ID?".to_owned(),
            Command::Version => "VER?".to_owned(),
            Command::UnitQuery => "UNI?".to_owned(),
            Command::SetUnit(u) => u.as_str().to_owned(),
            Command::UnitChangeAllowed(b) => format!("UNI{}", bit(*b)),
            Command::Settings => "SET?".to_owned(),
            Command::Battery => "BAT?".to_owned(),
            Command::PresetQuery => "PRE?".to_owned(),
            Command::Preset(v) => format!("PRE {}", format_value(*v, 3, 4)),
            Command::PresetMode(on) => if *on { "PRE ON" } else { "PRE OFF" }.to_owned(),
            Command::HoldQuery => "STO?".to_owned(),
            Command::Hold(b) => format!("STO{}", bit(*b)),
            Command::KeypadQuery => "KEY?".to_owned(),
            Command::Keypad(b) => format!("KEY{}", bit(*b)),
            Command::ContinuousOutput(b) => format!("OUT{}", bit(*b)),
            Command::NotifyOnChangeOnly(b) => format!("SVR{}", bit(*b)),
        }
    }

    /// Wire bytes: the text and CR.
    pub fn encode(&self) -> Vec<u8> {
        let mut b = self.to_text().into_bytes();
        b.push(CR);
        b
    }

    /// True for commands the gauge answers with a line (queries); setters may be silent
    /// (\[UNC\], see `docs/drivers.md`).
    pub fn is_query(&self) -> bool {
        matches!(
            self,
            Command::Read
                | Command::Id
                | Command::Version
                | Command::UnitQuery
                | Command::Settings
                | Command::Battery
                | Command::PresetQuery
                | Command::HoldQuery
                | Command::KeypadQuery
        )
    }

    /// Parses a command line (terminator removed; case-insensitive, surrounding blanks
    /// ignored). `None` for anything outside this set (the gauge answers `ERR1`).
    pub fn parse(line: &str) -> Option<Self> {
        let t = line.trim().to_ascii_uppercase();
        let flag = |rest: &str| match rest {
            "0" => Some(false),
            "1" => Some(true),
            _ => None,
        };
        Some(match t.as_str() {
            "?" => Command::Read,
            "ID?" => Command::Id,
            "VER?" => Command::Version,
            "UNI?" => Command::UnitQuery,
            "MM" => Command::SetUnit(Unit::Mm),
            "IN" => Command::SetUnit(Unit::Inch),
            "SET?" => Command::Settings,
            "BAT?" => Command::Battery,
            "PRE?" => Command::PresetQuery,
            "PRE ON" => Command::PresetMode(true),
            "PRE OFF" => Command::PresetMode(false),
            "STO?" => Command::HoldQuery,
            "KEY?" => Command::KeypadQuery,
            _ => {
                if let Some(v) = t.strip_prefix("PRE ") {
                    return parse_value(v).ok().map(Command::Preset);
                }
                let (last, _) = t.char_indices().last()?;
                let (head, tail) = t.split_at(last);
                let b = flag(tail)?;
                match head {
                    "UNI" => Command::UnitChangeAllowed(b),
                    "STO" => Command::Hold(b),
                    "KEY" => Command::Keypad(b),
                    "OUT" => Command::ContinuousOutput(b),
                    "SVR" => Command::NotifyOnChangeOnly(b),
                    _ => return None,
                }
            }
        })
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_text())
    }
}

/// Error answers of the cable protocol (OPTO-RS manual).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GaugeError {
    /// `ERR0`: sensor error.
    Sensor,
    /// `ERR1`: unknown or incorrect command.
    UnknownCommand,
    /// `ERR2`: parity error.
    Parity,
    /// `ERR3`: measuring range exceeded.
    RangeExceeded,
}

impl GaugeError {
    /// The digit after `ERR`.
    pub fn code(self) -> u8 {
        match self {
            GaugeError::Sensor => 0,
            GaugeError::UnknownCommand => 1,
            GaugeError::Parity => 2,
            GaugeError::RangeExceeded => 3,
        }
    }

    /// From the digit after `ERR`.
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0 => GaugeError::Sensor,
            1 => GaugeError::UnknownCommand,
            2 => GaugeError::Parity,
            3 => GaugeError::RangeExceeded,
            _ => return None,
        })
    }

    /// `ERRn`.
    pub fn to_text(self) -> String {
        format!("ERR{}", self.code())
    }
}

impl fmt::Display for GaugeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = match self {
            GaugeError::Sensor => "sensor error",
            GaugeError::UnknownCommand => "unknown or incorrect command",
            GaugeError::Parity => "parity error",
            GaugeError::RangeExceeded => "measuring range exceeded",
        };
        write!(f, "{} ({what})", self.to_text())
    }
}

/// One answer line.
#[derive(Debug, Clone, PartialEq)]
pub enum Answer {
    /// a signed decimal value (in the display unit)
    Value(f64),
    /// `ERR0`…`ERR3`
    Error(GaugeError),
    /// anything else (`SY289`, `MM`, `BAT1`, `V1.00 01.01.2020`, …)
    Text(String),
}

impl Answer {
    /// Classifies a line (terminator removed).
    pub fn parse(line: &str) -> Self {
        let t = line.trim();
        if let Some(d) = t.strip_prefix("ERR")
            && let Some(e) = d.parse::<u8>().ok().and_then(GaugeError::from_code)
        {
            return Answer::Error(e);
        }
        match parse_value(t) {
            Ok(v) => Answer::Value(v),
            Err(_) => Answer::Text(t.to_owned()),
        }
    }
}

/// A value that is not a number.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("'{0}' is not a gauge value")]
pub struct ValueError(pub String);

/// Parses a displayed value leniently (§3.3): surrounding blanks, an optional `+`/`-` (a
/// blank sign is trimmed), any number of integer and decimal digits, an optional trailing
/// unit word (`MM`, `IN`, `mm`).
pub fn parse_value(text: &str) -> Result<f64, ValueError> {
    let err = || ValueError(text.to_owned());
    let t = text.trim();
    let t = t.trim_end_matches(|c: char| c.is_ascii_alphabetic()).trim_end();
    let (negative, digits) = match t.as_bytes().first() {
        Some(b'+') => (false, t[1..].trim_start()),
        Some(b'-') => (true, t[1..].trim_start()),
        _ => (false, t),
    };
    let valid = !digits.is_empty()
        && digits.bytes().all(|b| b.is_ascii_digit() || b == b'.')
        && digits.bytes().filter(|&b| b == b'.').count() <= 1
        && digits.bytes().any(|b| b.is_ascii_digit());
    if !valid {
        return Err(err());
    }
    let v: f64 = digits.parse().map_err(|_| err())?;
    Ok(if negative { -v } else { v })
}

/// Formats a value the way the gauge displays it: sign, `int_digits` zero-padded integer
/// digits, `decimals` decimals (`+001.2345`).
pub fn format_value(v: f64, int_digits: usize, decimals: usize) -> String {
    let width = int_digits + 1 + decimals;
    let sign =
        if v < 0.0 && format!("{:.*}", decimals, v.abs()).bytes().any(|b| b.is_ascii_digit() && b != b'0') {
            '-'
        } else {
            '+'
        };
    format!("{sign}{:0width$.decimals$}", v.abs())
}

/// Cuts a byte stream into lines on CR or LF: the shared
/// [`CrOrLfDeframer`](vatcal_hardware_traits::transport::CrOrLfDeframer) with lines of up to
/// [`MAX_LINE_LEN`] bytes, blank lines skipped. Every method of the shared
/// [`LineDeframer`](vatcal_hardware_traits::transport::LineDeframer) (`push`, `next_line`,
/// `clear`, `pending`, …) is available through `Deref`.
pub type LineDeframer = vatcal_hardware_traits::transport::CrOrLfDeframer<MAX_LINE_LEN>;

/// A line longer than [`MAX_LINE_LEN`] arrived; it was discarded (the shared
/// [`FrameError`](vatcal_hardware_traits::transport::FrameError) under its old name).
pub type LineTooLong = vatcal_hardware_traits::transport::FrameError;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn values_in_the_formats_of_the_reference() {
        assert_eq!(parse_value("+000.0124"), Ok(0.0124));
        assert_eq!(parse_value("+001.2345"), Ok(1.2345));
        assert_eq!(parse_value("-12.5"), Ok(-12.5));
        assert_eq!(parse_value(" 6.350"), Ok(6.35));
        assert_eq!(parse_value("- 0.001"), Ok(-0.001));
        assert_eq!(parse_value("+6.3500 MM"), Ok(6.35));
        assert_eq!(parse_value("12"), Ok(12.0));
        for bad in ["", "+", "SY289", "1.2.3", "ERR3", "--1", "."] {
            assert!(parse_value(bad).is_err(), "{bad}");
        }
        assert_eq!(format_value(1.2345, 3, 4), "+001.2345");
        assert_eq!(format_value(-0.00001, 3, 4), "+000.0000");
        assert_eq!(format_value(-6.35, 3, 4), "-006.3500");
    }

    #[test]
    fn answers_are_classified() {
        assert_eq!(Answer::parse("ERR3"), Answer::Error(GaugeError::RangeExceeded));
        assert_eq!(Answer::parse("ERR0\r"), Answer::Error(GaugeError::Sensor));
        assert_eq!(Answer::parse("+000.0124"), Answer::Value(0.0124));
        assert_eq!(Answer::parse("SY289"), Answer::Text("SY289".to_owned()));
        assert_eq!(Answer::parse("MM STO0 KEY1 BAT1"), Answer::Text("MM STO0 KEY1 BAT1".to_owned()));
        assert_eq!(Answer::parse("ERR9"), Answer::Text("ERR9".to_owned()));
    }

    #[test]
    fn the_paper_preset_command() {
        // the paper sets each gauge to 6.350 mm on the master ball
        assert_eq!(Command::Preset(6.35).to_text(), "PRE +006.3500");
        assert_eq!(Command::Preset(6.35).encode(), b"PRE +006.3500\r");
        assert_eq!(Command::parse("pre +6.350"), Some(Command::Preset(6.35)));
        assert_eq!(Command::parse("PRE ON"), Some(Command::PresetMode(true)));
        assert_eq!(Command::parse("FAC RST"), None);
        assert_eq!(Command::parse("OUT2"), None);
        assert_eq!(Command::parse("STOé"), None);
        assert_eq!(Command::parse(""), None);
    }

    #[test]
    fn deframer_splits_on_cr() {
        let mut d = LineDeframer::new();
        d.push(b"+001.2345\rSY289\r\n\rMM");
        let mut lines = Vec::new();
        while let Ok(Some(l)) = d.next_line() {
            lines.push(l);
        }
        assert_eq!(lines, ["+001.2345", "SY289"]);
    }

    fn arb_command() -> impl Strategy<Value = Command> {
        prop_oneof![
            Just(Command::Read),
            Just(Command::Id),
            Just(Command::Version),
            Just(Command::UnitQuery),
            Just(Command::SetUnit(Unit::Mm)),
            Just(Command::SetUnit(Unit::Inch)),
            Just(Command::Settings),
            Just(Command::Battery),
            Just(Command::PresetQuery),
            Just(Command::HoldQuery),
            Just(Command::KeypadQuery),
            (-1_999_990i32..=1_999_990).prop_map(|v| Command::Preset(f64::from(v) / 10_000.0)),
            any::<bool>().prop_map(Command::PresetMode),
            any::<bool>().prop_map(Command::UnitChangeAllowed),
            any::<bool>().prop_map(Command::Hold),
            any::<bool>().prop_map(Command::Keypad),
            any::<bool>().prop_map(Command::ContinuousOutput),
            any::<bool>().prop_map(Command::NotifyOnChangeOnly),
        ]
    }

    proptest! {
        #[test]
        fn command_round_trip(cmd in arb_command()) {
            let bytes = cmd.encode();
            prop_assert_eq!(bytes.last(), Some(&CR));
            let mut d = LineDeframer::new();
            d.push(&bytes);
            let line = d.next_line().ok().flatten().unwrap_or_default();
            let back = Command::parse(&line);
            match (&cmd, &back) {
                (Command::Preset(a), Some(Command::Preset(b))) => prop_assert!((a - b).abs() < 5e-5),
                _ => prop_assert_eq!(back, Some(cmd)),
            }
        }

        #[test]
        fn parsers_never_panic(text in "\\PC{0,40}") {
            let _ = Command::parse(&text);
            let _ = Answer::parse(&text);
            let _ = parse_value(&text);
        }

        #[test]
        fn value_round_trip(v in -999.0f64..999.0, decimals in 0usize..6, int_digits in 1usize..4) {
            let text = format_value(v, int_digits, decimals);
            let back = parse_value(&text);
            prop_assert!(back.is_ok(), "{}", text);
            let back = back.unwrap_or(f64::NAN);
            prop_assert!((back - v).abs() <= 0.5 * 10f64.powi(-(decimals as i32)) + 1e-9, "{} {}", text, back);
        }
    }
}
