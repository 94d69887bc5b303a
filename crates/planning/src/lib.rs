//! # vatcal-planning (being written)
