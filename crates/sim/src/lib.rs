//! # vatcal-sim (being written)
