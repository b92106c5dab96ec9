//! One module per `fem2d` subcommand.

pub mod mesh;
pub mod run;
