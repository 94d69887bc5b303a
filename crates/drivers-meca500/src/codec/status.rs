//! The status word `[2007]` ([`StatusWord`]).

use super::code;
use super::reply::{Reply, ReplyError};

/// The status word `[2007][as,hs,sm,es,pm,eob,eom]` (§1.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct StatusWord {
    /// motors activated
    pub activated: bool,
    /// homing done
    pub homed: bool,
    /// simulation mode
    pub simulation: bool,
    /// in error mode
    pub error: bool,
    /// motion paused (also after `ClearMotion` and while in error)
    pub paused: bool,
    /// end of block: not moving and queue empty
    pub end_of_block: bool,
    /// end of movement: not moving
    pub end_of_movement: bool,
}

impl StatusWord {
    /// The seven flags in wire order.
    pub fn to_flags(&self) -> [bool; 7] {
        [
            self.activated,
            self.homed,
            self.simulation,
            self.error,
            self.paused,
            self.end_of_block,
            self.end_of_movement,
        ]
    }

    /// From the seven flags in wire order.
    pub fn from_flags(f: [bool; 7]) -> Self {
        Self {
            activated: f[0],
            homed: f[1],
            simulation: f[2],
            error: f[3],
            paused: f[4],
            end_of_block: f[5],
            end_of_movement: f[6],
        }
    }

    /// The `[2007]` reply carrying this status.
    pub fn to_reply(&self) -> Reply {
        let p = self.to_flags().iter().map(|&b| if b { "1" } else { "0" }).collect::<Vec<_>>().join(",");
        Reply::new(code::STATUS, p)
    }

    /// Parses the payload of a `[2007]` reply (at least seven 0/1 integers; extra fields of
    /// other firmware versions are ignored).
    pub fn from_reply(reply: &Reply) -> Result<Self, ReplyError> {
        let bad = |reason: String| ReplyError::BadPayload {
            code: reply.code,
            payload: reply.payload.clone(),
            reason,
        };
        if reply.code != code::STATUS {
            return Err(bad(format!("expected code {}, got {}", code::STATUS, reply.code)));
        }
        let fields: Vec<&str> = reply.payload.split(',').map(str::trim).collect();
        if fields.len() < 7 {
            return Err(bad(format!("expected 7 fields, got {}", fields.len())));
        }
        let mut flags = [false; 7];
        for (slot, f) in flags.iter_mut().zip(&fields) {
            *slot = match *f {
                "0" => false,
                "1" => true,
                other => return Err(bad(format!("'{other}' is not 0 or 1"))),
            };
        }
        Ok(Self::from_flags(flags))
    }
}
