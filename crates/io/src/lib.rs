//! # vatcal-io (being written)
