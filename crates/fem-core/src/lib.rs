//! # fem-core: energies, the linear triangle, assembly and stress for 2D elasticity
//!
//! The dependency-light layer of the framework: pick it to evaluate hyperelastic energies and
//! their derivatives, assemble forces and stiffness matrices on a triangle mesh, and compute
//! stresses, without a solver or a mesher.
//!
//! - [`material`]: Young's modulus, Poisson ratio, density; Lamé parameters (plane strain or
//!   plane stress).
//! - [`energy`]: the [`Energy`](energy::Energy) trait and five energies (`stvk`,
//!   `corotational`, `neo-hookean`, `stable-neo-hookean`, `linear`), each seeing only `F`.
//! - [`element`]: the Tri3 element (`Dm^-1`, rest area, chain rule from `P` to nodal forces).
//! - [`mesh`]: a validated mesh with rest data, adjacency and lumped masses; repeated
//!   triangles, edges of more than two triangles and overlapping triangles are refused.
//! - [`structured`]: the structured rectangle mesh (cases A-C), four diagonal patterns.
//! - [`partition`]: the chunking that makes the parallel scatter deterministic.
//! - [`assembly`]: energy, forces and stiffness; serial reference and bit-identical parallel
//!   paths.
//! - [`stress`]: Cauchy, von Mises (formula stated) and principal stresses.
//! - [`simd`]: the instruction set (baseline, AVX2, AVX-512) the batched kernels run under,
//!   picked at run time, with the same results on each.
//! - [`fd`]: the finite-difference oracle the tests use.
//!
//! Units are SI, per unit thickness. Notation (`F`, `P`, `J`, `psi`) follows continuum
//! mechanics; fourth-order tensors act on the column-major `vec(F)` ([`math`]).
//!
//! Features: `parallel` (default) runs the assembly on rayon's thread pool ([`par`]; off, the
//! same loops run in order, with the same bits); `serde` (de)serialises
//! [`EnergyKind`](energy::EnergyKind), [`PlaneModel`] and
//! [`Diagonal`](structured::Diagonal) as their names (`"neo-hookean"`, `"plane-strain"`), so
//! files and scenes name them as the command line does. [`prelude`] has the types most programs
//! need, [`na`] is the nalgebra this crate uses.
//!
//! What this crate does not know: time stepping, boundary conditions, contact, file formats
//! and meshing. Those live in `fem-solvers`, `fem-mesh` and `fem-cases`.
//!
//! ```
//! use fem_core::{assembly, energy::{EnergyKind, NeoHookean}, material::Material, mesh::Mesh, PlaneModel};
//! let mesh = Mesh::from_arrays(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], &[[0, 1, 2]]).unwrap();
//! let lame = Material::new(1000.0, 0.3, 1.0).unwrap().lame(PlaneModel::PlaneStrain);
//! let energy = NeoHookean::new(lame).unwrap();
//! // Stretch the element by 10% along x and read the nodal forces.
//! let x: Vec<_> = mesh.vertices().iter().map(|p| nalgebra::Vector2::new(1.1 * p.x, p.y)).collect();
//! let mut f = vec![nalgebra::Vector2::zeros(); 3];
//! let report = assembly::populate_forces_serial(&mesh, &energy, &x, &mut f);
//! assert!((report.min_det_f - 1.1).abs() < 1e-12);
//! assert!(f[1].x < 0.0); // the stretched vertex is pulled back
//! ```

pub mod assembly;
pub mod clock;
pub mod dim;
pub mod element;
pub mod energy;
pub mod fd;
pub mod material;
pub mod math;
pub mod mesh;
pub mod nodal_pressure;
mod overlap;
pub mod par;
pub mod partition;
pub mod polar;
pub mod simd;
pub mod simplex;
pub mod stress;
pub mod structured;

pub use material::{Lame, Material, MaterialError, PlaneModel};

/// The nalgebra this crate is built on (0.35): its `Vector2` is [`math::Vec2`]. Use it instead
/// of a nalgebra dependency of your own, so the versions cannot differ.
pub use nalgebra as na;

/// The types most programs need, in one import: `use fem_core::prelude::*;`.
///
/// The materials and Lamé parameters, the energies (trait, kinds and the five types), the mesh,
/// the rectangle generator, the von Mises formula, the scalar and vector types, and nalgebra
/// as `na`. Error types other than [`MaterialError`] and
/// [`EnergyError`](energy::EnergyError) stay in their modules: their names repeat in the
/// crates above (`fem_core::mesh::MeshError` is not `fem_mesh::MeshError`).
pub mod prelude {
    pub use crate::energy::{
        AnyEnergy, Corotational, Energy, EnergyError, EnergyKind, Linear, NeoHookean,
        StableNeoHookean, Stvk,
    };
    pub use crate::material::{Lame, Material, MaterialError, PlaneModel};
    pub use crate::math::{Mat2, Real, Vec2};
    pub use crate::mesh::Mesh;
    pub use crate::na;
    pub use crate::stress::VonMisesFormula;
    pub use crate::structured::{Diagonal, NodeOrder, RectangleParams, rectangle};
}

// The README's example runs as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
