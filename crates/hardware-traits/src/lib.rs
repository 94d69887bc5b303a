//! # vatcal-hardware-traits (being written)
