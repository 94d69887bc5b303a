//! [`Command`]: the text-API commands, their names, kinds and wire encoding.

use std::fmt;

use super::{ARG_DECIMALS, NUL, Six};

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
