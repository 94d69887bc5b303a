//! [`Reply`]: one message from the robot, `[CCCC][payload]`, parsed and written.

use std::fmt;

use super::code;
use super::{NUL, Six};

/// One message from the robot: `[CCCC][payload]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    /// the 4-digit code
    pub code: u16,
    /// the text between the second `[` and the last `]` (may be empty)
    pub payload: String,
}

/// What a frame from the robot could not be parsed as.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// Not 7-bit ASCII text.
    #[error("reply is not ASCII text")]
    NotAscii,
    /// No `[code]` at the start.
    #[error("reply '{0}' has no [code]")]
    MissingCode(String),
    /// The code is not a number.
    #[error("reply '{0}' has a non-numeric code")]
    BadCode(String),
    /// The payload is not enclosed in `[...]`.
    #[error("reply '{0}' has no [payload]")]
    MissingPayload(String),
    /// A JSON message (only after `EnableJsonMode`, which this driver never sends).
    #[error("JSON message received; this driver speaks the text protocol only")]
    Json,
    /// A payload value is not a number, or there are too few of them.
    #[error("reply [{code}] payload '{payload}': {reason}")]
    BadPayload {
        /// reply code
        code: u16,
        /// raw payload
        payload: String,
        /// what is wrong
        reason: String,
    },
}

impl Reply {
    /// A reply with this code and payload.
    pub fn new(code: u16, payload: impl Into<String>) -> Self {
        Self { code, payload: payload.into() }
    }

    /// Parses a frame (without its NUL) the way mecademicpy does: code between the first `[`
    /// and the next `]`, payload from the next `[` to the **last** `]`.
    pub fn parse(frame: &[u8]) -> Result<Self, ReplyError> {
        if !frame.is_ascii() {
            return Err(ReplyError::NotAscii);
        }
        let text = String::from_utf8_lossy(frame);
        let text = text.trim_matches(|c: char| c.is_ascii_whitespace());
        if text.starts_with('{') {
            return Err(ReplyError::Json);
        }
        let missing_code = || ReplyError::MissingCode(text.to_owned());
        let rest = text.strip_prefix('[').ok_or_else(missing_code)?;
        let close = rest.find(']').ok_or_else(missing_code)?;
        let code_text = &rest[..close];
        let code = code_text.trim().parse::<u16>().map_err(|_| ReplyError::BadCode(text.to_owned()))?;
        let after = &rest[close + 1..];
        let open = after.find('[').ok_or_else(|| ReplyError::MissingPayload(text.to_owned()))?;
        let last = after
            .rfind(']')
            .filter(|&l| l > open)
            .ok_or_else(|| ReplyError::MissingPayload(text.to_owned()))?;
        Ok(Self { code, payload: after[open + 1..last].to_owned() })
    }

    /// The reply text without terminator, e.g. `[2007][1,1,0,0,0,1,1]`.
    pub fn to_text(&self) -> String {
        format!("[{:04}][{}]", self.code, self.payload)
    }

    /// Wire bytes: the text followed by one NUL.
    pub fn encode(&self) -> Vec<u8> {
        let mut bytes = self.to_text().into_bytes();
        bytes.push(NUL);
        bytes
    }

    /// The payload as comma-separated numbers.
    pub fn values(&self) -> Result<Vec<f64>, ReplyError> {
        if self.payload.trim().is_empty() {
            return Ok(Vec::new());
        }
        self.payload
            .split(',')
            .map(|s| {
                s.trim().parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| ReplyError::BadPayload {
                    code: self.code,
                    payload: self.payload.clone(),
                    reason: format!("'{}' is not a number", s.trim()),
                })
            })
            .collect()
    }

    /// The last six payload values (joints or pose; a leading time stamp is skipped).
    pub fn last_six(&self) -> Result<Six, ReplyError> {
        let v = self.values()?;
        if v.len() < 6 {
            return Err(ReplyError::BadPayload {
                code: self.code,
                payload: self.payload.clone(),
                reason: format!("expected at least 6 values, got {}", v.len()),
            });
        }
        let mut six = [0.0; 6];
        six.copy_from_slice(&v[v.len() - 6..]);
        Ok(six)
    }

    /// True when this message reports an error: a refused command (1000–1999) or an error
    /// event (motion/drive/internal/torque errors, a raised E-Stop or P-Stop).
    pub fn is_error(&self) -> bool {
        match self.code {
            1000..=1999 => true,
            code::COMMAND_TOO_LONG
            | code::MOTION_ERROR
            | code::DRIVE_COMM
            | code::INIT_FAILED
            | code::MAINTENANCE
            | code::INTERNAL
            | code::TORQUE_LIMIT => true,
            code::ESTOP | code::PSTOP1 | code::PSTOP2 | 3080..=3087 => self.payload.trim() != "0",
            _ => false,
        }
    }
}

impl fmt::Display for Reply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_text())
    }
}
