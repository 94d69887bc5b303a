//! The `vatcal` command.
fn main() {}
