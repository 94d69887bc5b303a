//! `--discovery-budget-min`: the device time the discovery measurements may take, shared by
//! `vatcal demo` and `vatcal calibrate`.

/// Default of `--discovery-budget-min` \[min\]: the library's default,
/// [`vatcal_pipeline::budget::DEFAULT_DISCOVERY_BUDGET_S`] (15 min of device time; a test
/// keeps the two equal).
pub const DEFAULT_BUDGET_MIN: &str = "15";

/// A device-time budget given in minutes on the command line, held in seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BudgetSeconds(pub Option<f64>);

/// Parses `--discovery-budget-min`: minutes of device time (> 0), or `none` for no budget
/// (the discovery campaign's full count and the targeted batch, whatever they take).
///
/// # Errors
/// Not a positive number of minutes nor `none`.
pub fn parse_budget_min(text: &str) -> Result<BudgetSeconds, String> {
    if text.trim().eq_ignore_ascii_case("none") {
        return Ok(BudgetSeconds(None));
    }
    match text.trim().parse::<f64>() {
        Ok(min) if min.is_finite() && min > 0.0 => Ok(BudgetSeconds(Some(60.0 * min))),
        _ => Err(format!("`{text}` is not a positive number of minutes (or `none`)")),
    }
}

#[cfg(test)]
mod tests {
    use super::{BudgetSeconds, DEFAULT_BUDGET_MIN, parse_budget_min};

    #[test]
    fn the_default_is_the_librarys() {
        assert_eq!(
            parse_budget_min(DEFAULT_BUDGET_MIN),
            Ok(BudgetSeconds(Some(vatcal_pipeline::budget::DEFAULT_DISCOVERY_BUDGET_S)))
        );
        let stage = vatcal_pipeline::discovery_stage::DiscoveryStageOptions::new(1);
        assert_eq!(stage.budget_s, Some(vatcal_pipeline::budget::DEFAULT_DISCOVERY_BUDGET_S));
    }

    #[test]
    fn minutes_or_none() {
        assert_eq!(parse_budget_min("15"), Ok(BudgetSeconds(Some(900.0))));
        assert_eq!(parse_budget_min("2.5"), Ok(BudgetSeconds(Some(150.0))));
        assert_eq!(parse_budget_min("none"), Ok(BudgetSeconds(None)));
        assert!(parse_budget_min("0").is_err());
        assert!(parse_budget_min("-3").is_err());
        assert!(parse_budget_min("fifteen").is_err());
    }
}
