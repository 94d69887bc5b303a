//! # vatcal-identification (being written)
