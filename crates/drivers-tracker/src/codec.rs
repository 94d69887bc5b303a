//! The tracker line protocol (sans-IO): requests and replies as text lines, and the `x y z`
//! reading format shared by every tracker kind.
//!
//! ASCII lines ended by LF (a CR before it is ignored), at most [`MAX_LINE`] bytes. Every
//! request starts with a request id (1..=9999) that its reply repeats, so a reply that
//! arrives after its request timed out is recognised and skipped:
//!
//! | request | reply |
//! |---|---|
//! | `<id> ID?` | `<id> OK <identity text>` |
//! | `<id> MEASURE <target>` | `<id> OK <x> <y> <z>` (mm, the tracker's frame) |
//! | anything | `<id> ERR <CODE> <message>` with CODE `LOS` (line of sight lost: the SMR cannot be seen now), `TARGET` (unknown target), `REQUEST` (malformed or unknown request), `DEVICE` (any other fault of the tracker) |
//!
//! `target` is a TCP id (the SMR in the nest that stands for it) or 0
//! ([`PROBE_NEST_TARGET`](vatcal_hardware_traits::PROBE_NEST_TARGET): the SMR in the probe's
//! trihedral nest). A request without a readable id is answered with id 0.

use nalgebra::Vector3;
use vatcal_hardware_traits::transport::Framing;

/// Longest line, terminator excluded.
pub const MAX_LINE: usize = 256;
/// Largest request id (ids cycle 1..=MAX_ID).
pub const MAX_ID: u16 = 9999;
/// Largest plausible coordinate of a reading \[mm\] (100 m: beyond any tracker's range).
pub const MAX_COORDINATE_MM: f64 = 1.0e5;

/// LF-terminated lines (CR before LF removed), blank lines skipped, [`MAX_LINE`] bytes.
pub const FRAMING: Framing =
    Framing { terminators: b"\n", strip_cr: true, skip_blank: true, max_len: MAX_LINE };

/// What a client asks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// `ID?`: who are you
    Identify,
    /// `MEASURE <target>`
    Measure {
        /// TCP id, or 0 for the SMR in the probe's nest
        target: u32,
    },
}

impl Request {
    /// The request line with id `id`, LF included.
    pub fn encode(&self, id: u16) -> Vec<u8> {
        match self {
            Request::Identify => format!("{id} ID?\n").into_bytes(),
            Request::Measure { target } => format!("{id} MEASURE {target}\n").into_bytes(),
        }
    }

    /// Parses a request line (terminator removed) into `(id, request)`.
    ///
    /// # Errors
    /// `(id, reason)`: the id (0 when unreadable) and why the line is not a request.
    pub fn parse(line: &str) -> Result<(u16, Request), (u16, String)> {
        let mut words = line.split_whitespace();
        let id = match words.next().map(str::parse::<u16>) {
            Some(Ok(id)) if (1..=MAX_ID).contains(&id) => id,
            _ => return Err((0, format!("`{}` does not start with a request id 1..={MAX_ID}", clip(line)))),
        };
        let verb = words.next().unwrap_or("");
        let request = if verb.eq_ignore_ascii_case("ID?") {
            Request::Identify
        } else if verb.eq_ignore_ascii_case("MEASURE") {
            match words.next().map(str::parse::<u32>) {
                Some(Ok(target)) => Request::Measure { target },
                _ => return Err((id, "MEASURE needs a target number".into())),
            }
        } else {
            return Err((id, format!("unknown request `{}`", clip(verb))));
        };
        if words.next().is_some() {
            return Err((id, "extra words after the request".into()));
        }
        Ok((id, request))
    }
}

/// Why the tracker refused a request (`ERR <CODE> …`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorCode {
    /// `LOS`: the SMR cannot be seen now (beam broken, SMR turned away)
    LineOfSight,
    /// `TARGET`: the tracker knows no such target
    UnknownTarget,
    /// `REQUEST`: malformed or unknown request
    BadRequest,
    /// `DEVICE`: any other fault of the tracker
    Device,
}

impl ErrorCode {
    /// The code word on the wire.
    pub fn as_str(self) -> &'static str {
        match self {
            ErrorCode::LineOfSight => "LOS",
            ErrorCode::UnknownTarget => "TARGET",
            ErrorCode::BadRequest => "REQUEST",
            ErrorCode::Device => "DEVICE",
        }
    }

    fn parse(word: &str) -> Option<Self> {
        [ErrorCode::LineOfSight, ErrorCode::UnknownTarget, ErrorCode::BadRequest, ErrorCode::Device]
            .into_iter()
            .find(|c| c.as_str().eq_ignore_ascii_case(word))
    }
}

impl std::fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ErrorCode::LineOfSight => "line of sight lost",
            ErrorCode::UnknownTarget => "unknown target",
            ErrorCode::BadRequest => "bad request",
            ErrorCode::Device => "tracker fault",
        })
    }
}

/// A reply line.
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// `<id> OK <text>`
    Ok {
        /// the request's id
        id: u16,
        /// the rest of the line (identity, or `x y z`)
        text: String,
    },
    /// `<id> ERR <CODE> <message>`
    Err {
        /// the request's id (0: the request's id was unreadable)
        id: u16,
        /// why
        code: ErrorCode,
        /// the tracker's words
        message: String,
    },
}

impl Reply {
    /// The reply line, LF included (newlines in the text become spaces).
    pub fn encode(&self) -> Vec<u8> {
        let one_line = |s: &str| s.replace(['\r', '\n'], " ");
        match self {
            Reply::Ok { id, text } => format!("{id} OK {}\n", one_line(text)).into_bytes(),
            Reply::Err { id, code, message } => {
                format!("{id} ERR {} {}\n", code.as_str(), one_line(message)).into_bytes()
            }
        }
    }

    /// The id the reply answers.
    pub fn id(&self) -> u16 {
        match self {
            Reply::Ok { id, .. } | Reply::Err { id, .. } => *id,
        }
    }

    /// Parses a reply line (terminator removed).
    ///
    /// # Errors
    /// Why the line is not a reply (no id, no `OK`/`ERR`, unknown error code).
    pub fn parse(line: &str) -> Result<Reply, String> {
        let line = line.trim();
        let (id, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
        let id: u16 = match id.parse() {
            Ok(id) if id <= MAX_ID => id,
            _ => return Err("it does not start with a request id".into()),
        };
        let rest = rest.trim_start();
        let (status, rest) = rest.split_once(char::is_whitespace).unwrap_or((rest, ""));
        if status == "OK" {
            return Ok(Reply::Ok { id, text: rest.trim().to_owned() });
        }
        if status != "ERR" {
            return Err(format!("`{}` is neither OK nor ERR", clip(status)));
        }
        let rest = rest.trim_start();
        let (code, message) = rest.split_once(char::is_whitespace).unwrap_or((rest, ""));
        let code = ErrorCode::parse(code).ok_or_else(|| format!("unknown error code `{}`", clip(code)))?;
        Ok(Reply::Err { id, code, message: message.trim().to_owned() })
    }
}

/// A reading as text: `x y z` in mm with 6 decimals (1 nm), the format every tracker kind
/// answers in.
pub fn format_xyz_mm(p: &Vector3<f64>) -> String {
    format!("{:.6} {:.6} {:.6}", p.x, p.y, p.z)
}

/// Parses a reading `x y z` \[mm\]: three numbers separated by spaces, tabs, commas or
/// semicolons (a pasted spreadsheet row works), optionally followed by `mm`.
///
/// # Errors
/// Why the text is not a reading: not three numbers, a word that is not a number, a value that
/// is not finite or beyond ±[`MAX_COORDINATE_MM`].
pub fn parse_xyz_mm(text: &str) -> Result<Vector3<f64>, String> {
    let t = text.trim();
    let t = t.strip_suffix("mm").or_else(|| t.strip_suffix("MM")).unwrap_or(t);
    let words: Vec<&str> =
        t.split(|c: char| c.is_whitespace() || c == ',' || c == ';').filter(|w| !w.is_empty()).collect();
    if words.len() != 3 {
        return Err(format!("`{}` is not `x y z` (mm): {} values", clip(text.trim()), words.len()));
    }
    let mut v = [0.0; 3];
    for (slot, (word, axis)) in v.iter_mut().zip(words.iter().zip(["x", "y", "z"])) {
        let value: f64 = word.parse().map_err(|_| format!("{axis} = `{}` is not a number", clip(word)))?;
        if !value.is_finite() || value.abs() > MAX_COORDINATE_MM {
            return Err(format!(
                "{axis} = {value} mm is not a finite coordinate within ±{MAX_COORDINATE_MM} mm"
            ));
        }
        *slot = value;
    }
    Ok(Vector3::from(v))
}

/// At most 60 characters of `s` for a message.
pub(crate) fn clip(s: &str) -> String {
    let mut out: String = s.chars().take(60).collect();
    if s.chars().nth(60).is_some() {
        out.push('…');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transcript() {
        assert_eq!(Request::Measure { target: 2 }.encode(17), b"17 MEASURE 2\n");
        assert_eq!(Request::parse("17 measure 2"), Ok((17, Request::Measure { target: 2 })));
        assert_eq!(Request::parse("3 ID?"), Ok((3, Request::Identify)));
        assert_eq!(Request::parse("MEASURE 2").map_err(|e| e.0), Err(0));
        assert_eq!(Request::parse("4 MEASURE x").map_err(|e| e.0), Err(4));
        assert_eq!(
            Reply::parse("17 OK 812.5 -40.25 300"),
            Ok(Reply::Ok { id: 17, text: "812.5 -40.25 300".into() })
        );
        assert_eq!(
            Reply::parse("17 ERR LOS SMR 2 not visible"),
            Ok(Reply::Err { id: 17, code: ErrorCode::LineOfSight, message: "SMR 2 not visible".into() })
        );
        assert!(Reply::parse("17 ERR WHAT x").is_err());
        assert!(Reply::parse("OK 1 2 3").is_err());
        assert_eq!(parse_xyz_mm(" 1.5, -2;3e1 mm "), Ok(Vector3::new(1.5, -2.0, 30.0)));
        assert!(parse_xyz_mm("1 2").expect_err("two").contains("2 values"));
        assert!(parse_xyz_mm("1 two 3").expect_err("word").contains("y = `two`"));
        assert!(parse_xyz_mm("1 2 NaN").is_err() && parse_xyz_mm("1 2 1e9").is_err());
    }
}
