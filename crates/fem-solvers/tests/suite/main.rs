//! The integration test suite of fem-solvers, one binary with a module per topic (one link
//! instead of many): explicit stepping, PBD/XPBD, contact and thread determinism.

mod common;
mod contact;
mod determinism;
mod explicit;
mod implicit;
mod position_based;
mod statics;
