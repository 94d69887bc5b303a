//! # vatcal-observability (being written)
