//! One module per `fem2d` subcommand.

pub mod budget;
pub mod compare;
pub mod mesh;
pub mod report;
pub mod run;
pub mod scaling;
pub mod sweep;
pub mod table1;
