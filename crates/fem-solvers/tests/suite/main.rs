//! The integration test suite of fem-solvers, one binary with a module per topic (one link
//! instead of many): the stepper battery over every registered solver, explicit stepping,
//! PBD/XPBD, implicit Euler, linearly implicit Euler, statics, contact, thread determinism of
//! the other orderings, and the registry as scenes use it; `docs/solvers.md` kept true.

mod barrier_contact;
mod battery;
mod capability_table;
mod common;
mod contact;
mod critical_time_step;
mod determinism;
mod explicit;
mod grab;
mod implicit;
mod integrator;
mod linear_implicit;
mod nd;
mod nd_position_based;
mod nd_projective;
mod nd_quasi_newton;
mod nd_vbd;
mod position_based;
mod pressure;
mod projective;
mod quasi_newton;
mod quasi_newton_coupled;
mod regions;
mod registry;
mod rigid;
mod statics;
mod tolerance;
mod vbd;
