//! Bluetooth LE payload decoding (protocols.md §3.2), as pure functions.
//!
//! The BLE link itself (btleplug, BlueZ, D-Bus) is the `ble_link` module behind the off-by-default
//! `ble` feature; these decoders are the part of it that can be verified without an adapter:
//! the Measurement notification (int32 LE × 10^exponent metres), the exponent of the
//! Characteristic Presentation Format descriptor, the Parameters bitmap, and the reassembly
//! of RemoteResponse notifications (≤ 20 bytes each, CR-terminated ASCII).

/// SDS Measurement characteristic (notify): int32 LE.
pub const MEASUREMENT_UUID: &str = "00005020-0000-1000-8000-00805f9b34fb";
/// SDS Parameters characteristic (notify): uint16 LE bitmap.
pub const PARAMETERS_UUID: &str = "00005021-0000-1000-8000-00805f9b34fb";
/// Sylvac Metrology Service.
pub const SMS_SERVICE_UUID: &str = "c1b25000-caaf-6d0e-4c33-7dae30052840";
/// SMS DataSend (indicate): ASCII value + CR when the DATA button is pressed.
pub const DATA_SEND_UUID: &str = "c1b25010-caaf-6d0e-4c33-7dae30052840";
/// SMS RemoteRequest (write without response): ASCII command + CR.
pub const REMOTE_REQUEST_UUID: &str = "c1b25012-caaf-6d0e-4c33-7dae30052840";
/// SMS RemoteResponse (notify): ASCII answer, ≤ 20 bytes per notification, CR at the end.
pub const REMOTE_RESPONSE_UUID: &str = "c1b25013-caaf-6d0e-4c33-7dae30052840";
/// Battery level (read/notify): uint8 %.
pub const BATTERY_LEVEL_UUID: &str = "00002a19-0000-1000-8000-00805f9b34fb";
/// Characteristic Presentation Format descriptor (16-bit UUID 0x2904).
pub const PRESENTATION_FORMAT_DESCRIPTOR: u16 = 0x2904;

use vatcal_hardware_traits::transport::{Framing, LineDeframer};

/// Exponent assumed when the presentation-format descriptor is absent (nanometres).
pub const DEFAULT_EXPONENT: i8 = -9;
/// Raw measurement meaning "no value" (what a plain read returns).
pub const NO_VALUE: i32 = 0x7FFF_FFFF;
/// Largest RemoteResponse notification.
pub const MAX_NOTIFICATION_LEN: usize = 20;

/// A payload that cannot be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BleDecodeError {
    /// Wrong payload length.
    #[error("expected {expected} bytes, got {got}")]
    Length {
        /// expected length
        expected: usize,
        /// actual length
        got: usize,
    },
    /// A response longer than the limit without CR.
    #[error("response longer than {0} bytes without CR")]
    ResponseTooLong(usize),
}

/// The exponent (byte index 1, signed) of a Characteristic Presentation Format descriptor
/// value; [`DEFAULT_EXPONENT`] if the descriptor is too short.
pub fn presentation_format_exponent(descriptor: &[u8]) -> i8 {
    descriptor.get(1).map(|&b| b as i8).unwrap_or(DEFAULT_EXPONENT)
}

/// Decodes a Measurement notification: `Some(value in SI units — metres, or radians for
/// angular instruments)`, `None` for the "no value" sentinel.
pub fn decode_measurement(payload: &[u8], exponent: i8) -> Result<Option<f64>, BleDecodeError> {
    let bytes: [u8; 4] =
        payload.try_into().map_err(|_| BleDecodeError::Length { expected: 4, got: payload.len() })?;
    let raw = i32::from_le_bytes(bytes);
    if raw == NO_VALUE {
        return Ok(None);
    }
    Ok(Some(f64::from(raw) * 10f64.powi(i32::from(exponent))))
}

/// [`decode_measurement`] in mm (for linear instruments).
pub fn decode_measurement_mm(payload: &[u8], exponent: i8) -> Result<Option<f64>, BleDecodeError> {
    Ok(decode_measurement(payload, exponent)?.map(|m| m * 1000.0))
}

/// Display unit in the Parameters bitmap (bits 15–12).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BleUnit {
    /// 0
    Unknown,
    /// 1
    Mm,
    /// 2
    Inch,
    /// 4
    Radian,
    /// 5
    Degree,
    /// 6
    DegreeMinute,
    /// any other value
    Other(u8),
}

/// Measuring mode in the Parameters bitmap (bits 1–0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// 0
    Normal,
    /// 1
    Min,
    /// 2
    Max,
    /// 3
    Delta,
}

/// The decoded Parameters bitmap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Parameters {
    /// display unit
    pub unit: BleUnit,
    /// display resolution \[m\], `None` if unspecified
    pub resolution_m: Option<f64>,
    /// measuring mode
    pub mode: Mode,
}

/// Decodes a Parameters notification (uint16 little-endian).
pub fn decode_parameters(payload: &[u8]) -> Result<Parameters, BleDecodeError> {
    let bytes: [u8; 2] =
        payload.try_into().map_err(|_| BleDecodeError::Length { expected: 2, got: payload.len() })?;
    let bits = u16::from_le_bytes(bytes);
    let unit = match ((bits >> 12) & 0xf) as u8 {
        0 => BleUnit::Unknown,
        1 => BleUnit::Mm,
        2 => BleUnit::Inch,
        4 => BleUnit::Radian,
        5 => BleUnit::Degree,
        6 => BleUnit::DegreeMinute,
        other => BleUnit::Other(other),
    };
    let resolution_m = match (bits >> 8) & 0xf {
        code @ 1..=5 => Some(10f64.powi(-3 - i32::from(code))),
        _ => None,
    };
    let mode = match bits & 0b11 {
        0 => Mode::Normal,
        1 => Mode::Min,
        2 => Mode::Max,
        _ => Mode::Delta,
    };
    Ok(Parameters { unit, resolution_m, mode })
}

/// Reassembles RemoteResponse notifications into CR-terminated answers (the shared
/// [`LineDeframer`] on CR, empty answers
/// kept).
#[derive(Debug, Clone)]
pub struct ResponseReassembler {
    deframer: LineDeframer,
}

impl Default for ResponseReassembler {
    fn default() -> Self {
        Self::new()
    }
}

impl ResponseReassembler {
    /// Longest answer accepted before [`BleDecodeError::ResponseTooLong`].
    pub const MAX_RESPONSE: usize = 256;

    /// An empty reassembler.
    pub fn new() -> Self {
        let framing =
            Framing { terminators: b"\r", strip_cr: false, skip_blank: false, max_len: Self::MAX_RESPONSE };
        Self { deframer: LineDeframer::new(framing) }
    }

    /// Adds one notification; returns every answer it completed (CR removed). An answer
    /// longer than [`Self::MAX_RESPONSE`] fails with [`BleDecodeError::ResponseTooLong`] and is
    /// dropped up to its CR.
    pub fn push(&mut self, notification: &[u8]) -> Result<Vec<String>, BleDecodeError> {
        self.deframer.push(notification);
        let mut done = Vec::new();
        while let Some(line) =
            self.deframer.next_line().map_err(|_| BleDecodeError::ResponseTooLong(Self::MAX_RESPONSE))?
        {
            done.push(line);
        }
        Ok(done)
    }

    /// Drops a partial answer (e.g. before a new request after a timeout).
    pub fn clear(&mut self) {
        self.deframer.clear();
    }
}

/// Splits an ASCII message into notifications of at most [`MAX_NOTIFICATION_LEN`] bytes (what
/// the gauge does; used to test the reassembler).
pub fn split_into_notifications(message: &[u8]) -> Vec<Vec<u8>> {
    message.chunks(MAX_NOTIFICATION_LEN).map(<[u8]>::to_vec).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn measurement_fixture_of_the_reference() {
        // raw 0x00BC614E (12 345 678) with e = -9 → 12.345678 mm
        let payload = [0x4E, 0x61, 0xBC, 0x00];
        let mm = decode_measurement_mm(&payload, DEFAULT_EXPONENT).ok().flatten().unwrap_or(f64::NAN);
        assert!((mm - 12.345678).abs() < 1e-12, "{mm}");
        // negative values, other exponents
        let neg = (-1_234_567i32).to_le_bytes();
        let m = decode_measurement(&neg, -7).ok().flatten().unwrap_or(f64::NAN);
        assert!((m + 0.1234567).abs() < 1e-15);
        assert_eq!(decode_measurement(&NO_VALUE.to_le_bytes(), -9), Ok(None));
        assert_eq!(decode_measurement(&[1, 2, 3], -9), Err(BleDecodeError::Length { expected: 4, got: 3 }));
    }

    #[test]
    fn presentation_format_descriptor() {
        // format 0x10 (sint32), exponent -9 (0xF7), unit 0x2701 (metre) LE, namespace, description
        assert_eq!(presentation_format_exponent(&[0x10, 0xF7, 0x01, 0x27, 0x01, 0x00, 0x00]), -9);
        assert_eq!(presentation_format_exponent(&[0x10, 0xF9]), -7);
        assert_eq!(presentation_format_exponent(&[]), DEFAULT_EXPONENT);
    }

    #[test]
    fn parameters_fixture_of_the_reference() {
        // 0x1300 = mm, 1 um resolution, normal
        let p = decode_parameters(&0x1300u16.to_le_bytes()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(p.unit, BleUnit::Mm);
        assert_eq!(p.mode, Mode::Normal);
        assert!((p.resolution_m.unwrap_or(0.0) - 1e-6).abs() < 1e-18);
        let p = decode_parameters(&0x2403u16.to_le_bytes()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((p.unit, p.mode), (BleUnit::Inch, Mode::Delta));
        assert!((p.resolution_m.unwrap_or(0.0) - 1e-7).abs() < 1e-19);
        let p = decode_parameters(&0x0001u16.to_le_bytes()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((p.unit, p.resolution_m, p.mode), (BleUnit::Unknown, None, Mode::Min));
        assert!(decode_parameters(&[0x00]).is_err());
    }

    #[test]
    fn reassembles_chunked_responses() {
        let mut r = ResponseReassembler::new();
        assert_eq!(r.push(b"MM STO0 KEY1 BAT1 EC"), Ok(vec![]));
        assert_eq!(
            r.push(b"O0\r+001.2345\r"),
            Ok(vec!["MM STO0 KEY1 BAT1 ECO0".to_owned(), "+001.2345".to_owned()])
        );
        assert!(r.push(&[b'x'; 300]).is_err());
    }

    proptest! {
        #[test]
        fn measurement_round_trip(raw in any::<i32>(), exponent in -12i8..=0) {
            prop_assume!(raw != NO_VALUE);
            let v = decode_measurement(&raw.to_le_bytes(), exponent);
            let expected = f64::from(raw) * 10f64.powi(i32::from(exponent));
            prop_assert_eq!(v, Ok(Some(expected)));
        }

        #[test]
        fn reassembly_is_independent_of_chunking(answers in proptest::collection::vec("[ -~]{0,40}", 1..5)) {
            let stream: Vec<u8> = answers.iter().flat_map(|a| a.bytes().chain(std::iter::once(b'\r'))).collect();
            let mut r = ResponseReassembler::new();
            let mut got = Vec::new();
            for chunk in split_into_notifications(&stream) {
                prop_assert!(chunk.len() <= MAX_NOTIFICATION_LEN);
                got.extend(r.push(&chunk).unwrap_or_default());
            }
            prop_assert_eq!(got, answers);
        }
    }
}
