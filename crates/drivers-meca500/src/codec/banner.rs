//! The `[3000]` connection banner ([`Banner`]).

use super::code;
use super::reply::Reply;

/// Robot models mecademicpy accepts in the banner (§1.4).
pub const KNOWN_MODELS: &[&str] = &["Meca500", "MCS500", "MCA250", "MCA1000", "Unknown"];

/// What the `[3000]` connection banner says, e.g. `Connected to Meca500 R3 v9.3.0`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Banner {
    /// model word as sent (e.g. `Meca500`)
    pub model: String,
    /// hardware revision (`R3` → 3), if present
    pub revision: Option<u8>,
    /// a virtual robot (`-virtual`)
    pub virtual_robot: bool,
    /// `-safe-boot`
    pub safe_boot: bool,
    /// firmware `major.minor.patch`
    pub version: (u32, u32, u32),
}

/// Why a banner was not understood.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BannerError {
    /// The robot refused the connection (`[3001]` another user, `[3002]` firmware update,
    /// `[3053]` reboot pending, …).
    #[error("connection refused by the robot: {0}")]
    Refused(Reply),
    /// The first message was not a banner.
    #[error("expected a [3000] banner, got {0}")]
    NotABanner(Reply),
    /// The banner text could not be parsed.
    #[error("cannot parse banner '{0}'")]
    Unparsable(String),
    /// The model word is not a known Mecademic model.
    #[error("unknown robot model '{0}'")]
    UnknownModel(String),
}

impl Banner {
    /// The banner text, e.g. `Connected to Meca500 R3 v9.3.0`.
    pub fn to_text(&self) -> String {
        let (a, b, c) = self.version;
        let mut s = format!("Connected to {}", self.model);
        if let Some(r) = self.revision {
            s.push_str(&format!(" R{r}"));
        }
        if self.virtual_robot {
            s.push_str("-virtual");
        }
        if self.safe_boot {
            s.push_str("-safe-boot");
        }
        s.push_str(&format!(" v{a}.{b}.{c}"));
        s
    }

    /// The `[3000]` reply carrying this banner.
    pub fn to_reply(&self) -> Reply {
        Reply::new(code::CONNECTED, self.to_text())
    }

    /// Parses the first message of the control port (mecademicpy's rule, §1.4): model word,
    /// optional `R<digit>`, optional `-virtual`, optional `-safe-boot`, then ` v` or `_`,
    /// then `major.minor.patch`. Refusal codes give [`BannerError::Refused`].
    pub fn from_reply(reply: &Reply) -> Result<Self, BannerError> {
        match reply.code {
            code::CONNECTED => {}
            code::ANOTHER_USER | code::FIRMWARE_UPDATE | code::REBOOT_PENDING => {
                return Err(BannerError::Refused(reply.clone()));
            }
            _ => return Err(BannerError::NotABanner(reply.clone())),
        }
        let text = reply.payload.trim();
        let unparsable = || BannerError::Unparsable(text.to_owned());
        let body = text.strip_prefix("Connected to ").unwrap_or(text);
        // split off the version: " v1.2.3" or "_1.2.3"
        let (head, version_text) = match body.rfind(" v") {
            Some(i) => (&body[..i], &body[i + 2..]),
            None => body.rsplit_once('_').ok_or_else(unparsable)?,
        };
        let version = parse_version(version_text).ok_or_else(unparsable)?;
        let mut virtual_robot = false;
        let mut safe_boot = false;
        let mut head = head.trim().to_owned();
        for (suffix, flag) in [("-safe-boot", &mut safe_boot), ("-virtual", &mut virtual_robot)] {
            if let Some(stripped) = head.strip_suffix(suffix) {
                *flag = true;
                head = stripped.to_owned();
            }
        }
        let mut words = head.split_whitespace();
        let model = words.next().ok_or_else(unparsable)?.to_owned();
        let revision = match words.next() {
            None => None,
            Some(r) => Some(r.strip_prefix('R').and_then(|d| d.parse::<u8>().ok()).ok_or_else(unparsable)?),
        };
        if words.next().is_some() {
            return Err(unparsable());
        }
        if !KNOWN_MODELS.iter().any(|m| m.eq_ignore_ascii_case(&model)) {
            return Err(BannerError::UnknownModel(model));
        }
        Ok(Self { model, revision, virtual_robot, safe_boot, version })
    }
}

/// `9.3.0` (extra components such as `9.3.0.1234` are ignored) → (9, 3, 0).
fn parse_version(text: &str) -> Option<(u32, u32, u32)> {
    let digits: String = text.chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
    let mut parts = digits.split('.').map(|p| p.parse::<u32>().ok());
    Some((parts.next()??, parts.next()??, parts.next()??))
}
