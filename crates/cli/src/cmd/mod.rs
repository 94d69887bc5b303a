//! One module per subcommand.

pub mod demo;
pub mod discover;
pub mod fk;
pub mod identify;
pub mod observability;
pub mod plan;
pub mod select;
pub mod torque;
pub mod validate;
