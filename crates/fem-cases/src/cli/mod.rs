//! The `fem2d` subcommands, one module each.

pub mod mesh;
