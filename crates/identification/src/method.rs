//! The estimation method of a fit.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// The estimation method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Levenberg–Marquardt on the stacked, column-scaled Jacobian, gain-ratio damping control,
    /// each step by QR of the augmented matrix `[J_s; √λ I]` (background.md §6.3). Default.
    #[default]
    LevenbergMarquardt,
    /// Undamped Gauss–Newton on the stacked Jacobian: `Δρ = J⁺ r` by QR (what the paper's
    /// Table 7 is meant to do, background.md §6.2).
    GaussNewton,
    /// The paper's Table 7 / Eqs. (10)–(13) read literally: one minimum-norm pseudo-inverse
    /// correction per pose, summed over the poses. Kept **for comparison only**: it does not
    /// minimise the least-squares cost and diverges on realistic data (see
    /// `docs/identification.md`).
    PaperLiteral,
}

impl Method {
    /// Short name used by the CLI: `lm`, `gn`, `paper`.
    pub fn short_name(self) -> &'static str {
        match self {
            Method::LevenbergMarquardt => "lm",
            Method::GaussNewton => "gn",
            Method::PaperLiteral => "paper",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Method::LevenbergMarquardt => "Levenberg-Marquardt",
            Method::GaussNewton => "Gauss-Newton",
            Method::PaperLiteral => "paper-literal (Table 7, per-pose pseudo-inverses)",
        })
    }
}

impl FromStr for Method {
    type Err = String;

    /// Parses `lm`, `gn`, `paper` (and the long kebab-case names).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "lm" | "levenberg-marquardt" => Ok(Method::LevenbergMarquardt),
            "gn" | "gauss-newton" => Ok(Method::GaussNewton),
            "paper" | "paper-literal" => Ok(Method::PaperLiteral),
            other => Err(format!("unknown method `{other}` (expected lm, gn or paper)")),
        }
    }
}
