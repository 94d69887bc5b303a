//! # vatcal-discovery (being written)
