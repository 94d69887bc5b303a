//! # vatcal-report (being written)
