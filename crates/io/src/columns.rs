//! Column names shared by the readers and writers: the joint columns `q1..qN`, the direction
//! columns `dir{i}`, the probe offsets, and the spans of names used in messages.

use vatcal_core::JointKind;
use vatcal_kinematics::Model;

/// The joint columns `q1..qN` of an N-joint chain.
pub fn joint_columns(n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("q{i}")).collect()
}

/// The direction columns `dir{i}` of the revolute joints i of a chain with joints `kinds`.
pub fn dir_columns(kinds: &[JointKind]) -> Vec<(usize, String)> {
    kinds
        .iter()
        .enumerate()
        .filter(|(_, k)| k.is_revolute())
        .map(|(k, _)| (k + 1, format!("dir{}", k + 1)))
        .collect()
}

/// `first..last` (or the single name) for messages.
pub(crate) fn span(columns: &[String]) -> String {
    match columns {
        [] => String::new(),
        [one] => one.clone(),
        [first, .., last] => format!("{first}..{last}"),
    }
}

/// The column names a reader needs: `prefix`, then `q1..qN`, then `suffix`.
pub(crate) fn required_columns(prefix: &[&str], model: &Model, suffix: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = prefix.iter().map(|s| s.to_string()).collect();
    v.extend(joint_columns(model.joint_count()));
    v.extend(suffix.iter().map(|s| s.to_string()));
    v
}

/// The optional per-row centring offset columns of probe measurements (world axes, mm).
pub const OFFSET_COLUMNS: [&str; 3] = ["offset_x_mm", "offset_y_mm", "offset_z_mm"];
