//! Parsing a received command line into a [`Command`] (the simulator's side), with the
//! robot's reply code for a line it does not understand ([`CommandError::code`]).

use super::Six;
use super::command::{Command, RealTimeCodes};

/// Argument shape of a command name, used by the parser.
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
