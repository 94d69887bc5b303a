//! Everything vatcal knows about its **canonical cell** — the paper's Meca500 on a Zaber linear
//! guide (cell file version 1, `fixtures/meca500-zaber.toml`) — in one place.
//!
//! Generic crates (observability, identification, planning, the CLI) ask this module whether a
//! chain is the canonical one ([`is_canonical_chain`]) and read the canonical defaults from here:
//! the default parameter set ([`default_param_set`], the paper's 34), the parameter-set names
//! that only make sense on it ([`CANONICAL_ONLY_SETS`]) and the advice printed with rank and
//! conditioning errors ([`rank_hint`], [`conditioning_hint`]). On any other chain the generic
//! wording is used. (The canonical plausibility bounds of the effect catalog belong here too, as
//! `canonical::bounds`; the closed-form IK of planning is selected through
//! [`is_canonical_chain`], via `vatcal_kinematics::Model::is_meca500_on_guide`.)

pub mod bounds;

use crate::params::ParamSet;
use crate::units::{JointKind, MECA500_ON_GUIDE_KINDS};

/// The dispatch predicate: true for the canonical chain — 7 joints, a prismatic guide followed
/// by the six revolute Meca500 joints.
///
/// # Examples
/// ```
/// use vatcal_core::JointKind::{Prismatic as P, Revolute as R};
/// use vatcal_core::canonical::is_canonical_chain;
///
/// assert!(is_canonical_chain(&[P, R, R, R, R, R, R]));
/// assert!(!is_canonical_chain(&[R, R, R, R, R, R]));
/// ```
pub fn is_canonical_chain(kinds: &[JointKind]) -> bool {
    kinds == MECA500_ON_GUIDE_KINDS
}

/// Name of the canonical cell's default parameter set (what `--params default` means there).
pub const DEFAULT_PARAM_SET_NAME: &str = "paper34";

/// The canonical cell's default parameter set: the paper's 34 (Eq. 7).
pub fn default_param_set() -> ParamSet {
    ParamSet::paper34()
}

/// Parameter-set names that list the parameters of the canonical cell by the paper's names and
/// mean nothing on another chain: `paper34` and `geometric` (paper34 without compliances).
pub const CANONICAL_ONLY_SETS: [&str; 2] = ["paper34", "geometric"];

/// True when `spec` (trimmed) is one of [`CANONICAL_ONLY_SETS`].
pub fn is_canonical_only_set(spec: &str) -> bool {
    CANONICAL_ONLY_SETS.contains(&spec.trim())
}

/// The sentence ending a rank-deficiency error: what data fix it. On the canonical cell the
/// world frame is fixed by the three calibration positions; on another chain the advice is
/// generic.
pub fn rank_hint(kinds: &[JointKind]) -> &'static str {
    if is_canonical_chain(kinds) {
        "Fix or drop these parameters, or add poses (all three calibration positions are needed to fix the world frame)."
    } else {
        "Fix or drop these parameters (a smaller set: --params registration or joint-offsets), or add postures that move every joint over more of its range."
    }
}

/// The advice ending an ill-conditioning error (see [`rank_hint`]).
pub fn conditioning_hint(kinds: &[JointKind]) -> &'static str {
    if is_canonical_chain(kinds) {
        "add poses (at all three calibration positions), drop parameters, or give priors"
    } else {
        "add postures that move every joint over more of its range, drop parameters (--params registration or joint-offsets), or give priors"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::JointKind::{Prismatic as P, Revolute as R};

    #[test]
    fn only_the_guide_plus_six_revolute_chain_is_canonical() {
        assert!(is_canonical_chain(&MECA500_ON_GUIDE_KINDS));
        assert!(!is_canonical_chain(&[R, P, R, R, R, R, R]));
        assert!(!is_canonical_chain(&[P, R, R, R, R, R, R, R]));
        assert!(!is_canonical_chain(&[]));
        assert_eq!(default_param_set(), ParamSet::parse(DEFAULT_PARAM_SET_NAME).expect("name"));
        assert!(is_canonical_only_set(" geometric") && !is_canonical_only_set("kinematic"));
        assert_ne!(rank_hint(&[R; 6]), rank_hint(&MECA500_ON_GUIDE_KINDS));
        assert!(conditioning_hint(&MECA500_ON_GUIDE_KINDS).contains("three calibration positions"));
    }
}
