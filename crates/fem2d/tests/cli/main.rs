//! End-to-end tests of the `fem2d` binary, in one test binary (one link of the command and its
//! dependencies): every subcommand run as a user would, its files read back, bad input turned
//! into one-line errors.

mod commands;
mod common;
mod implicit;
mod mesh;
mod outputs;
mod pictures;
mod report;
mod run;
mod solid;
