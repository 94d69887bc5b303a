//! A thermometer: the cell's temperature, recorded as `temperature_c` beside each measurement
//! so that a temperature-driven thermal drift of the arm can be modelled and discovered.

use crate::error::{Error, ErrorKind, Result};

/// Reads the cell's (air or structure) temperature in **°C**.
///
/// # Implementation
/// * `read_c` returns a fresh reading or fails after the driver's I/O timeout
///   ([`ErrorKind::Timeout`]); a reading that is not a finite temperature is
///   [`ErrorKind::Protocol`], a sensor reporting a value outside its range
///   [`ErrorKind::OutOfRange`] — never a made-up or clamped value.
/// * A reading must not move anything and should take little time (the campaign reads it once
///   per measurement).
pub trait Thermometer: Send {
    /// Current temperature \[°C\].
    fn read_c(&mut self) -> Result<f64>;
}

impl<T: Thermometer + ?Sized> Thermometer for &mut T {
    fn read_c(&mut self) -> Result<f64> {
        (**self).read_c()
    }
}

impl<T: Thermometer + ?Sized> Thermometer for Box<T> {
    fn read_c(&mut self) -> Result<f64> {
        (**self).read_c()
    }
}

/// Plausible range of a cell temperature [°C]: readings outside it are sensor faults.
pub const PLAUSIBLE_TEMPERATURE_C: (f64, f64) = (-40.0, 100.0);

/// Parses one temperature text (e.g. the first line of a sensor file, or `23.41`, `23.41 C`,
/// `23.41 °C`, `23.41degC`) into °C, checking it is finite and within
/// [`PLAUSIBLE_TEMPERATURE_C`]. `device` names the sensor in the error.
///
/// # Errors
/// [`ErrorKind::Protocol`] for text that is not a number (with an optional `C`/`°C`/`degC`
/// suffix); [`ErrorKind::OutOfRange`] for a value outside the plausible range.
pub fn parse_temperature_c(device: &str, text: &str) -> Result<f64> {
    let t = text.trim();
    let number = ["°C", "degC", "C", "c"].iter().find_map(|s| t.strip_suffix(s)).unwrap_or(t).trim();
    let value: f64 = number
        .parse()
        .map_err(|_| Error::new(ErrorKind::Protocol, device, format!("`{t}` is not a temperature in °C")))?;
    let (lo, hi) = PLAUSIBLE_TEMPERATURE_C;
    if !value.is_finite() || !(lo..=hi).contains(&value) {
        return Err(Error::new(
            ErrorKind::OutOfRange,
            device,
            format!("{value} °C is outside the plausible range {lo}..{hi} °C"),
        ));
    }
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Fixed(f64);
    impl Thermometer for Fixed {
        fn read_c(&mut self) -> Result<f64> {
            Ok(self.0)
        }
    }

    #[test]
    fn boxed_and_borrowed_thermometers_forward() {
        let mut t = Fixed(21.5);
        let mut borrowed: &mut dyn Thermometer = &mut t;
        assert_eq!(Thermometer::read_c(&mut borrowed).expect("read"), 21.5);
        let mut b: Box<dyn Thermometer> = Box::new(Fixed(19.0));
        assert_eq!(b.read_c().expect("read"), 19.0);
    }

    #[test]
    fn temperature_text_is_parsed_or_rejected_clearly() {
        for (text, v) in [("23.41", 23.41), (" 23.41 C\n", 23.41), ("23.4°C", 23.4), ("-1.5degC", -1.5)] {
            assert_eq!(parse_temperature_c("t", text).expect(text), v);
        }
        let e = parse_temperature_c("room sensor", "warm").expect_err("not a number");
        assert_eq!(e.kind(), ErrorKind::Protocol);
        assert!(e.to_string().contains("room sensor") && e.to_string().contains("warm"), "{e}");
        for text in ["150", "NaN", "inf", "-273"] {
            let e = parse_temperature_c("t", text).expect_err(text);
            assert!(matches!(e.kind(), ErrorKind::OutOfRange | ErrorKind::Protocol), "{text}: {e}");
        }
        assert_eq!(parse_temperature_c("t", "150").expect_err("hot").kind(), ErrorKind::OutOfRange);
    }
}
