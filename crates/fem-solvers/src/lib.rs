//! # fem-solvers: time stepping, boundary conditions and contact for 2D elastodynamics
//!
//! Pick this crate to advance a [`fem_core`] mesh in time with the paper's three frameworks
//! (Sections 3.1-3.2): explicit FEM (Algorithm I), energy-based PBD (Eqs. 4-6) and energy-based
//! XPBD (Algorithm II, Eq. 7), with pinned and prescribed vertices, gravity, nodal loads and
//! boundary tractions, a ground and rigid obstacles; and beyond the paper, implicit Euler
//! ([`ImplicitStepper`]) and quasi-static equilibrium ([`StaticStepper`]), both by Newton with a
//! sparse Cholesky factorisation (faer), and for real-time frame rates the same implicit Euler
//! step by cheaper iterations: Vertex Block Descent ([`VbdStepper`]), Projective Dynamics
//! ([`PdStepper`], co-rotational) and L-BFGS with the Projective Dynamics matrix
//! ([`QuasiNewtonStepper`]). These four also take second-order BDF2 steps in place of
//! backward Euler's ([`Integrator`], [`integrator`]).
//! Linearly implicit Euler ([`LinearImplicitStepper`]) takes one linear solve per step, with
//! no Newton loop.
//!
//! The pieces, kept apart:
//! - a [`Model`] (mesh, energy, lumped masses, boundary conditions, loads, obstacles): fixed
//!   during a run except for the drag attachment ([`Grab`], a pin or a compliant spring moved
//!   between steps and honoured by every stepper; see [`grab`]);
//! - a [`State`] (positions, velocities, rigid-body poses, clock): what steps change;
//! - steppers that advance a state by one step of their clock ([`Clock`]: a time step, or for
//!   the static solver a load increment) and return a [`StepReport`] (min det F, inverted
//!   elements, iterations, constraint or Newton residual, contacts): [`ExplicitStepper`],
//!   [`PbdStepper`], [`XpbdStepper`], [`ImplicitStepper`], [`StaticStepper`], [`VbdStepper`],
//!   [`PdStepper`], [`QuasiNewtonStepper`], [`LinearImplicitStepper`], all behind the
//!   [`Stepper`] trait.
//!
//! **Where things are**: the modules are folders that are layers, each using only those
//! listed before it: [`rigid`] (rigid bodies and the obstacles made of them), [`model`] (what
//! every solver reads: the model, the state, boundary conditions, the grab, limits,
//! diagnostics), [`contact`] (penalty and projection, barrier contact and its IPC primitives,
//! the broad phase, contact pressure), [`optim`] (Newton, the Projective Dynamics matrix) and
//! [`steppers`] (one file per solver, the registry, the step's commit and report). Every module
//! is also re-exported under its short path ([`grab`], [`explicit`], [`pressure`], ...).
//!
//! **The solver registry** ([`registry`]): one list of the solvers, from which [`SolverKind`]
//! (the names, [`SolverKind::ALL`], [`Capabilities`]), [`SolverParams`] (any solver's parameters,
//! validated under the caller's field names, built into a stepper) and [`AnyStepper`] (the
//! stepper chosen at run time, dispatching to the concrete one) are generated. Each solver
//! implements [`Solver`] in its own file; adding one is that file, one line in the list, and
//! the regenerated table of `docs/solvers.md` ([`capability_table`]).
//!
//! Also: the explicit stability guard ([`Model::check_time_step`]: `2 / omega` with `omega` the
//! element eigenvalue bound on the highest rest-state frequency, provably conservative at the
//! stiffness at rest; forward Euler warned about whenever it amplifies that mode), blow-up
//! detection (a step never writes non-finite values into
//! the state; it returns [`SolverError::NonFinite`] naming the step and the first bad vertex),
//! and energy diagnostics ([`diagnostics::energies`]).
//!
//! Optional feature `serde`: [`SolverKind`] (de)serialises as its name, the parameter structs
//! under the scene's `[solver]` keys (`SolverParams::deserialize_as` reads one solver's keys
//! from a flat table), and fem-core's energy and plane-model names likewise.
//!
//! Architecture invariants:
//! - **fem-solvers never names a concrete energy.** Models and steppers are generic over
//!   [`fem_core::energy::Energy`]; only tests, benches and examples pick one.
//! - **A step never writes a non-finite value into the state**: every stepper ends its steps
//!   through one commit that checks the new values before swapping them in.
//! - **Every stepper gives bit-identical states for any number of rayon threads**: fixed work
//!   chunks, element-order sums, no atomics, no hash maps (see the `kernel` module docs in the
//!   source; the stepper battery checks every registered solver).
//! - **Hot loops do not allocate**: steppers own their workspace, sized on construction or on
//!   the first step.
//!
//! Units are SI per unit thickness (plane strain or plane stress is decided where the energy's
//! Lamé parameters are built). Conventions where the paper's printed text is ambiguous or
//! departs from standard practice (symplectic Euler by default, damping `v <- v exp(-c dt)`, the
//! consistent XPBD constraint `C = sqrt(2 a psi)`) are documented in each stepper's module. On
//! `wasm32-unknown-unknown`, which has no clock of its own, Newton's reported time split reads
//! zero unless the host supplies one ([`fem_core::clock::set_clock`]).
//!
//! What this crate does not know: meshing, file formats, scenes and the command line, and
//! which energy a run uses.
//!
//! ```
//! use fem_core::{energy::NeoHookean, material::Material, PlaneModel};
//! use fem_solvers::{testing::beam_mesh, ExplicitParams, ExplicitStepper, Model, Region, State, Stepper};
//! use nalgebra::Vector2;
//! let lame = Material::new(1000.0, 0.3, 1.0).unwrap().lame(PlaneModel::PlaneStrain);
//! let mut model = Model::with_total_mass(beam_mesh(20, 4).unwrap(), NeoHookean::new(lame).unwrap(), 1.0)
//!     .unwrap()
//!;
//! model.set_standard_gravity();
//! model.pin(&Region::in_box(Vector2::new(0.0, 0.0), Vector2::new(0.0, 1.0))).unwrap();
//! let mut stepper = ExplicitStepper::new(&model, ExplicitParams { dt: 1e-3, damping: 1.0, ..Default::default() }).unwrap();
//! assert!(stepper.time_step_check().warning().is_none());
//! let mut state = State::at_rest(&model);
//! for _ in 0..100 {
//!     stepper.step(&model, &mut state).unwrap();
//! }
//! // After 0.1 s the tip has fallen about 1/2 g t^2 = 49 mm (paper Table 1, frame 10).
//! let tip = state.displacement(&model, fem_solvers::testing::node_index(20, 0, 20));
//! assert!((tip.y + 0.049).abs() < 0.003);
//! ```
//!
//! The same run with the solver chosen by name, through the registry:
//!
//! ```
//! use fem_core::{energy::NeoHookean, material::Material, PlaneModel};
//! use fem_solvers::{testing::{beam_mesh, cantilever}, SolverKind, State, Stepper};
//! let lame = Material::new(1000.0, 0.3, 1.0).unwrap().lame(PlaneModel::PlaneStrain);
//! let model = cantilever(beam_mesh(20, 4).unwrap(), NeoHookean::new(lame).unwrap()).unwrap();
//! let kind: SolverKind = "xpbd".parse().unwrap();
//! let mut params = kind.default_params();
//! params.set_dt(1e-3);
//! params.validate_as("solver").unwrap();
//! let mut stepper = params.build(&model).unwrap();
//! let mut state = State::at_rest(&model);
//! for _ in 0..100 {
//!     stepper.step(&model, &mut state).unwrap();
//! }
//! assert!((state.t - 0.1).abs() < 1e-12);
//! assert!(kind.capabilities().contact);
//! ```

// The tree is the architecture (ARCHITECTURE.md, fem-solvers): each folder imports only the
// ones listed before it, and the root files below (`error`, `kernel`) import no folder.
pub mod contact;
mod error;
mod kernel;
pub mod model;
pub mod nd;
pub mod optim;
pub mod rigid;
pub mod steppers;
pub mod testing;

// Every module keeps the path it had before the folders: `fem_solvers::grab`,
// `fem_solvers::explicit`, ...
pub use contact::{ipc, pressure};
pub use model::{bc, diagnostics, grab, limits};
pub use optim::newton;
pub use steppers::{
    colour, explicit, implicit, integrator, linear_implicit, position_based, projective,
    quasi_newton, registry, statics, vbd,
};

pub use bc::{PrescribedMotion, Region};
pub use contact::{
    BodyState, Contact, ContactKind, ContactParams, Ground, ObstacleMotion, ObstacleMove,
};
pub use error::SolverError;
pub use explicit::{ExplicitParams, ExplicitScheme, ExplicitStepper};
pub use grab::{Grab, GrabModel};
pub use implicit::{ImplicitParams, ImplicitStepper};
pub use integrator::Integrator;
pub use linear_implicit::{LinearImplicitParams, LinearImplicitStepper};
pub use model::state::State;
pub use model::{Model, TimeStepCheck};
pub use newton::{LinearReport, LinearSolver, NewtonParams, NewtonReport};
pub use position_based::{
    LambdaReset, Ordering, PbdParams, PbdStepper, XpbdForm, XpbdParams, XpbdSchedule, XpbdStepper,
};
pub use pressure::{ContactPressure, PeakPressure};
pub use projective::{PdParams, PdStepper};
pub use quasi_newton::{QuasiNewtonParams, QuasiNewtonReport, QuasiNewtonStepper};
pub use registry::{
    AnyStepper, Capabilities, Clock, ParamsSerde, Solver, SolverKind, SolverParams,
    capability_table,
};
pub use rigid::{BodyMotion, RigidBody};
pub use statics::{StaticParams, StaticReport, StaticSolver, StaticStepper};
pub use steppers::Stepper;
pub use steppers::report::StepReport;
pub use vbd::{VbdInit, VbdParams, VbdStats, VbdStepper};

/// fem-core, the layer below, as this crate depends on it: `fem_solvers::fem_core::...` (and
/// nalgebra as `fem_solvers::fem_core::na`) needs no dependency of your own.
pub use fem_core;

/// The types most programs need, in one import: `use fem_solvers::prelude::*;`.
///
/// Everything of [`fem_core::prelude`] (materials, energies, the mesh, the rectangle
/// generator, `na`), the model and its boundary conditions, contact and grabs, the state,
/// the [`Stepper`] trait, every solver's stepper and parameters, the registry
/// ([`SolverKind`], [`SolverParams`], [`AnyStepper`]) and [`SolverError`].
pub mod prelude {
    pub use crate::{
        AnyStepper, BodyState, Clock, ContactParams, ExplicitParams, ExplicitScheme,
        ExplicitStepper, Grab, GrabModel, Ground, ImplicitParams, ImplicitStepper, Integrator,
        LinearImplicitParams, LinearImplicitStepper, LinearSolver, Model, NewtonParams,
        ObstacleMotion, PbdParams, PbdStepper, PdParams, PdStepper, PrescribedMotion,
        QuasiNewtonParams, QuasiNewtonStepper, Region, Solver, SolverError, SolverKind,
        SolverParams, State, StaticParams, StaticSolver, StaticStepper, StepReport, Stepper,
        VbdParams, VbdStepper, XpbdParams, XpbdStepper,
    };
    pub use fem_core::prelude::*;
}

// The README's example runs as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
