//! Sans-IO codec of the Meca500 TCP text API (protocols.md §1.2–1.6).
//!
//! Pure functions only: [`Command`] ↔ text/bytes, bytes → [`Reply`], a [`Deframer`] that cuts
//! a TCP byte stream into NUL-terminated frames, the [`StatusWord`] of `[2007]` and the
//! connection [`Banner`]. Both the driver and the simulator use these types, so the two sides
//! cannot drift apart silently.

use std::fmt;

use vatcal_hardware_traits::transport::{Framing, LineDeframer};

/// Byte that ends every message in both directions.
pub const NUL: u8 = 0;

/// Longest frame (command or reply) the deframer accepts before reporting
/// [`FrameError::TooLong`] (the robot answers `[3003]` to overlong commands).
pub const MAX_FRAME_LEN: usize = 4096;

/// Number of decimals used when writing a floating-point argument (the manual allows up to 9).
pub const ARG_DECIMALS: usize = 9;

/// Six numbers: joint angles \[deg\] or a pose `x, y, z \[mm\], α, β, γ \[deg\]`.
pub type Six = [f64; 6];

/// Which optional real-time monitoring codes `SetRealTimeMonitoring` enables.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RealTimeCodes {
    /// `SetRealTimeMonitoring(all)`
    All,
    /// explicit list of 22xx codes
    Codes(Vec<u16>),
}

/// A text-API command (the subset a calibration campaign and the simulator need).
///
/// Kinds (§1.5): *requests* are answered at once; *queued* commands go into the motion queue
/// and are silent on success.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// A lone NUL: mecademicpy sends it after connecting; ignored, no reply.
    Empty,
    /// `ActivateRobot` → `[2000]`.
    ActivateRobot,
    /// `DeactivateRobot` → `[2004]`.
    DeactivateRobot,
    /// `Home` → `[2002]`.
    Home,
    /// `ResetError` → `[2005]` or `[2006]`.
    ResetError,
    /// `PauseMotion` → `[2042]`.
    PauseMotion,
    /// `ResumeMotion` → `[2043]`.
    ResumeMotion,
    /// `ClearMotion` → `[2044]` (leaves the robot paused).
    ClearMotion,
    /// `GetStatusRobot` → `[2007]`.
    GetStatusRobot,
    /// `GetJoints` → `[2026]` (legacy, degrees).
    GetJoints,
    /// `GetPose` → `[2027]` (legacy).
    GetPose,
    /// `GetRtTargetJointPos` → `[2200][t,θ1..θ6]`.
    GetRtTargetJointPos,
    /// `GetRtJointPos` → `[2210][t,θ1..θ6]` (measured).
    GetRtJointPos,
    /// `GetRtTargetCartPos` → `[2201][t,x,y,z,α,β,γ]`.
    GetRtTargetCartPos,
    /// `GetRtCartPos` → `[2211][t,…]` (measured).
    GetRtCartPos,
    /// `GetRobotSerial` → `[2083]`.
    GetRobotSerial,
    /// `GetFwVersion` → `[2081]`.
    GetFwVersion,
    /// `GetFwVersionFull` → `[2082]`.
    GetFwVersionFull,
    /// `GetProductType` → `[2084]`.
    GetProductType,
    /// `GetTrf` → `[2014]`.
    GetTrf,
    /// `GetWrf` → `[2013]`.
    GetWrf,
    /// `GetMonitoringInterval` → `[2116]`.
    GetMonitoringInterval,
    /// `GetRealTimeMonitoring` → `[2117]`.
    GetRealTimeMonitoring,
    /// `SetJointVel(p)`, % of the rated joint speeds (queued).
    SetJointVel(f64),
    /// `SetJointAcc(p)`, % (queued).
    SetJointAcc(f64),
    /// `SetCartLinVel(v)`, mm/s (queued).
    SetCartLinVel(f64),
    /// `SetCartAngVel(w)`, °/s (queued).
    SetCartAngVel(f64),
    /// `SetCartAcc(p)`, % (queued).
    SetCartAcc(f64),
    /// `SetBlending(p)`, % (queued).
    SetBlending(f64),
    /// `SetJointVelLimit(p)`, % (queued).
    SetJointVelLimit(f64),
    /// `MoveJoints(θ1..θ6)` \[deg\] (queued).
    MoveJoints(Six),
    /// `MoveJointsRel(Δθ1..Δθ6)` \[deg\] (queued).
    MoveJointsRel(Six),
    /// `MovePose(x,y,z,α,β,γ)` (queued).
    MovePose(Six),
    /// `MoveLin(x,y,z,α,β,γ)` (queued).
    MoveLin(Six),
    /// `MoveLinRelTrf(x,y,z,α,β,γ)`: displacement in the current tool frame (queued).
    MoveLinRelTrf(Six),
    /// `MoveLinRelWrf(x,y,z,α,β,γ)`: displacement along the world axes (queued).
    MoveLinRelWrf(Six),
    /// `SetTrf(…)` (queued).
    SetTrf(Six),
    /// `SetWrf(…)` (queued).
    SetWrf(Six),
    /// `Delay(t)` seconds (queued).
    Delay(f64),
    /// `SetCheckpoint(n)` → `[3030][n]` once the queue reaches it (queued).
    SetCheckpoint(u32),
    /// `SetEob(e)` → `[2054]`/`[2055]`.
    SetEob(bool),
    /// `SetEom(e)` → `[2052]`/`[2053]`.
    SetEom(bool),
    /// `SyncCmdQueue(n)` → `[2097][n]`.
    SyncCmdQueue(u32),
    /// `SetCtrlPortMonitoring(e)`.
    SetCtrlPortMonitoring(bool),
    /// `SetMonitoringInterval(t)` seconds.
    SetMonitoringInterval(f64),
    /// `SetRealTimeMonitoring(…)` → `[2117]`.
    SetRealTimeMonitoring(RealTimeCodes),
    /// `SetRtc(t)` UNIX seconds, no reply.
    SetRtc(u64),
}

/// Argument shape of a command name, used by both encoding and parsing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Shape {
    None,
    Float,
    SixFloats,
    Uint,
    Bool,
    Codes,
}

/// (canonical name, shape) for every command except `Empty`.
const TABLE: &[(&str, Shape)] = &[
    ("ActivateRobot", Shape::None),
    ("DeactivateRobot", Shape::None),
    ("Home", Shape::None),
    ("ResetError", Shape::None),
    ("PauseMotion", Shape::None),
    ("ResumeMotion", Shape::None),
    ("ClearMotion", Shape::None),
    ("GetStatusRobot", Shape::None),
    ("GetJoints", Shape::None),
    ("GetPose", Shape::None),
    ("GetRtTargetJointPos", Shape::None),
    ("GetRtJointPos", Shape::None),
    ("GetRtTargetCartPos", Shape::None),
    ("GetRtCartPos", Shape::None),
    ("GetRobotSerial", Shape::None),
    ("GetFwVersion", Shape::None),
    ("GetFwVersionFull", Shape::None),
    ("GetProductType", Shape::None),
    ("GetTrf", Shape::None),
    ("GetWrf", Shape::None),
    ("GetMonitoringInterval", Shape::None),
    ("GetRealTimeMonitoring", Shape::None),
    ("SetJointVel", Shape::Float),
    ("SetJointAcc", Shape::Float),
    ("SetCartLinVel", Shape::Float),
    ("SetCartAngVel", Shape::Float),
    ("SetCartAcc", Shape::Float),
    ("SetBlending", Shape::Float),
    ("SetJointVelLimit", Shape::Float),
    ("MoveJoints", Shape::SixFloats),
    ("MoveJointsRel", Shape::SixFloats),
    ("MovePose", Shape::SixFloats),
    ("MoveLin", Shape::SixFloats),
    ("MoveLinRelTrf", Shape::SixFloats),
    ("MoveLinRelWrf", Shape::SixFloats),
    ("SetTrf", Shape::SixFloats),
    ("SetWrf", Shape::SixFloats),
    ("Delay", Shape::Float),
    ("SetCheckpoint", Shape::Uint),
    ("SetEob", Shape::Bool),
    ("SetEom", Shape::Bool),
    ("SyncCmdQueue", Shape::Uint),
    ("SetCtrlPortMonitoring", Shape::Bool),
    ("SetMonitoringInterval", Shape::Float),
    ("SetRealTimeMonitoring", Shape::Codes),
    ("SetRtc", Shape::Uint),
];

impl Command {
    /// Canonical command name as written on the wire (`""` for [`Command::Empty`]).
    pub fn name(&self) -> &'static str {
        use Command as C;
        match self {
            C::Empty => "",
            C::ActivateRobot => "ActivateRobot",
            C::DeactivateRobot => "DeactivateRobot",
            C::Home => "Home",
            C::ResetError => "ResetError",
            C::PauseMotion => "PauseMotion",
            C::ResumeMotion => "ResumeMotion",
            C::ClearMotion => "ClearMotion",
            C::GetStatusRobot => "GetStatusRobot",
            C::GetJoints => "GetJoints",
            C::GetPose => "GetPose",
            C::GetRtTargetJointPos => "GetRtTargetJointPos",
            C::GetRtJointPos => "GetRtJointPos",
            C::GetRtTargetCartPos => "GetRtTargetCartPos",
            C::GetRtCartPos => "GetRtCartPos",
            C::GetRobotSerial => "GetRobotSerial",
            C::GetFwVersion => "GetFwVersion",
            C::GetFwVersionFull => "GetFwVersionFull",
            C::GetProductType => "GetProductType",
            C::GetTrf => "GetTrf",
            C::GetWrf => "GetWrf",
            C::GetMonitoringInterval => "GetMonitoringInterval",
            C::GetRealTimeMonitoring => "GetRealTimeMonitoring",
            C::SetJointVel(_) => "SetJointVel",
            C::SetJointAcc(_) => "SetJointAcc",
            C::SetCartLinVel(_) => "SetCartLinVel",
            C::SetCartAngVel(_) => "SetCartAngVel",
            C::SetCartAcc(_) => "SetCartAcc",
            C::SetBlending(_) => "SetBlending",
            C::SetJointVelLimit(_) => "SetJointVelLimit",
            C::MoveJoints(_) => "MoveJoints",
            C::MoveJointsRel(_) => "MoveJointsRel",
            C::MovePose(_) => "MovePose",
            C::MoveLin(_) => "MoveLin",
            C::MoveLinRelTrf(_) => "MoveLinRelTrf",
            C::MoveLinRelWrf(_) => "MoveLinRelWrf",
            C::SetTrf(_) => "SetTrf",
            C::SetWrf(_) => "SetWrf",
            C::Delay(_) => "Delay",
            C::SetCheckpoint(_) => "SetCheckpoint",
            C::SetEob(_) => "SetEob",
            C::SetEom(_) => "SetEom",
            C::SyncCmdQueue(_) => "SyncCmdQueue",
            C::SetCtrlPortMonitoring(_) => "SetCtrlPortMonitoring",
            C::SetMonitoringInterval(_) => "SetMonitoringInterval",
            C::SetRealTimeMonitoring(_) => "SetRealTimeMonitoring",
            C::SetRtc(_) => "SetRtc",
        }
    }

    /// True for commands that go into the motion queue (no reply on acceptance).
    pub fn is_queued(&self) -> bool {
        use Command as C;
        matches!(
            self,
            C::SetJointVel(_)
                | C::SetJointAcc(_)
                | C::SetCartLinVel(_)
                | C::SetCartAngVel(_)
                | C::SetCartAcc(_)
                | C::SetBlending(_)
                | C::SetJointVelLimit(_)
                | C::MoveJoints(_)
                | C::MoveJointsRel(_)
                | C::MovePose(_)
                | C::MoveLin(_)
                | C::MoveLinRelTrf(_)
                | C::MoveLinRelWrf(_)
                | C::SetTrf(_)
                | C::SetWrf(_)
                | C::Delay(_)
                | C::SetCheckpoint(_)
        )
    }

    /// True for queued commands that move the arm.
    pub fn is_motion(&self) -> bool {
        use Command as C;
        matches!(
            self,
            C::MoveJoints(_)
                | C::MoveJointsRel(_)
                | C::MovePose(_)
                | C::MoveLin(_)
                | C::MoveLinRelTrf(_)
                | C::MoveLinRelWrf(_)
        )
    }

    /// The command text without terminator, e.g. `MoveJoints(10,-20,30,0,45,0)`.
    pub fn to_text(&self) -> String {
        use Command as C;
        let args = match self {
            C::SetJointVel(v)
            | C::SetJointAcc(v)
            | C::SetCartLinVel(v)
            | C::SetCartAngVel(v)
            | C::SetCartAcc(v)
            | C::SetBlending(v)
            | C::SetJointVelLimit(v)
            | C::Delay(v)
            | C::SetMonitoringInterval(v) => Some(format_number(*v)),
            C::MoveJoints(s)
            | C::MoveJointsRel(s)
            | C::MovePose(s)
            | C::MoveLin(s)
            | C::MoveLinRelTrf(s)
            | C::MoveLinRelWrf(s)
            | C::SetTrf(s)
            | C::SetWrf(s) => Some(s.iter().map(|v| format_number(*v)).collect::<Vec<_>>().join(",")),
            C::SetCheckpoint(n) | C::SyncCmdQueue(n) => Some(n.to_string()),
            C::SetRtc(t) => Some(t.to_string()),
            C::SetEob(b) | C::SetEom(b) | C::SetCtrlPortMonitoring(b) => Some(u8::from(*b).to_string()),
            C::SetRealTimeMonitoring(RealTimeCodes::All) => Some("all".to_owned()),
            C::SetRealTimeMonitoring(RealTimeCodes::Codes(c)) => {
                Some(c.iter().map(u16::to_string).collect::<Vec<_>>().join(","))
            }
            _ => None,
        };
        match args {
            Some(a) => format!("{}({a})", self.name()),
            None => self.name().to_owned(),
        }
    }

    /// Wire bytes: the text followed by one NUL.
    pub fn encode(&self) -> Vec<u8> {
        let mut bytes = self.to_text().into_bytes();
        bytes.push(NUL);
        bytes
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_text())
    }
}

/// Writes a number with at most [`ARG_DECIMALS`] decimals and no trailing zeros
/// (`10`, `-0.5`, `0.000000001`); never exponent notation.
pub fn format_number(v: f64) -> String {
    let s = format!("{v:.ARG_DECIMALS$}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { s.as_str() };
    if s == "-0" { "0".to_owned() } else { s.to_owned() }
}

/// Why a command line could not be understood; [`CommandError::code`] is the robot's reply
/// code for it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// Unknown or empty command name → `[1001]`.
    #[error("unknown command '{0}'")]
    Unknown(String),
    /// Missing parenthesis, stray characters, non-numeric argument → `[1002]`.
    #[error("syntax error in '{0}'")]
    Syntax(String),
    /// Wrong number of arguments, or an argument of the wrong kind/range → `[1003]`.
    #[error("wrong arguments for {name}: {reason}")]
    Arguments {
        /// canonical command name
        name: &'static str,
        /// what is wrong
        reason: String,
    },
}

impl CommandError {
    /// The Meca500 reply code for this error (1001, 1002 or 1003).
    pub fn code(&self) -> u16 {
        match self {
            CommandError::Unknown(_) => 1001,
            CommandError::Syntax(_) => 1002,
            CommandError::Arguments { .. } => 1003,
        }
    }
}

/// A command as received: the command and whether it carried the silent `-` prefix.
#[derive(Debug, Clone, PartialEq)]
pub struct ParsedCommand {
    /// the command
    pub command: Command,
    /// it started with `-` (not written to the robot's user log)
    pub silent: bool,
}

/// Parses one command line (terminator already removed): case-insensitive name, optional
/// leading `-`, optional `(a1, a2, …)` with optional spaces.
pub fn parse_command(line: &str) -> Result<ParsedCommand, CommandError> {
    let trimmed = line.trim_matches(|c: char| c.is_ascii_whitespace());
    let (silent, body) = match trimmed.strip_prefix('-') {
        Some(rest) => (true, rest.trim_start()),
        None => (false, trimmed),
    };
    if body.is_empty() {
        return if silent {
            Err(CommandError::Unknown(String::new()))
        } else {
            Ok(ParsedCommand { command: Command::Empty, silent })
        };
    }
    let (name, args) = split_name_args(body)?;
    let (canonical, shape) = TABLE
        .iter()
        .find(|(n, _)| n.eq_ignore_ascii_case(name))
        .copied()
        .ok_or_else(|| CommandError::Unknown(name.to_owned()))?;
    let command = build_command(canonical, shape, &args)?;
    Ok(ParsedCommand { command, silent })
}

/// Splits `Name(a, b)` into the name and the raw argument strings.
fn split_name_args(body: &str) -> Result<(&str, Vec<&str>), CommandError> {
    let syntax = || CommandError::Syntax(body.to_owned());
    let (name, args) = match body.find('(') {
        None => (body.trim_end(), Vec::new()),
        Some(open) => {
            let inner = body[open + 1..].trim_end().strip_suffix(')').ok_or_else(syntax)?;
            if inner.contains('(') || inner.contains(')') {
                return Err(syntax());
            }
            let args = if inner.trim().is_empty() {
                Vec::new()
            } else {
                inner.split(',').map(str::trim).collect::<Vec<_>>()
            };
            (body[..open].trim_end(), args)
        }
    };
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(if name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            CommandError::Unknown(name.to_owned())
        } else {
            syntax()
        });
    }
    if args.iter().any(|a| a.is_empty()) {
        return Err(syntax());
    }
    Ok((name, args))
}

fn build_command(name: &'static str, shape: Shape, args: &[&str]) -> Result<Command, CommandError> {
    let arity = |n: usize| {
        if args.len() == n {
            Ok(())
        } else {
            Err(CommandError::Arguments {
                name,
                reason: format!("expected {n} argument(s), got {}", args.len()),
            })
        }
    };
    match shape {
        Shape::None => {
            arity(0)?;
            no_arg_command(name)
        }
        Shape::Float => {
            arity(1)?;
            let v = parse_float(name, args[0])?;
            float_command(name, v)
        }
        Shape::SixFloats => {
            arity(6)?;
            let mut six = [0.0; 6];
            for (slot, a) in six.iter_mut().zip(args) {
                *slot = parse_float(name, a)?;
            }
            six_command(name, six)
        }
        Shape::Uint => {
            arity(1)?;
            let v = parse_float(name, args[0])?;
            if v < 0.0 || v.fract() != 0.0 || v > u64::MAX as f64 {
                return Err(CommandError::Arguments {
                    name,
                    reason: format!("'{}' is not a whole number", args[0]),
                });
            }
            uint_command(name, v as u64)
        }
        Shape::Bool => {
            arity(1)?;
            let v = parse_float(name, args[0])?;
            let b = match v {
                0.0 => false,
                1.0 => true,
                _ => {
                    return Err(CommandError::Arguments {
                        name,
                        reason: format!("'{}' is not 0 or 1", args[0]),
                    });
                }
            };
            bool_command(name, b)
        }
        Shape::Codes => {
            if args.len() == 1 && args[0].eq_ignore_ascii_case("all") {
                return Ok(Command::SetRealTimeMonitoring(RealTimeCodes::All));
            }
            let mut codes = Vec::with_capacity(args.len());
            for a in args {
                let v = parse_float(name, a)?;
                if !(0.0..=9999.0).contains(&v) || v.fract() != 0.0 {
                    return Err(CommandError::Arguments { name, reason: format!("'{a}' is not a code") });
                }
                codes.push(v as u16);
            }
            Ok(Command::SetRealTimeMonitoring(RealTimeCodes::Codes(codes)))
        }
    }
}

fn parse_float(_name: &'static str, s: &str) -> Result<f64, CommandError> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(CommandError::Syntax(s.to_owned())),
    }
}

fn no_arg_command(name: &str) -> Result<Command, CommandError> {
    use Command as C;
    Ok(match name {
        "ActivateRobot" => C::ActivateRobot,
        "DeactivateRobot" => C::DeactivateRobot,
        "Home" => C::Home,
        "ResetError" => C::ResetError,
        "PauseMotion" => C::PauseMotion,
        "ResumeMotion" => C::ResumeMotion,
        "ClearMotion" => C::ClearMotion,
        "GetStatusRobot" => C::GetStatusRobot,
        "GetJoints" => C::GetJoints,
        "GetPose" => C::GetPose,
        "GetRtTargetJointPos" => C::GetRtTargetJointPos,
        "GetRtJointPos" => C::GetRtJointPos,
        "GetRtTargetCartPos" => C::GetRtTargetCartPos,
        "GetRtCartPos" => C::GetRtCartPos,
        "GetRobotSerial" => C::GetRobotSerial,
        "GetFwVersion" => C::GetFwVersion,
        "GetFwVersionFull" => C::GetFwVersionFull,
        "GetProductType" => C::GetProductType,
        "GetTrf" => C::GetTrf,
        "GetWrf" => C::GetWrf,
        "GetMonitoringInterval" => C::GetMonitoringInterval,
        "GetRealTimeMonitoring" => C::GetRealTimeMonitoring,
        other => return Err(CommandError::Unknown(other.to_owned())),
    })
}

fn float_command(name: &'static str, v: f64) -> Result<Command, CommandError> {
    use Command as C;
    Ok(match name {
        "SetJointVel" => C::SetJointVel(v),
        "SetJointAcc" => C::SetJointAcc(v),
        "SetCartLinVel" => C::SetCartLinVel(v),
        "SetCartAngVel" => C::SetCartAngVel(v),
        "SetCartAcc" => C::SetCartAcc(v),
        "SetBlending" => C::SetBlending(v),
        "SetJointVelLimit" => C::SetJointVelLimit(v),
        "Delay" => C::Delay(v),
        "SetMonitoringInterval" => C::SetMonitoringInterval(v),
        other => return Err(CommandError::Unknown(other.to_owned())),
    })
}

fn six_command(name: &'static str, s: Six) -> Result<Command, CommandError> {
    use Command as C;
    Ok(match name {
        "MoveJoints" => C::MoveJoints(s),
        "MoveJointsRel" => C::MoveJointsRel(s),
        "MovePose" => C::MovePose(s),
        "MoveLin" => C::MoveLin(s),
        "MoveLinRelTrf" => C::MoveLinRelTrf(s),
        "MoveLinRelWrf" => C::MoveLinRelWrf(s),
        "SetTrf" => C::SetTrf(s),
        "SetWrf" => C::SetWrf(s),
        other => return Err(CommandError::Unknown(other.to_owned())),
    })
}

fn uint_command(name: &'static str, v: u64) -> Result<Command, CommandError> {
    let small = || {
        u32::try_from(v).map_err(|_| CommandError::Arguments { name, reason: format!("{v} is too large") })
    };
    Ok(match name {
        "SetCheckpoint" => Command::SetCheckpoint(small()?),
        "SyncCmdQueue" => Command::SyncCmdQueue(small()?),
        "SetRtc" => Command::SetRtc(v),
        other => return Err(CommandError::Unknown(other.to_owned())),
    })
}

fn bool_command(name: &'static str, b: bool) -> Result<Command, CommandError> {
    Ok(match name {
        "SetEob" => Command::SetEob(b),
        "SetEom" => Command::SetEom(b),
        "SetCtrlPortMonitoring" => Command::SetCtrlPortMonitoring(b),
        other => return Err(CommandError::Unknown(other.to_owned())),
    })
}

// ---------------------------------------------------------------------------------------------
// Replies
// ---------------------------------------------------------------------------------------------

/// Reply / event codes the driver and simulator refer to by name (§1.5, §1.9).
pub mod code {
    /// command buffer full
    pub const BUFFER_FULL: u16 = 1000;
    /// unknown or empty command
    pub const UNKNOWN_COMMAND: u16 = 1001;
    /// syntax error
    pub const SYNTAX_ERROR: u16 = 1002;
    /// wrong argument count or value out of range
    pub const BAD_ARGUMENTS: u16 = 1003;
    /// robot not activated
    pub const NOT_ACTIVATED: u16 = 1005;
    /// robot not homed
    pub const NOT_HOMED: u16 = 1006;
    /// joint over its limit
    pub const JOINT_LIMIT: u16 = 1007;
    /// robot is in error
    pub const IN_ERROR: u16 = 1011;
    /// linear move would cross a singularity
    pub const SINGULARITY: u16 = 1012;
    /// activation failed
    pub const ACTIVATION_FAILED: u16 = 1013;
    /// homing failed
    pub const HOMING_FAILED: u16 = 1014;
    /// pose out of reach
    pub const OUT_OF_REACH: u16 = 1016;
    /// mastering lost (not resettable)
    pub const MASTERING_LOST: u16 = 1024;
    /// error cannot be reset
    pub const NOT_RESETTABLE: u16 = 1025;
    /// motors activated
    pub const ACTIVATED: u16 = 2000;
    /// already activated (old firmware)
    pub const ALREADY_ACTIVATED: u16 = 2001;
    /// homing done
    pub const HOMED: u16 = 2002;
    /// already homed (old firmware)
    pub const ALREADY_HOMED: u16 = 2003;
    /// motors deactivated
    pub const DEACTIVATED: u16 = 2004;
    /// error reset
    pub const ERROR_RESET: u16 = 2005;
    /// there was no error to reset
    pub const NO_ERROR_TO_RESET: u16 = 2006;
    /// status word
    pub const STATUS: u16 = 2007;
    /// joints (legacy)
    pub const JOINTS: u16 = 2026;
    /// pose (legacy)
    pub const POSE: u16 = 2027;
    /// WRF
    pub const WRF: u16 = 2013;
    /// TRF
    pub const TRF: u16 = 2014;
    /// motion paused
    pub const PAUSED: u16 = 2042;
    /// motion resumed
    pub const RESUMED: u16 = 2043;
    /// motion cleared
    pub const CLEARED: u16 = 2044;
    /// end of movement events enabled / disabled
    pub const EOM_ON: u16 = 2052;
    /// end of movement events disabled
    pub const EOM_OFF: u16 = 2053;
    /// end of block events enabled
    pub const EOB_ON: u16 = 2054;
    /// end of block events disabled
    pub const EOB_OFF: u16 = 2055;
    /// firmware version
    pub const FW_VERSION: u16 = 2081;
    /// full firmware version
    pub const FW_VERSION_FULL: u16 = 2082;
    /// robot serial
    pub const SERIAL: u16 = 2083;
    /// product type
    pub const PRODUCT_TYPE: u16 = 2084;
    /// acknowledgement of `SetCtrlPortMonitoring` (our simulator's choice, see §1.4)
    pub const CTRL_PORT_MONITORING: u16 = 2096;
    /// `SyncCmdQueue` marker
    pub const SYNC: u16 = 2097;
    /// monitoring interval
    pub const MONITORING_INTERVAL: u16 = 2116;
    /// enabled real-time codes
    pub const RT_MONITORING: u16 = 2117;
    /// target joints with time stamp
    pub const RT_TARGET_JOINTS: u16 = 2200;
    /// target pose with time stamp
    pub const RT_TARGET_CART: u16 = 2201;
    /// measured joints with time stamp
    pub const RT_JOINTS: u16 = 2210;
    /// measured pose with time stamp
    pub const RT_CART: u16 = 2211;
    /// end of a monitoring cycle
    pub const RT_CYCLE_END: u16 = 2230;
    /// connection banner
    pub const CONNECTED: u16 = 3000;
    /// another user is connected
    pub const ANOTHER_USER: u16 = 3001;
    /// firmware update in progress
    pub const FIRMWARE_UPDATE: u16 = 3002;
    /// command too long / missing terminator
    pub const COMMAND_TOO_LONG: u16 = 3003;
    /// end of movement event
    pub const EOM: u16 = 3004;
    /// motion error
    pub const MOTION_ERROR: u16 = 3005;
    /// drive communication error
    pub const DRIVE_COMM: u16 = 3006;
    /// initialisation failed
    pub const INIT_FAILED: u16 = 3009;
    /// end of block event
    pub const EOB: u16 = 3012;
    /// maintenance check found a hardware problem
    pub const MAINTENANCE: u16 = 3026;
    /// internal error
    pub const INTERNAL: u16 = 3027;
    /// torque limit exceeded
    pub const TORQUE_LIMIT: u16 = 3029;
    /// checkpoint reached
    pub const CHECKPOINT: u16 = 3030;
    /// P-Stop 2 raised / cleared
    pub const PSTOP2: u16 = 3032;
    /// checkpoint discarded
    pub const CHECKPOINT_DISCARDED: u16 = 3040;
    /// reboot pending
    pub const REBOOT_PENDING: u16 = 3053;
    /// P-Stop 1 (newer firmware)
    pub const PSTOP1: u16 = 3069;
    /// E-Stop raised / cleared
    pub const ESTOP: u16 = 3070;
}

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

// ---------------------------------------------------------------------------------------------
// Status word
// ---------------------------------------------------------------------------------------------

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

// ---------------------------------------------------------------------------------------------
// Banner
// ---------------------------------------------------------------------------------------------

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

// ---------------------------------------------------------------------------------------------
// Framing
// ---------------------------------------------------------------------------------------------

pub use vatcal_hardware_traits::transport::FrameError;

/// Cuts a byte stream into NUL-terminated frames: the shared
/// [`LineDeframer`] configured for the
/// Meca500 (frames up to [`MAX_FRAME_LEN`] bytes, empty frames kept). TCP may split or
/// coalesce messages: push whatever arrived, then pop complete frames with `next_frame`; the
/// unterminated tail is kept for the next push. Every method of the shared deframer is
/// available through `Deref`.
#[derive(Debug, Clone)]
pub struct Deframer(LineDeframer);

impl Deframer {
    /// Splits on NUL only (what the robot sends, and what the driver reads).
    pub fn nul_only() -> Self {
        Self(LineDeframer::new(Framing::nul(MAX_FRAME_LEN)))
    }

    /// Splits on NUL **or** LF (the robot also accepts LF-terminated commands, §1.1; a CR
    /// before the LF is removed).
    pub fn nul_or_lf() -> Self {
        Self(LineDeframer::new(Framing::nul_or_lf(MAX_FRAME_LEN)))
    }
}

impl std::ops::Deref for Deframer {
    type Target = LineDeframer;

    fn deref(&self) -> &LineDeframer {
        &self.0
    }
}

impl std::ops::DerefMut for Deframer {
    fn deref_mut(&mut self) -> &mut LineDeframer {
        &mut self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn parse(s: &str) -> Command {
        match parse_command(s) {
            Ok(p) => p.command,
            Err(e) => panic!("{s}: {e}"),
        }
    }

    #[test]
    fn encodes_the_lines_mecademicpy_writes() {
        // protocols.md §1.2: mecademicpy writes exactly these
        assert_eq!(
            Command::MoveJoints([10.0, -20.0, 30.0, 0.0, 45.0, 0.0]).to_text(),
            "MoveJoints(10,-20,30,0,45,0)"
        );
        assert_eq!(
            Command::MoveLinRelTrf([0.01, 0.0, 0.0, 0.0, 0.0, 0.0]).to_text(),
            "MoveLinRelTrf(0.01,0,0,0,0,0)"
        );
        assert_eq!(Command::GetStatusRobot.encode(), b"GetStatusRobot\0");
        assert_eq!(Command::SetRtc(1795314763).to_text(), "SetRtc(1795314763)");
        assert_eq!(Command::SetCtrlPortMonitoring(true).to_text(), "SetCtrlPortMonitoring(1)");
        assert_eq!(Command::Empty.encode(), vec![0u8]);
        assert_eq!(format_number(-0.0000000001), "0");
        assert_eq!(format_number(1e-9), "0.000000001");
    }

    #[test]
    fn parses_the_transcript_commands_of_the_reference() {
        // §1.4 connect sequence and §1.9 error transcript
        let cases = [
            ("-GetRobotSerial", Command::GetRobotSerial, true),
            ("-GetFwVersionFull", Command::GetFwVersionFull, true),
            ("-GetRealTimeMonitoring", Command::GetRealTimeMonitoring, true),
            ("-GetMonitoringInterval", Command::GetMonitoringInterval, true),
            ("-SetRtc(1795314763)", Command::SetRtc(1795314763), true),
            ("-SetCtrlPortMonitoring(1)", Command::SetCtrlPortMonitoring(true), true),
            ("MoveJoints(200,0,0,0,0,0)", Command::MoveJoints([200.0, 0.0, 0.0, 0.0, 0.0, 0.0]), false),
            ("SetCheckpoint(8001)", Command::SetCheckpoint(8001), false),
            ("ResetError", Command::ResetError, false),
            ("ResumeMotion", Command::ResumeMotion, false),
            ("", Command::Empty, false),
        ];
        for (line, cmd, silent) in cases {
            let p = parse_command(line).unwrap_or_else(|e| panic!("{line}: {e}"));
            assert_eq!(p.command, cmd, "{line}");
            assert_eq!(p.silent, silent, "{line}");
        }
    }

    #[test]
    fn parsing_is_case_insensitive_and_tolerates_spaces() {
        assert_eq!(
            parse("movejoints( 1, 2 ,3,4,5, 6 )"),
            Command::MoveJoints([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
        );
        assert_eq!(parse("  GETSTATUSROBOT "), Command::GetStatusRobot);
        assert_eq!(parse("GetJoints()"), Command::GetJoints);
        assert_eq!(parse("SetRealTimeMonitoring(all)"), Command::SetRealTimeMonitoring(RealTimeCodes::All));
        assert_eq!(
            parse("SetRealTimeMonitoring(2200, 2210)"),
            Command::SetRealTimeMonitoring(RealTimeCodes::Codes(vec![2200, 2210]))
        );
    }

    #[test]
    fn bad_commands_map_to_the_robot_codes() {
        let code = |s: &str| parse_command(s).map(|_| 0).unwrap_or_else(|e| e.code());
        assert_eq!(code("Dance"), 1001);
        assert_eq!(code("-"), 1001);
        assert_eq!(code("MoveJoints(1,2,3"), 1002);
        assert_eq!(code("MoveJoints(1,2,x,4,5,6)"), 1002);
        assert_eq!(code("MoveJoints(1,,3,4,5,6)"), 1002);
        assert_eq!(code("Move Joints(1)"), 1002);
        assert_eq!(code("MoveJoints(1,2,3)"), 1003);
        assert_eq!(code("Home(1)"), 1003);
        assert_eq!(code("SetCheckpoint(1.5)"), 1003);
        assert_eq!(code("SetEob(2)"), 1003);
    }

    #[test]
    fn parses_the_replies_quoted_in_the_reference() {
        let r = |s: &str| Reply::parse(s.as_bytes()).unwrap_or_else(|e| panic!("{s}: {e}"));
        assert_eq!(r("[2083][M500-0000]"), Reply::new(2083, "M500-0000"));
        assert_eq!(r("[2117][]"), Reply::new(2117, ""));
        assert_eq!(r("[2116][0.015]").values(), Ok(vec![0.015]));
        let st = StatusWord::from_reply(&r("[2007][0,0,0,0,0,1,1]")).unwrap_or_else(|e| panic!("{e}"));
        assert!(!st.activated && st.end_of_block && st.end_of_movement);
        let st = StatusWord::from_reply(&r("[2007][1,1,0,1,1,1,1]")).unwrap_or_else(|e| panic!("{e}"));
        assert!(st.activated && st.homed && st.error && st.paused);
        assert!(r("[1007][Joint 1 over limit ...]").is_error());
        assert!(r("[1011][The robot is already in error.]").is_error());
        assert!(!r("[2005][The error was reset.]").is_error());
        assert!(r("[3070][1]").is_error());
        assert!(!r("[3070][0]").is_error());
        assert!(!r("[3030][8001]").is_error());
        // payload runs to the LAST ']'
        assert_eq!(r("[1001][Unknown command [Foo]]").payload, "Unknown command [Foo]");
        assert_eq!(Reply::parse(b"{\"a\":1}"), Err(ReplyError::Json));
        assert!(matches!(Reply::parse(b"2007 1,1"), Err(ReplyError::MissingCode(_))));
        assert!(matches!(Reply::parse(b"[20x7][1]"), Err(ReplyError::BadCode(_))));
        assert!(matches!(Reply::parse(b"[2007]"), Err(ReplyError::MissingPayload(_))));
        assert_eq!(Reply::parse(&[0x5b, 0xff]), Err(ReplyError::NotAscii));
    }

    #[test]
    fn rt_joint_reply_skips_the_time_stamp() {
        let r = Reply::new(2200, "123456,1,2,3,4,5,6");
        assert_eq!(r.last_six(), Ok([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]));
        assert!(Reply::new(2200, "1,2,3").last_six().is_err());
        assert!(Reply::new(2026, "1,2,3,4,5,nan").values().is_err());
    }

    #[test]
    fn banner_variants() {
        let b = Banner::from_reply(&Reply::new(3000, "Connected to Meca500 R3 v9.3.0"))
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((b.model.as_str(), b.revision, b.version), ("Meca500", Some(3), (9, 3, 0)));
        assert_eq!(b.to_text(), "Connected to Meca500 R3 v9.3.0");
        let b = Banner::from_reply(&Reply::new(3000, "Connected to meca500 R4-virtual v10.1.2.1234"))
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(b.virtual_robot && b.revision == Some(4) && b.version == (10, 1, 2));
        let b = Banner::from_reply(&Reply::new(3000, "Connected to Meca500_8.3.5"))
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((b.revision, b.version), (None, (8, 3, 5)));
        assert!(matches!(
            Banner::from_reply(&Reply::new(3001, "Another user is already connected, closing connection.")),
            Err(BannerError::Refused(_))
        ));
        assert!(matches!(
            Banner::from_reply(&Reply::new(3000, "Connected to Robot R3 v9.3.0")),
            Err(BannerError::UnknownModel(_))
        ));
        assert!(matches!(Banner::from_reply(&Reply::new(3000, "hello")), Err(BannerError::Unparsable(_))));
        assert!(matches!(Banner::from_reply(&Reply::new(2007, "1")), Err(BannerError::NotABanner(_))));
    }

    #[test]
    fn deframer_handles_lf_crlf_and_overlong_input() {
        let mut d = Deframer::nul_or_lf();
        d.push(b"GetJoints\nHome\r\nResetError\0Act");
        let mut frames = Vec::new();
        while let Ok(Some(f)) = d.next_frame() {
            frames.push(f);
        }
        assert_eq!(frames, vec![b"GetJoints".to_vec(), b"Home".to_vec(), b"ResetError".to_vec()]);
        assert_eq!(d.pending(), 3);
        let mut d = Deframer::nul_only();
        d.push(&vec![b'x'; MAX_FRAME_LEN + 1]);
        assert_eq!(d.next_frame(), Err(FrameError::TooLong { max: MAX_FRAME_LEN }));
        assert_eq!(d.pending(), 0);
        // the rest of the overlong frame (up to its NUL) is dropped, then frames come intact
        d.push(b"xxx\0[2007][1]\0");
        assert_eq!(d.next_frame(), Ok(Some(b"[2007][1]".to_vec())));
    }

    fn arb_number() -> impl Strategy<Value = f64> {
        prop_oneof![(-100_000.0f64..100_000.0), (-1.0f64..1.0), (-36_000i32..36_000).prop_map(f64::from)]
    }

    fn arb_six() -> impl Strategy<Value = Six> {
        proptest::array::uniform6(arb_number())
    }

    fn arb_command() -> impl Strategy<Value = Command> {
        use Command as C;
        prop_oneof![
            Just(C::Empty),
            Just(C::ActivateRobot),
            Just(C::Home),
            Just(C::ResetError),
            Just(C::ClearMotion),
            Just(C::GetStatusRobot),
            Just(C::GetRtTargetJointPos),
            arb_number().prop_map(C::SetJointVel),
            arb_number().prop_map(C::SetCartLinVel),
            arb_number().prop_map(C::Delay),
            arb_six().prop_map(C::MoveJoints),
            arb_six().prop_map(C::MoveLinRelTrf),
            arb_six().prop_map(C::MoveLinRelWrf),
            arb_six().prop_map(C::SetTrf),
            any::<u32>().prop_map(C::SetCheckpoint),
            any::<u32>().prop_map(C::SyncCmdQueue),
            any::<bool>().prop_map(C::SetEob),
            any::<bool>().prop_map(C::SetCtrlPortMonitoring),
            (0u64..=u64::from(u32::MAX) * 4).prop_map(C::SetRtc),
            proptest::collection::vec(2200u16..2300, 0..5)
                .prop_map(|c| C::SetRealTimeMonitoring(RealTimeCodes::Codes(c))),
        ]
    }

    /// Equal up to the written precision (9 decimals).
    fn close(a: &Command, b: &Command) -> bool {
        let nums = |c: &Command| -> Vec<f64> {
            match c {
                Command::SetJointVel(v) | Command::SetCartLinVel(v) | Command::Delay(v) => vec![*v],
                Command::MoveJoints(s)
                | Command::MoveLinRelTrf(s)
                | Command::MoveLinRelWrf(s)
                | Command::SetTrf(s) => s.to_vec(),
                _ => Vec::new(),
            }
        };
        std::mem::discriminant(a) == std::mem::discriminant(b)
            && nums(a).len() == nums(b).len()
            && nums(a).iter().zip(nums(b)).all(|(x, y)| (x - y).abs() <= 1e-9 + 1e-15 * x.abs())
            && (!nums(a).is_empty() || a == b)
    }

    proptest! {
        #[test]
        fn command_round_trip(cmd in arb_command()) {
            let bytes = cmd.encode();
            prop_assert_eq!(bytes.last(), Some(&NUL));
            prop_assert!(bytes[..bytes.len() - 1].iter().all(|&b| b != NUL && b.is_ascii()));
            let mut d = Deframer::nul_or_lf();
            d.push(&bytes);
            let frame = d.next_frame().ok().flatten().unwrap_or_default();
            let back = parse_command(&String::from_utf8_lossy(&frame));
            prop_assert!(back.is_ok(), "{:?}", back);
            let back = back.map(|p| p.command).unwrap_or(Command::Empty);
            prop_assert!(close(&cmd, &back), "{:?} -> {} -> {:?}", cmd, cmd, back);
        }

        #[test]
        fn reply_round_trip(code in 0u16..10_000, payload in "[ -~]{0,40}") {
            let r = Reply::new(code, payload);
            let bytes = r.encode();
            let back = Reply::parse(&bytes[..bytes.len() - 1]);
            // surrounding whitespace is trimmed by the parser, not part of the payload
            prop_assert_eq!(back, Ok(r));
        }

        #[test]
        fn parsers_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..80), text in "[ -~]{0,80}") {
            let _ = Reply::parse(&bytes);
            let _ = parse_command(&String::from_utf8_lossy(&bytes));
            let _ = parse_command(&text);
            if let Ok(r) = Reply::parse(text.as_bytes()) {
                let _ = r.values();
                let _ = r.last_six();
                let _ = StatusWord::from_reply(&r);
                let _ = Banner::from_reply(&Reply::new(3000, r.payload.clone()));
            }
        }

        #[test]
        fn status_word_round_trip(flags in proptest::array::uniform7(any::<bool>())) {
            let s = StatusWord::from_flags(flags);
            prop_assert_eq!(StatusWord::from_reply(&s.to_reply()), Ok(s));
        }

        #[test]
        fn deframing_is_independent_of_tcp_segmentation(
            replies in proptest::collection::vec((0u16..10_000, "[ -~]{0,20}"), 1..8),
            cuts in proptest::collection::vec(0usize..400, 0..10),
        ) {
            let replies: Vec<Reply> = replies.into_iter().map(|(c, p)| Reply::new(c, p)).collect();
            let stream: Vec<u8> = replies.iter().flat_map(Reply::encode).collect();
            let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c % (stream.len() + 1)).collect();
            cuts.push(0);
            cuts.push(stream.len());
            cuts.sort_unstable();
            let mut d = Deframer::nul_only();
            let mut got = Vec::new();
            for w in cuts.windows(2) {
                d.push(&stream[w[0]..w[1]]);
                while let Ok(Some(f)) = d.next_frame() {
                    got.push(Reply::parse(&f));
                }
            }
            prop_assert_eq!(got, replies.into_iter().map(Ok).collect::<Vec<_>>());
        }
    }
}
