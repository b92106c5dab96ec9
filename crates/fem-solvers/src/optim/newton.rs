//! Newton's method on a potential over the free degrees of freedom, shared by the implicit
//! Euler stepper and the quasi-static solver.
//!
//! The potential is `Phi(x) = w/2 |x - x_hat|_M^2 + Psi(x) - f . x` with `w = 1/h^2` for
//! implicit Euler (`x_hat` the inertial prediction) and `w = 0` for statics; `Psi` is the elastic
//! energy and `f` the external load (gravity and nodal forces). Kinematic vertices are held at
//! the positions the caller put in `x`; their rows and columns are removed from the system.
//!
//! Each iteration assembles the gradient and the Hessian `w M + K` with **per-element
//! PSD-projected** stiffness blocks (so the matrix is positive definite whenever the free
//! vertices are anchored or `w > 0`), factorises it with faer's sparse Cholesky and takes a
//! backtracking (Armijo) line search step. The symbolic analysis (fill-reducing ordering,
//! elimination tree, supernodes) is done once per solver and reused by every factorisation;
//! buffers are sized once. A trial state whose energy is not finite (an inverted element under an
//! energy that forbids inversion, such as Neo-Hookean's `log J`) is rejected by the line
//! search like any state that does not decrease the potential.
//!
//! The factorisation runs sequentially (`Par::Seq`) so that results are bit-identical for any
//! number of rayon threads; assembly is parallel and deterministic (fem-core).
//!
//! Each solve reports the wall time it spent in assembly, factorisation, triangular solves and
//! line search ([`NewtonReport`]), read from [`fem_core::clock`]: on `wasm32-unknown-unknown`,
//! which has no clock of its own, they read zero unless the host supplied one (the solve
//! itself is unchanged).
//!
//! Why faer rather than a hand-written solver: a supernodal sparse Cholesky with an AMD ordering
//! is the heart of the cost here, and faer's is well tested and fast.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use faer::{Conj, MatMut, Par, Side};
use fem_core::assembly::{
    Scratch, Stiffness, Tangent, elastic_energy, populate_forces, populate_stiffness,
};
use fem_core::energy::{ElementEnergies, Energy, EnergyOf};
use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;
use fem_core::nodal_pressure::NodalPressure;

use crate::contact::barrier::{BarrierContact, Dof};
use crate::error::{SolverError, check_at_most, check_count};
use crate::kernel::Inversion;
use crate::model::grab::{Spring, spring_energy, spring_of};
use crate::model::limits;
use crate::rigid::{BodyState, RigidBody};
use fem_core::clock::Stopwatch;

// The linearly implicit Euler step: one linear solve of this solver's system per step.
mod linear;
pub use linear::{LinearReport, LinearSolver};

/// The round-off floor of a gradient entry, in units in the last place of the coordinates
/// times its Hessian row (see `NewtonSolver::floors`): a force computed from positions off by
/// one ulp each is off by about one ulp times its row, and sums over a handful of elements and
/// the energy's own arithmetic add a few tens more; 100 leaves a margin without hiding a
/// residual a thousand times above the round-off.
pub(crate) const FLOOR_ULPS: Real = 100.0;
pub(crate) use linear::{LinearSettings, LinearWork};

/// Convergence and line-search settings of Newton's method.
///
/// With the `serde` feature the fields are read under their own names (`tolerance`,
/// `max_iterations`, `max_halvings`); the implicit and static parameters flatten them into
/// their own table.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct NewtonParams {
    /// Stop when the residual (the 2-norm of the free part of the gradient, N) falls below
    /// `tolerance` times the force scale (the largest of the first residual, the norm of the
    /// external load, the norm of the elastic forces on the free DOFs at the start, which at
    /// equilibrium balance the load and the contact forces, and 1e-12 N), dimensionless, in the
    /// open interval (0, 1). Default `1e-8`.
    pub tolerance: Real,
    /// Most Newton iterations per solve (>= 1). Default 50.
    pub max_iterations: usize,
    /// Most step halvings of the line search. Default 40.
    pub max_halvings: usize,
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams {
            tolerance: 1e-8,
            max_iterations: 50,
            max_halvings: 40,
        }
    }
}

impl NewtonParams {
    /// Check every field; errors name `<prefix>.tolerance` and `<prefix>.max_iterations`.
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(SolverError::invalid(
                format!("{prefix}.tolerance"),
                self.tolerance,
                "must lie in the open interval (0, 1) (relative to the force scale)",
            ));
        }
        check_count(
            &format!("{prefix}.max_iterations"),
            self.max_iterations,
            limits::MAX_NEWTON_ITERATIONS,
        )?;
        check_at_most(
            &format!("{prefix}.max_halvings"),
            self.max_halvings,
            limits::MAX_HALVINGS,
        )
    }
}

/// One free rigid body as Newton sees it.
#[derive(Clone, Debug)]
struct FreeBody {
    /// Its index in the model's rigid bodies.
    index: usize,
    mass: Real,
    inertia: Real,
    /// Its vertices and their rest offsets from the centroid.
    vertices: Vec<u32>,
    offsets: Vec<Vec2>,
}

/// The free rigid bodies of the rigid regions as Newton unknowns: three per body, its
/// centroid and angle `q = (p, theta)`, in reduced coordinates. A slaved vertex is
/// `x_v = p + R(theta) r_v`, so `d x_v / d q = J_v = [I | perp(x_v - p)]`: the gradient of the
/// potential in `q` is `sum_v J_v^T g_v` plus the body's inertia `w diag(M, M, I) (q - q_hat)`
/// (exact in 2D: a body's kinetic energy is `M |p'|^2 / 2 + I theta'^2 / 2`), and its Hessian
/// `J^T K J` plus that inertia and the rotation's curvature (see
/// `NewtonSolver::assemble_rigid`). The slaved vertices are held in the soft system; every
/// trial places them on the trial poses.
#[derive(Clone, Debug, Default)]
pub(crate) struct RigidUnknowns {
    bodies: Vec<FreeBody>,
    /// For each vertex, the free body it is slaved to (`u32::MAX`: none).
    of: Vec<u32>,
    /// The stiffness entries `(entry, row DOF, column DOF)` with a slaved row or column.
    entries: Vec<(u32, u32, u32)>,
    /// For each of `entries`, the slots in the reduced Hessian's values of its up to four
    /// products (row unknown `k`, column unknown `l`) at `2 k + l` (`u32::MAX`: none, or in the
    /// upper triangle): found once, when the pattern is built.
    entry_slots: Vec<[u32; 4]>,
    /// Free index of the first body's first unknown.
    first: usize,
    /// The current poses `(p_x, p_y, theta)`.
    pub(crate) q: Vec<[Real; 3]>,
    /// The inertial targets (implicit Euler: `q + h q'`; BDF2: [`RigidUnknowns::begin_towards`]).
    target: Vec<[Real; 3]>,
    /// The poses at the start of the step (the fallback start).
    pub(crate) start: Vec<[Real; 3]>,
    trial: Vec<[Real; 3]>,
}

impl RigidUnknowns {
    fn new(n_vertices: usize, bodies: &[RigidBody]) -> Self {
        let mut of = vec![u32::MAX; n_vertices];
        let mut free = Vec::new();
        for (index, body) in bodies.iter().enumerate() {
            if !body.is_free() {
                continue;
            }
            for &v in &body.vertices {
                of[v as usize] = free.len() as u32;
            }
            free.push(FreeBody {
                index,
                mass: body.mass,
                inertia: body.inertia,
                vertices: body.vertices.clone(),
                offsets: body.offsets.clone(),
            });
        }
        let n = free.len();
        RigidUnknowns {
            bodies: free,
            of,
            entries: Vec::new(),
            entry_slots: Vec::new(),
            first: 0,
            q: vec![[0.0; 3]; n],
            target: vec![[0.0; 3]; n],
            start: vec![[0.0; 3]; n],
            trial: vec![[0.0; 3]; n],
        }
    }

    /// Start a solve from the model's body states `states` (all bodies, the model's order):
    /// with a step `h`, the unknowns start at and aim for the inertial prediction
    /// `q + h q'`; without (statics), they start where the bodies are. The slaved vertices of
    /// `x` are placed on the starting poses.
    pub(crate) fn begin(&mut self, states: &[BodyState], h: Option<Real>, x: &mut [Vec2]) {
        for (k, body) in self.bodies.iter().enumerate() {
            let b = &states[body.index];
            self.start[k] = [b.position.x, b.position.y, b.angle];
            self.q[k] = match h {
                Some(h) => [
                    b.position.x + h * b.velocity.x,
                    b.position.y + h * b.velocity.y,
                    b.angle + h * b.angular_velocity,
                ],
                None => self.start[k],
            };
            self.target[k] = self.q[k];
        }
        let q = std::mem::take(&mut self.q);
        self.place(&q, x);
        self.q = q;
    }

    /// As [`RigidUnknowns::begin`] with a step, but towards the given inertial targets
    /// `targets` (one pose `(p_x, p_y, theta)` per body of the model, the model's order; BDF2's
    /// prediction): the unknowns start at and aim for them.
    pub(crate) fn begin_towards(
        &mut self,
        states: &[BodyState],
        targets: &[[Real; 3]],
        x: &mut [Vec2],
    ) {
        for (k, body) in self.bodies.iter().enumerate() {
            let b = &states[body.index];
            self.start[k] = [b.position.x, b.position.y, b.angle];
            self.q[k] = targets[body.index];
            self.target[k] = self.q[k];
        }
        let q = std::mem::take(&mut self.q);
        self.place(&q, x);
        self.q = q;
    }

    /// Place the slaved vertices on poses `q`.
    pub(crate) fn place(&self, q: &[[Real; 3]], x: &mut [Vec2]) {
        for (body, q) in self.bodies.iter().zip(q) {
            let (s, c) = fem_core::math::sin_cos(q[2]);
            for (&v, r) in body.vertices.iter().zip(&body.offsets) {
                x[v as usize] = Vec2::new(q[0] + c * r.x - s * r.y, q[1] + s * r.x + c * r.y);
            }
        }
    }

    /// The solved poses written into the model's body states `states` (positions only).
    pub(crate) fn poses(&self) -> impl Iterator<Item = (usize, [Real; 3])> + '_ {
        self.bodies.iter().zip(&self.q).map(|(b, q)| (b.index, *q))
    }

    /// The body inertia `w/2 sum (M |p - p_hat|^2 + I (theta - theta_hat)^2)` at poses `q`.
    pub(crate) fn inertia(&self, weight: Real, q: &[[Real; 3]]) -> Real {
        if weight == 0.0 {
            return 0.0;
        }
        (self.bodies.iter().zip(q).zip(&self.target))
            .map(|((b, q), t)| {
                let (dx, dy, da) = (q[0] - t[0], q[1] - t[1], q[2] - t[2]);
                0.5 * weight * (b.mass * (dx * dx + dy * dy) + b.inertia * da * da)
            })
            .sum()
    }
}

/// Rewrites the unknowns to a safe starting point (see [`NewtonSolver::minimise`]).
pub(crate) type Restart<'a> = &'a dyn Fn(&mut [Vec2]);

/// What one Newton solve did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NewtonReport {
    /// Iterations (linear solves) taken.
    pub iterations: usize,
    /// Residual after each iteration, N, starting with the initial one.
    pub residuals: Vec<Real>,
    /// The potential after each iteration, J, starting with the initial one.
    pub potentials: Vec<Real>,
    /// Whether the residual met the tolerance.
    pub converged: bool,
    /// Smallest `det F` at the solution.
    pub min_det_f: Real,
    /// Inverted elements at the solution.
    pub inverted: usize,
    /// Wall time of gradient and Hessian assembly (forces, stiffness, reduction), s. This and
    /// the three times below read zero on `wasm32-unknown-unknown` unless the host supplied a
    /// clock ([`fem_core::clock::set_clock`]).
    pub assembly_seconds: Real,
    /// Wall time of the numeric Cholesky factorisations, s.
    pub factorisation_seconds: Real,
    /// Wall time of the triangular solves, s.
    pub solve_seconds: Real,
    /// Wall time of the line searches (potential evaluations), s.
    pub line_search_seconds: Real,
}

/// The reduced Hessian (free degrees of freedom only, lower triangle, compressed columns),
/// its symbolic factorisation and the buffers of every Newton iteration.
pub(crate) struct NewtonSolver {
    /// Field prefix of error messages (`implicit`, `static`).
    prefix: &'static str,
    /// Free-DOF index of each of the `2 n_vertices` DOFs, or `u32::MAX` when kinematic.
    free: Vec<u32>,
    /// Free DOFs: the soft ones, then `n_extra` extra ones (moving obstacles' poses).
    n_free: usize,
    /// Free soft DOFs (the extra ones follow them).
    n_soft: usize,
    /// The extra unknowns' line-search direction and the obstacles' trial poses.
    trial_q: Vec<[Real; 3]>,
    /// Free rigid bodies as unknowns, after the contact's extra unknowns.
    rigid: RigidUnknowns,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<Real>,
    /// For each entry of the full stiffness CSR, its slot in `values` (or `u32::MAX`).
    map: Vec<u32>,
    /// Slot of each free DOF's diagonal entry in `values`.
    diag: Vec<usize>,
    /// The factorisation's order: free unknown `i` is row and column `position[i]` of the
    /// matrix as stored (`col_ptr`, `row_idx`, `values`, `map`, `diag`: all in that order).
    position: Vec<usize>,
    /// The right-hand side in the factorisation's order.
    permuted: Vec<Real>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<Real>,
    mem: MemBuffer,
    stiffness: Stiffness,
    scratch: Scratch,
    forces: Vec<Vec2>,
    /// The 2-norm of the elastic forces on the free DOFs at the last gradient, N.
    elastic_force: Real,
    gradient: Vec<Real>,
    direction: Vec<Real>,
    trial: Vec<Vec2>,
    /// Each free unknown's round-off floor of the gradient, N (see [`Self::floors`]), from the
    /// last assembled Hessian.
    floor: Vec<Real>,
    /// The stored matrix's absolute row sums, in the factorisation's order (scratch).
    row_sums: Vec<Real>,
}

impl std::fmt::Debug for NewtonSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NewtonSolver")
            .field("free_dofs", &self.n_free)
            .field("hessian_entries", &self.values.len())
            .field("factor_entries", &self.l_values.len())
            .finish_non_exhaustive()
    }
}

/// The inputs of one solve that do not change during it.
pub(crate) struct Potential<'a, E: Energy> {
    pub mesh: &'a Mesh,
    pub energy: &'a ElementEnergies<E>,
    pub masses: &'a [Real],
    /// Inertia weight `1/h^2` (BDF2: `9/(4 h^2)`; 0 for statics).
    pub weight: Real,
    /// The inertial target `x_hat` (ignored when `weight == 0`).
    pub target: &'a [Vec2],
    /// External load per vertex, N (gravity included).
    pub load: &'a [Vec2],
    /// The springs of a spring grab (`k/2 |x - goal|^2` each).
    pub springs: &'a [Spring],
}

impl<E: Energy> Potential<'_, E> {
    /// The potential and the sum of its terms' magnitudes (the scale of its round-off).
    pub(crate) fn value(&self, x: &[Vec2], scratch: &mut Scratch) -> (Real, Real) {
        let elastic = elastic_energy(self.mesh, self.energy, x, scratch);
        let mut rest = 0.0;
        let mut magnitude = elastic.abs();
        // The load's work is measured from the rest positions: the same minimiser, without a
        // large constant that would swamp the line search's comparisons in round-off.
        for ((i, p), x0) in x.iter().enumerate().zip(self.mesh.vertices()) {
            if self.weight > 0.0 {
                let inertia =
                    0.5 * self.weight * self.masses[i] * (p - self.target[i]).norm_squared();
                rest += inertia;
                magnitude += inertia;
            }
            let work = self.load[i].dot(&(p - x0));
            rest -= work;
            magnitude += work.abs();
        }
        let springs = spring_energy(self.springs, x);
        (elastic + rest + springs, magnitude + springs)
    }
}

impl NewtonSolver {
    /// Build the reduced pattern for `mesh` with the vertices `kinematic` held (sorted,
    /// deduplicated), and analyse it symbolically; with `n_extra` more unknowns (always free)
    /// that may couple with each other and with the soft vertices `coupled` (sorted): the poses of moving
    /// obstacles in barrier contact; then three unknowns per body of `rigid` (the model's
    /// free rigid bodies, whose vertices must be in `kinematic`): see [`RigidUnknowns`].
    pub(crate) fn with_extra(
        mesh: &Mesh,
        pressure: Option<&NodalPressure>,
        kinematic: &[usize],
        prefix: &'static str,
        n_extra: usize,
        coupled: &[u32],
        rigid: &[RigidBody],
    ) -> Result<Self, SolverError> {
        let self_prefix = prefix;
        // The averaged nodal pressure triangle couples every vertex of a node's patch.
        let stiffness = match pressure {
            Some(np) => Stiffness::with_nodal_pressure(mesh, np),
            None => Stiffness::new(mesh),
        };
        let n_contact = n_extra;
        let mut rigid = RigidUnknowns::new(mesh.n_vertices(), rigid);
        let n_extra = n_contact + 3 * rigid.bodies.len();
        // The soft vertices that share an element with a body's vertex couple with that
        // body's three unknowns (`touch`, sorted per vertex); the extra unknowns' own block is
        // dense (a few unknowns).
        let mut touch: Vec<Vec<u32>> = vec![Vec::new(); mesh.n_vertices()];
        if !rigid.bodies.is_empty() {
            let m = &stiffness.matrix;
            for r in 0..m.row_offsets.len() - 1 {
                if rigid.of[r / 2] == u32::MAX {
                    continue;
                }
                for e in m.row_offsets[r]..m.row_offsets[r + 1] {
                    let c = m.col_indices[e];
                    if rigid.of[c / 2] == u32::MAX {
                        touch[c / 2].push(rigid.of[r / 2]);
                    }
                    rigid.entries.push((e as u32, r as u32, c as u32));
                }
            }
            // The entries of a soft row in a body's column, too (the matrix is symmetric:
            // the same pairs, seen from the other side).
            let extra: Vec<(u32, u32, u32)> = (0..m.row_offsets.len() - 1)
                .filter(|r| rigid.of[r / 2] == u32::MAX)
                .flat_map(|r| {
                    (m.row_offsets[r]..m.row_offsets[r + 1])
                        .filter(|&e| rigid.of[m.col_indices[e] / 2] != u32::MAX)
                        .map(move |e| (e as u32, r as u32, m.col_indices[e] as u32))
                })
                .collect();
            rigid.entries.extend(extra);
            for t in &mut touch {
                t.sort_unstable();
                t.dedup();
            }
        }
        let n_dof = 2 * mesh.n_vertices();
        let mut free = vec![0u32; n_dof];
        let mut n_free = 0usize;
        let mut k = 0;
        for v in 0..mesh.n_vertices() {
            let held = k < kinematic.len() && kinematic[k] == v;
            if held {
                k += 1;
            }
            for d in 0..2 {
                free[2 * v + d] = if held {
                    u32::MAX
                } else {
                    n_free += 1;
                    (n_free - 1) as u32
                };
            }
        }
        let n_soft = n_free;
        if n_free == 0 {
            return Err(SolverError::invalid(
                format!("{prefix}.kinematics"),
                "every vertex",
                "an implicit or static solve needs at least one free vertex",
            ));
        }
        // Lower triangle in compressed columns: column j of the reduced matrix is free DOF j,
        // rows i >= j. The full matrix is symmetric, so the CSR row of DOF r read as a column
        // gives the column's rows; free indices increase with DOF indices, so rows stay sorted.
        let m = &stiffness.matrix;
        let mut col_ptr = Vec::with_capacity(n_free + 1);
        let mut row_idx = Vec::new();
        let mut map = vec![u32::MAX; m.values.len()];
        let mut diag = vec![0usize; n_free];
        col_ptr.push(0);
        for r in 0..n_dof {
            let j = free[r];
            if j == u32::MAX {
                continue;
            }
            for e in m.row_offsets[r]..m.row_offsets[r + 1] {
                let i = free[m.col_indices[e]];
                if i != u32::MAX && i >= j {
                    if i == j {
                        diag[j as usize] = row_idx.len();
                    }
                    map[e] = row_idx.len() as u32;
                    row_idx.push(i as usize);
                }
            }
            // Rows of the extra unknowns (after every soft row) for coupled vertices: every
            // contact unknown, and the unknowns of the bodies the vertex touches.
            if n_contact > 0 && coupled.binary_search(&((r / 2) as u32)).is_ok() {
                row_idx.extend(n_soft..n_soft + n_contact);
            }
            for &b in &touch[r / 2] {
                let base = n_soft + n_contact + 3 * b as usize;
                row_idx.extend(base..base + 3);
            }
            col_ptr.push(row_idx.len());
        }
        // The extra unknowns' own columns: dense lower triangle.
        for j in n_soft..n_soft + n_extra {
            diag.push(row_idx.len());
            row_idx.extend(j..n_soft + n_extra);
            col_ptr.push(row_idx.len());
        }
        let n_free = n_soft + n_extra;
        let values = vec![0.0; row_idx.len()];
        let analyse = |col_ptr: &[usize], row_idx: &[usize], side, ordering| {
            let pattern =
                SymbolicSparseColMatRef::new_checked(n_free, n_free, col_ptr, None, row_idx);
            factorize_symbolic_cholesky(pattern, side, ordering, CholeskySymbolicParams::default())
                .map_err(|e| {
                    SolverError::invalid(
                        format!("{}.factorisation", self_prefix),
                        format!("{e:?}"),
                        "symbolic analysis failed",
                    )
                })
        };
        // The fill-reducing ordering (AMD), applied once to the pattern itself, which is
        // stored as the upper triangle (what faer's simplicial factorisation reads): the matrix
        // is assembled directly in that order and layout, so no factorisation has to permute
        // or transpose it (about a fifth of a numeric factorisation at case D's size).
        let amd = analyse(&col_ptr, &row_idx, Side::Lower, SymmetricOrdering::Amd)?;
        let position: Vec<usize> = match amd.perm() {
            Some(perm) => {
                let (_, inverse) = perm.arrays();
                inverse.to_vec()
            }
            None => (0..n_free).collect(),
        };
        let (col_ptr, row_idx, moved) = permute_to_upper(&col_ptr, &row_idx, &position);
        for slot in map.iter_mut().filter(|s| **s != u32::MAX) {
            *slot = moved[*slot as usize] as u32;
        }
        for slot in &mut diag {
            *slot = moved[*slot];
        }
        let symbolic = analyse(&col_ptr, &row_idx, Side::Upper, SymmetricOrdering::Identity)?;
        debug_assert_eq!(symbolic.len_val(), amd.len_val());
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<Real>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<Real>(1, Par::Seq),
        ]);
        let mem = MemBuffer::try_new(req).map_err(|_| {
            SolverError::invalid(
                format!("{}.factorisation", self_prefix),
                n_free,
                "out of memory for the workspace",
            )
        })?;
        rigid.first = n_soft + n_contact;
        let mut solver = NewtonSolver {
            n_soft,
            trial_q: Vec::new(),
            rigid,
            prefix,
            l_values: vec![0.0; symbolic.len_val()],
            symbolic,
            permuted: vec![0.0; n_free],
            position,
            mem,
            free,
            n_free,
            col_ptr,
            row_idx,
            values,
            map,
            diag,
            stiffness,
            scratch: Scratch::new(),
            forces: vec![Vec2::zeros(); mesh.n_vertices()],
            elastic_force: 0.0,
            gradient: vec![0.0; n_free],
            direction: vec![0.0; n_free],
            trial: vec![Vec2::zeros(); mesh.n_vertices()],
            floor: vec![0.0; n_free],
            row_sums: vec![0.0; n_free],
        };
        let slots: Vec<[u32; 4]> = (solver.rigid.entries.iter())
            .map(|&(_, r, c)| {
                let (a, na) = solver.reduced(r as usize);
                let (b, nb) = solver.reduced(c as usize);
                let mut out = [u32::MAX; 4];
                for k in 0..na {
                    for l in 0..nb {
                        if a[k] >= b[l] {
                            let slot = solver
                                .slot(a[k], b[l])
                                .expect("a body's entry outside the pattern");
                            out[2 * k + l] = slot as u32;
                        }
                    }
                }
                out
            })
            .collect();
        solver.rigid.entry_slots = slots;
        Ok(solver)
    }

    /// The reduced unknowns one full DOF `r` moves: none (held), its own free index, or a
    /// body's translation along its axis and the body's angle (in that order).
    fn reduced(&self, r: usize) -> ([usize; 2], usize) {
        let b = self.rigid.of[r / 2];
        if b == u32::MAX {
            return match self.free[r] {
                u32::MAX => ([0; 2], 0),
                j => ([j as usize, 0], 1),
            };
        }
        let base = self.rigid.first + 3 * b as usize;
        ([base + r % 2, base + 2], 2)
    }

    /// The free rigid bodies' unknowns (start a solve with [`RigidUnknowns::begin`], read
    /// the result with [`RigidUnknowns::poses`]).
    pub(crate) fn rigid(&mut self) -> &mut RigidUnknowns {
        &mut self.rigid
    }

    /// Free degrees of freedom.
    pub(crate) fn n_free(&self) -> usize {
        self.n_free
    }

    /// The gradient of the last [`NewtonSolver::gradient`] over the free degrees of freedom:
    /// the soft ones (`2 k + d` for the `k`-th free vertex), the contact's extra ones, the
    /// free rigid bodies' (three each).
    pub(crate) fn last_gradient(&self) -> &[Real] {
        &self.gradient
    }

    /// The 2-norm of the elastic forces on the free degrees of freedom (a free body's: on its
    /// vertices) at the last [`NewtonSolver::gradient`], N.
    pub(crate) fn elastic_force(&self) -> Real {
        self.elastic_force
    }

    /// The free index of a contact term's degree of freedom (`None`: held).
    #[inline]
    fn free_of(&self, d: Dof) -> Option<usize> {
        match d {
            Dof::Soft(i) => {
                let j = self.free[i];
                (j != u32::MAX).then_some(j as usize)
            }
            Dof::Extra(k) => Some(self.n_soft + k),
        }
    }

    /// The slot of free entry `(i, j)` (either order) in `values`.
    #[inline]
    fn slot(&self, i: usize, j: usize) -> Option<usize> {
        let (i, j) = (self.position[i], self.position[j]);
        let (r, c) = (i.min(j), i.max(j));
        let rows = &self.row_idx[self.col_ptr[c]..self.col_ptr[c + 1]];
        rows.binary_search(&r).ok().map(|k| self.col_ptr[c] + k)
    }

    /// Gradient of the potential (with the contact term at the poses `q`, when there is one,
    /// and the free rigid bodies at poses `rq`) over the free DOFs into `self.gradient`
    /// ([`NewtonSolver::last_gradient`]); returns its norm.
    pub(crate) fn gradient<E: Energy>(
        &mut self,
        p: &Potential<'_, E>,
        x: &[Vec2],
        contact: Option<(&BarrierContact, &[[Real; 3]])>,
        (rigid, rq): (&RigidUnknowns, &[[Real; 3]]),
    ) -> Real {
        populate_forces(p.mesh, p.energy, x, &mut self.forces, &mut self.scratch);
        let mut elastic_sq = 0.0;
        for (v, f) in self.forces.iter().enumerate() {
            for d in 0..2 {
                if self.free[2 * v + d] != u32::MAX {
                    elastic_sq += f[d] * f[d];
                }
            }
        }
        self.elastic_force = elastic_sq.sqrt();
        self.gradient[self.n_soft..].fill(0.0);
        if !rigid.bodies.is_empty() {
            // A slaved vertex's force and load reach its body through `J^T`; its inertia is
            // the body's.
            let first = rigid.first;
            for (k, (body, q)) in rigid.bodies.iter().zip(rq).enumerate() {
                let (mut g, mut force_sq) = ([0.0; 3], 0.0);
                for &v in &body.vertices {
                    let v = v as usize;
                    let gv = -self.forces[v] - p.load[v];
                    let r = x[v] - Vec2::new(q[0], q[1]);
                    g[0] += gv.x;
                    g[1] += gv.y;
                    g[2] += r.x * gv.y - r.y * gv.x;
                    force_sq += self.forces[v].norm_squared();
                }
                if p.weight > 0.0 {
                    let t = &rigid.target[k];
                    g[0] += p.weight * body.mass * (q[0] - t[0]);
                    g[1] += p.weight * body.mass * (q[1] - t[1]);
                    g[2] += p.weight * body.inertia * (q[2] - t[2]);
                }
                self.gradient[first + 3 * k..first + 3 * k + 3].copy_from_slice(&g);
                elastic_sq += force_sq;
            }
            self.elastic_force = elastic_sq.sqrt();
        }
        if let Some((c, q)) = contact {
            let n_soft = self.n_soft;
            let (forces, gradient) = (&mut self.forces, &mut self.gradient);
            c.derivatives(
                x,
                q,
                &mut |d, g| match d {
                    // As a force: the soft part joins the elastic forces below.
                    Dof::Soft(i) => forces[i / 2][i % 2] -= g,
                    Dof::Extra(k) => gradient[n_soft + k] += g,
                },
                None,
            );
        }
        let mut sq: Real = self.gradient[self.n_soft..].iter().map(|g| g * g).sum();
        for (v, xv) in x.iter().enumerate() {
            let mut g = -self.forces[v] - p.load[v];
            if p.weight > 0.0 {
                g += p.weight * p.masses[v] * (xv - p.target[v]);
            }
            if let Some(s) = spring_of(p.springs, v) {
                g += (xv - s.goal) * s.stiffness;
            }
            for d in 0..2 {
                let j = self.free[2 * v + d];
                if j != u32::MAX {
                    self.gradient[j as usize] = g[d];
                    sq += g[d] * g[d];
                }
            }
        }
        sq.sqrt()
    }

    /// Assemble `w M + K_projected` over the free DOFs and factorise it. A matrix that is not
    /// numerically positive definite (possible in statics when the free vertices are not
    /// anchored) is retried with a growing diagonal shift.
    fn factorise<E: Energy>(
        &mut self,
        p: &Potential<'_, E>,
        x: &[Vec2],
        contact: Option<(&BarrierContact, &[[Real; 3]])>,
        (rigid, rq): (&RigidUnknowns, &[[Real; 3]]),
        report: &mut NewtonReport,
    ) -> Result<(), SolverError> {
        let start = Stopwatch::start();
        self.assemble(p, x, contact, (rigid, rq));
        self.floors(x);
        report.assembly_seconds += start.seconds();
        self.factorise_assembled(report)
    }

    /// Each free unknown's round-off floor from the assembled Hessian `H` at `x`:
    /// `FLOOR_ULPS eps X sum_k |H_jk|`, with `X` the largest coordinate magnitude (at least the
    /// body's size). Positions are absolute coordinates, so each one carries a round-off of
    /// `eps X`, and a gradient entry computed from them one of about `eps X` times its row of
    /// `H` (its stiffness, inertia, springs and barriers, whatever their scale): below it, a
    /// residual is as small as double precision can make it. The floors are per unknown, so a
    /// stiff region's (a bone 1e11 times stiffer than the tissue) raises only its own.
    fn floors(&mut self, x: &[Vec2]) {
        let coordinate = x
            .iter()
            .fold(0.0, |m: Real, p| m.max(p.x.abs()).max(p.y.abs()))
            .max(body_size(x));
        self.row_sums.fill(0.0);
        for j in 0..self.n_free {
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                let (i, v) = (self.row_idx[k], self.values[k].abs());
                self.row_sums[i] += v;
                if i != j {
                    self.row_sums[j] += v;
                }
            }
        }
        let unit = FLOOR_ULPS * Real::EPSILON * coordinate;
        for (f, &k) in self.floor.iter_mut().zip(&self.position) {
            *f = unit * self.row_sums[k];
        }
    }

    /// The load on the free unknowns (the external load, the springs' pull towards their goals
    /// and a rigid body's share of its vertices' load) at `x`: its 2-norm and the 2-norm of
    /// its part above the round-off floors (`floors` at `x` first).
    fn load_above_floor<E: Energy>(
        &self,
        p: &Potential<'_, E>,
        x: &[Vec2],
        (rigid, rq): (&RigidUnknowns, &[[Real; 3]]),
    ) -> (Real, Real) {
        let (mut norm, mut above) = (0.0, 0.0);
        let mut add = |load: Real, floor: Real| {
            norm += load * load;
            above += (load.abs() - floor).max(0.0).powi(2);
        };
        for (v, xv) in x.iter().enumerate() {
            let mut f = p.load[v];
            if let Some(s) = spring_of(p.springs, v) {
                f += (s.goal - xv) * s.stiffness;
            }
            for d in 0..2 {
                let j = self.free[2 * v + d];
                if j != u32::MAX {
                    add(f[d], self.floor[j as usize]);
                }
            }
        }
        for (k, (body, q)) in rigid.bodies.iter().zip(rq).enumerate() {
            let (mut f, mut torque) = (Vec2::zeros(), 0.0);
            for &v in &body.vertices {
                let v = v as usize;
                let r = x[v] - Vec2::new(q[0], q[1]);
                f += p.load[v];
                torque += r.x * p.load[v].y - r.y * p.load[v].x;
            }
            let j = rigid.first + 3 * k;
            add(f.x, self.floor[j]);
            add(f.y, self.floor[j + 1]);
            add(torque, self.floor[j + 2]);
        }
        (norm.sqrt(), above.sqrt())
    }

    /// The part of `g` (one entry per free unknown) above the round-off floors, 2-norm:
    /// `sqrt(sum_j max(|g_j| - floor_j, 0)^2)`.
    fn above_floor(&self, g: &[Real]) -> Real {
        (g.iter().zip(&self.floor))
            .map(|(g, f)| (g.abs() - f).max(0.0).powi(2))
            .sum::<Real>()
            .sqrt()
    }

    /// Assemble `w M + K_projected` over the free DOFs into `self.values` (`self.forces` holds
    /// the forces of the last gradient, at `x`).
    fn assemble<E: Energy>(
        &mut self,
        p: &Potential<'_, E>,
        x: &[Vec2],
        contact: Option<(&BarrierContact, &[[Real; 3]])>,
        (rigid, rq): (&RigidUnknowns, &[[Real; 3]]),
    ) {
        populate_stiffness(
            p.mesh,
            p.energy,
            x,
            Tangent::Projected,
            &mut self.stiffness,
            &mut self.scratch,
        );
        self.values.fill(0.0);
        for (e, &slot) in self.map.iter().enumerate() {
            if slot != u32::MAX {
                self.values[slot as usize] += self.stiffness.matrix.values[e];
            }
        }
        if p.weight > 0.0 {
            for v in 0..p.mesh.n_vertices() {
                for d in 0..2 {
                    let j = self.free[2 * v + d];
                    if j != u32::MAX {
                        self.values[self.diag[j as usize]] += p.weight * p.masses[v];
                    }
                }
            }
        }
        for s in p.springs {
            for d in 0..2 {
                let j = self.free[2 * s.vertex as usize + d];
                if j != u32::MAX {
                    self.values[self.diag[j as usize]] += s.stiffness;
                }
            }
        }
        if !rigid.bodies.is_empty() {
            self.assemble_rigid(p, x, rigid, rq);
        }
        if let Some((c, q)) = contact {
            let mut values = std::mem::take(&mut self.values);
            c.derivatives(
                x,
                q,
                &mut |_, _| {},
                Some(&mut |a, b, v| {
                    // Each unordered pair arrives twice (as (a, b) and (b, a)); the lower
                    // triangle takes one of them, the diagonal both halves.
                    if let (Some(i), Some(j)) = (self.free_of(a), self.free_of(b))
                        && i >= j
                    {
                        let slot = self
                            .slot(i, j)
                            .expect("contact couples degrees of freedom outside the pattern");
                        values[slot] += v;
                    }
                }),
            );
            self.values = values;
        }
    }

    /// Factorise the assembled matrix, retried with a growing diagonal shift when it is not
    /// numerically positive definite.
    fn factorise_assembled(&mut self, report: &mut NewtonReport) -> Result<(), SolverError> {
        let scale = self
            .diag
            .iter()
            .map(|&s| self.values[s].abs())
            .fold(0.0, Real::max)
            .max(Real::MIN_POSITIVE);
        let start = Stopwatch::start();
        let mut shift = 0.0;
        for attempt in 0..8 {
            if attempt > 0 {
                let add = if shift == 0.0 {
                    1e-10 * scale
                } else {
                    9.0 * shift
                };
                for &s in &self.diag {
                    self.values[s] += add;
                }
                shift += add;
            }
            let pattern = SymbolicSparseColMatRef::new_checked(
                self.n_free,
                self.n_free,
                &self.col_ptr,
                None,
                &self.row_idx,
            );
            let a = SparseColMatRef::new(pattern, &self.values);
            let ok = self
                .symbolic
                .factorize_numeric_llt::<Real>(
                    &mut self.l_values,
                    a,
                    Side::Upper,
                    LltRegularization {
                        dynamic_regularization_delta: 0.0,
                        dynamic_regularization_epsilon: 0.0,
                    },
                    Par::Seq,
                    MemStack::new(&mut self.mem),
                    Default::default(),
                )
                .is_ok();
            if ok {
                report.factorisation_seconds += start.seconds();
                return Ok(());
            }
        }
        Err(SolverError::invalid(
            format!("{}.hessian", self.prefix),
            format!("shift {shift:e}"),
            "is not positive definite even with a diagonal shift (is the body anchored?)",
        ))
    }

    /// The rigid bodies' part of the reduced Hessian `J^T K J` (the stiffness entries that
    /// touch a slaved vertex, `K` already in `self.stiffness`), their inertia `w diag(M, M, I)`
    /// and the rotation's own curvature `-sum_v g_v . (x_v - p)` (the second derivative of
    /// `x_v` in the angle), kept only where positive so the matrix stays positive definite.
    /// `self.forces` holds the elastic forces at `x` (the gradient was evaluated there).
    fn assemble_rigid<E: Energy>(
        &mut self,
        p: &Potential<'_, E>,
        x: &[Vec2],
        rigid: &RigidUnknowns,
        rq: &[[Real; 3]],
    ) {
        let first = rigid.first;
        // The coefficients of one full DOF's reduced unknowns (see `reduced`): 1 for a soft
        // DOF; 1 and `d x_v / d angle = perp(x_v - p) = (-r_y, r_x)` for a slaved one.
        let coefficients = |r: usize| -> [Real; 2] {
            let v = r / 2;
            let b = rigid.of[v];
            if b == u32::MAX {
                return [1.0, 0.0];
            }
            let q = &rq[b as usize];
            let rel = x[v] - Vec2::new(q[0], q[1]);
            [1.0, if r.is_multiple_of(2) { -rel.y } else { rel.x }]
        };
        let mut values = std::mem::take(&mut self.values);
        for (&(e, r, col), slots) in rigid.entries.iter().zip(&rigid.entry_slots) {
            let k = self.stiffness.matrix.values[e as usize];
            if k == 0.0 {
                continue;
            }
            let a = coefficients(r as usize);
            let c = coefficients(col as usize);
            for (n, &slot) in slots.iter().enumerate() {
                if slot != u32::MAX {
                    values[slot as usize] += a[n / 2] * k * c[n % 2];
                }
            }
        }
        for (b, (body, q)) in rigid.bodies.iter().zip(rq).enumerate() {
            let base = first + 3 * b;
            let mut curvature = 0.0;
            for &v in &body.vertices {
                let v = v as usize;
                let gv = -self.forces[v] - p.load[v];
                curvature -= gv.dot(&(x[v] - Vec2::new(q[0], q[1])));
            }
            let d = |i: usize| self.diag[i];
            values[d(base + 2)] += curvature.max(0.0);
            if p.weight > 0.0 {
                values[d(base)] += p.weight * body.mass;
                values[d(base + 1)] += p.weight * body.mass;
                values[d(base + 2)] += p.weight * body.inertia;
            }
        }
        self.values = values;
    }

    /// Solve `H d = -g` with the last factorisation into `self.direction`.
    fn solve(&mut self) {
        for (&k, g) in self.position.iter().zip(&self.gradient) {
            self.permuted[k] = -g;
        }
        let llt = LltRef::<'_, usize, Real>::new(&self.symbolic, &self.l_values);
        let rhs = MatMut::from_column_major_slice_mut(&mut self.permuted, self.n_free, 1);
        llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut self.mem));
        for (&k, d) in self.position.iter().zip(&mut self.direction) {
            *d = self.permuted[k];
        }
    }

    /// Minimise the potential from `x` (kinematic vertices already placed), in place. When the
    /// potential is not finite at `x` (an inverted element under an energy that forbids it),
    /// `fallback` rewrites `x` to a safe start before giving up. With `contact`, its barrier,
    /// friction and moving obstacles join the potential (its poses `q` are unknowns too, and
    /// `x` must be free of contact: every candidate pair apart), and every line search starts
    /// at the largest step the CCD allows.
    ///
    /// With `step_tolerance > 0` (m) a solve also stops after a full Newton step (the line
    /// search accepted `alpha = 1`) that moved no vertex by more than `step_tolerance`: Newton
    /// converges quadratically there, so the iterate is within about that distance of the
    /// minimiser (implicit Euler's `velocity_tolerance` times the step).
    pub(crate) fn minimise<E: Energy>(
        &mut self,
        p: &Potential<'_, E>,
        x: &mut [Vec2],
        params: &NewtonParams,
        step_tolerance: Real,
        fallback: Option<Restart<'_>>,
        mut contact: Option<&mut BarrierContact>,
    ) -> Result<NewtonReport, SolverError> {
        let mut report = NewtonReport::default();
        let mut trial_q = std::mem::take(&mut self.trial_q);
        let mut rq = std::mem::take(&mut self.rigid.q);
        let mut rtrial = std::mem::take(&mut self.rigid.trial);
        let rigid = std::mem::take(&mut self.rigid);
        // The slaved vertices sit on the starting poses.
        rigid.place(&rq, x);
        let value = |x: &[Vec2],
                     q: Option<(&BarrierContact, &[[Real; 3]])>,
                     rq: &[[Real; 3]],
                     s: &mut Scratch| {
            let (e, m) = p.value(x, s);
            let inertia = rigid.inertia(p.weight, rq);
            let (e, m) = (e + inertia, m + inertia);
            match q {
                Some((c, q)) => {
                    let (ce, cm) = c.value(x, q);
                    (e + ce, m + cm)
                }
                None => (e, m),
            }
        };
        if let Some(c) = contact.as_deref_mut() {
            c.prepare(x, None);
        }
        let (mut phi, mut magnitude) = value(
            x,
            contact.as_deref().map(|c| (c, &c.q[..])),
            &rq,
            &mut self.scratch,
        );
        if let (false, Some(restart)) = (phi.is_finite(), fallback) {
            restart(x);
            rq.clone_from(&rigid.start);
            rigid.place(&rq, x);
            if let Some(c) = contact.as_deref_mut() {
                c.prepare(x, None);
            }
            (phi, magnitude) = value(
                x,
                contact.as_deref().map(|c| (c, &c.q[..])),
                &rq,
                &mut self.scratch,
            );
        }
        if !phi.is_finite() {
            self.trial_q = trial_q;
            self.rigid = RigidUnknowns {
                q: rq,
                trial: rtrial,
                ..rigid
            };
            let cause = start_cause(p, x, contact.as_deref());
            return Err(SolverError::invalid(
                format!("{}.initial_guess", self.prefix),
                phi,
                format!("the potential is not finite at the starting positions: {cause}"),
            ));
        }
        let mut residual = self.gradient(
            p,
            x,
            contact.as_deref().map(|c| (c, &c.q[..])),
            (&rigid, &rq),
        );
        // The force scale takes the first residual of the body's own unknowns (soft vertices
        // and rigid regions): an obstacle's (a kinematic obstacle's tether pulling it along its
        // schedule, about 1e6 times the body's stiffness) would make any relative tolerance
        // meaningless for the body.
        let own: Real = (self.gradient[..self.n_soft].iter())
            .chain(&self.gradient[rigid.first..])
            .map(|g| g * g)
            .sum::<Real>()
            .sqrt();
        let scale = force_scale(own, p.load, self.elastic_force);
        if !(residual.is_finite() && scale.is_finite()) {
            self.trial_q = trial_q;
            self.rigid = RigidUnknowns {
                q: rq,
                trial: rtrial,
                ..rigid
            };
            return Err(SolverError::invalid(
                format!("{}.forces", self.prefix),
                residual.max(scale),
                "the forces at the starting positions overflow double precision \
                 (a load, a modulus, a spring or a barrier stiffness too large)",
            ));
        }
        let target = params.tolerance * scale;
        report.residuals.push(residual);
        report.potentials.push(phi);
        // Positions are absolute coordinates, so forces carry a round-off floor (see
        // `floors`): a Newton step below `1e-13` of the body's size is at that floor and counts
        // as converged even when the residual tolerance is tighter, and so does a residual
        // whose part above each unknown's own floor meets the tolerance. The potential has a
        // floor too (eps times its terms, and `psi`'s terms are of the order of the modulus,
        // not of `psi`): where a trial's change of potential is below it, the line search
        // accepts the trial if it lowers the residual instead.
        let psi_scale = potential_scale(p.mesh, p.energy);
        let size = body_size(p.mesh.vertices());
        let mut at_floor = false;
        let mut settled = false;
        while residual > target && !at_floor && report.iterations < params.max_iterations {
            self.factorise(
                p,
                x,
                contact.as_deref().map(|c| (c, &c.q[..])),
                (&rigid, &rq),
                &mut report,
            )?;
            let excess = self.above_floor(&self.gradient);
            if excess <= target {
                // Every unknown's residual is within its round-off floor. Before any step that
                // is an equilibrium only if the load itself is resolvable: a load below the
                // floors on every unknown (a modulus or a spring beside which it is round-off,
                // or a step so short that it moves nothing by an ulp) would leave the body
                // where it is, which is not a solution of the problem posed.
                if report.iterations == 0 {
                    let (load, above) = self.load_above_floor(p, x, (&rigid, &rq));
                    if load > 0.0 && above <= params.tolerance * load {
                        self.trial_q = trial_q;
                        self.rigid = RigidUnknowns {
                            q: rq,
                            trial: rtrial,
                            ..rigid
                        };
                        let floor = self.floor.iter().map(|f| f * f).sum::<Real>().sqrt();
                        return Err(SolverError::BeyondPrecision {
                            prefix: self.prefix,
                            detail: format!(
                                "the load ({load:.3e} N) is below the round-off of the stiffness \
                                 and inertia it acts against on every free vertex (their floor, \
                                 {floor:.3e} N), so it would move nothing by one unit in the last \
                                 place of the coordinates"
                            ),
                        });
                    }
                }
                at_floor = true;
                break;
            }
            let start = Stopwatch::start();
            self.solve();
            report.solve_seconds += start.seconds();
            let start = Stopwatch::start();
            let step = self.direction.iter().fold(0.0, |m: Real, d| m.max(d.abs()));
            if step <= 1e-13 * size {
                if report.iterations == 0 {
                    // The first step would move nothing although the residual is above its
                    // floors: the factorisation lost the free part of the body (stiffnesses
                    // too far apart to solve together, or a diagonal shift swamped them).
                    self.trial_q = trial_q;
                    self.rigid = RigidUnknowns {
                        q: rq,
                        trial: rtrial,
                        ..rigid
                    };
                    return Err(SolverError::BeyondPrecision {
                        prefix: self.prefix,
                        detail: format!(
                            "the first Newton step ({step:.3e} m) is below the round-off of the \
                             coordinates while the residual ({residual:.3e} N) is above its \
                             floors ({excess:.3e} N above them): the stiffness matrix is too \
                             ill-conditioned to solve"
                        ),
                    });
                }
                at_floor = true;
                break;
            }
            if let Some(c) = contact.as_deref_mut() {
                // A rotating obstacle turns little enough in one line search for the CCD on
                // its corners' chords to hold: shorten the whole direction.
                c.dq.copy_from_slice(&self.direction[self.n_soft..rigid.first]);
                let limit = c.rotation_limit(x);
                if limit < 1.0 {
                    for d in self.direction.iter_mut() {
                        *d *= limit;
                    }
                }
            }
            let slope: Real = self
                .direction
                .iter()
                .zip(&self.gradient)
                .map(|(d, g)| d * g)
                .sum();
            let mut alpha = 1.0;
            if let Some(c) = contact.as_deref_mut() {
                // The whole Newton step per vertex, the candidates along it, and the CCD bound.
                for (v, t) in self.trial.iter_mut().enumerate() {
                    *t = Vec2::zeros();
                    for d in 0..2 {
                        let j = self.free[2 * v + d];
                        if j != u32::MAX {
                            t[d] = self.direction[j as usize];
                        }
                    }
                }
                c.dq.copy_from_slice(&self.direction[self.n_soft..rigid.first]);
                c.prepare(x, Some(&self.trial));
                alpha = c.max_step(x, &self.trial);
            }
            let mut accepted = false;
            for _ in 0..=params.max_halvings {
                self.trial.copy_from_slice(x);
                for (v, t) in self.trial.iter_mut().enumerate() {
                    for d in 0..2 {
                        let j = self.free[2 * v + d];
                        if j != u32::MAX {
                            t[d] += alpha * self.direction[j as usize];
                        }
                    }
                }
                if let Some(c) = contact.as_deref() {
                    c.trial_poses(alpha, &mut trial_q);
                }
                for (k, (t, q)) in rtrial.iter_mut().zip(&rq).enumerate() {
                    for d in 0..3 {
                        t[d] = q[d] + alpha * self.direction[rigid.first + 3 * k + d];
                    }
                }
                rigid.place(&rtrial, &mut self.trial);
                let cq = contact.as_deref().map(|c| (c, &trial_q[..]));
                let (trial_phi, trial_magnitude) =
                    value(&self.trial, cq, &rtrial, &mut self.scratch);
                if !trial_phi.is_finite() {
                    alpha *= 0.5;
                    continue;
                }
                let armijo = trial_phi <= phi + 1e-4 * alpha * slope;
                let in_round_off =
                    (trial_phi - phi).abs() <= 1e-12 * (magnitude + trial_magnitude + psi_scale);
                let lowers_residual = in_round_off && {
                    let trial = std::mem::take(&mut self.trial);
                    let r = self.gradient(p, &trial, cq, (&rigid, &rtrial));
                    self.trial = trial;
                    r < residual
                };
                if armijo || lowers_residual {
                    // A trial taken for its residual within the potential's round-off keeps
                    // the lower of the two potentials as the reference of the next Armijo
                    // test, so two such states can never alternate.
                    phi = if armijo {
                        trial_phi
                    } else {
                        phi.min(trial_phi)
                    };
                    magnitude = trial_magnitude;
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            report.line_search_seconds += start.seconds();
            report.iterations += 1;
            if !accepted {
                // No decrease along the Newton direction within round-off: the iterate is as
                // good as this precision allows (converged when at the forces' floors).
                at_floor = excess <= target;
                break;
            }
            if step_tolerance > 0.0 && alpha == 1.0 {
                let moved = (self.trial.iter().zip(x.iter()))
                    .map(|(t, x)| (t - x).norm_squared())
                    .fold(0.0, Real::max)
                    .sqrt();
                settled = moved <= step_tolerance;
            }
            x.copy_from_slice(&self.trial);
            rq.clone_from(&rtrial);
            if let Some(c) = contact.as_deref_mut() {
                c.q.clone_from(&trial_q);
                c.prepare(x, None);
            }
            let start = Stopwatch::start();
            residual = self.gradient(
                p,
                x,
                contact.as_deref().map(|c| (c, &c.q[..])),
                (&rigid, &rq),
            );
            report.assembly_seconds += start.seconds();
            report.residuals.push(residual);
            report.potentials.push(phi);
            if !residual.is_finite() {
                break;
            }
            at_floor |= self.above_floor(&self.gradient) <= target;
            if settled {
                break;
            }
        }
        self.trial_q = trial_q;
        self.rigid = RigidUnknowns {
            q: rq,
            trial: rtrial,
            ..rigid
        };
        report.converged = residual.is_finite() && (residual <= target || at_floor || settled);
        let inv = Inversion::of_mesh(p.mesh, x);
        report.min_det_f = inv.min_det_f;
        report.inverted = inv.inverted;
        Ok(report)
    }
}

/// The lower triangle `(col_ptr, row_idx)` (compressed columns, rows sorted) of a symmetric
/// pattern with its rows and columns renumbered (`position[i]`: the new index of `i`), as the
/// upper triangle (rows sorted), and for each old entry its new slot.
fn permute_to_upper(
    col_ptr: &[usize],
    row_idx: &[usize],
    position: &[usize],
) -> (Vec<usize>, Vec<usize>, Vec<usize>) {
    let n = col_ptr.len() - 1;
    // Each entry's new (row, column, old slot), sorted by column then row.
    let mut entries: Vec<(usize, usize, usize)> = Vec::with_capacity(row_idx.len());
    for j in 0..n {
        for (k, &i) in row_idx
            .iter()
            .enumerate()
            .take(col_ptr[j + 1])
            .skip(col_ptr[j])
        {
            let (a, b) = (position[i], position[j]);
            entries.push((a.min(b), a.max(b), k));
        }
    }
    entries.sort_unstable_by_key(|&(r, c, _)| (c, r));
    let mut new_ptr = vec![0usize; n + 1];
    let mut new_rows = Vec::with_capacity(entries.len());
    let mut moved = vec![0usize; entries.len()];
    for (slot, &(r, c, old)) in entries.iter().enumerate() {
        new_ptr[c + 1] += 1;
        new_rows.push(r);
        moved[old] = slot;
    }
    for j in 0..n {
        new_ptr[j + 1] += new_ptr[j];
    }
    (new_ptr, new_rows, moved)
}

/// The force scale a relative residual tolerance is measured against, N: the largest of the
/// first residual `first` (the gradient's norm over the free degrees of freedom at the start
/// of the solve), the norm of the external load `load` (every vertex), the norm of the elastic
/// forces on the free degrees of freedom at the start `elastic` (at equilibrium they balance
/// the load and the contact forces: a body held pressed by an obstacle starts a step nearly
/// balanced, with a tiny first residual, under kilonewtons of contact force), and 1e-12 N.
/// Newton's test ([`NewtonParams::tolerance`]), shared by the iterative solvers that stop at a
/// residual tolerance (VBD, Projective Dynamics, quasi-Newton).
pub(crate) fn force_scale(first: Real, load: &[Vec2], elastic: Real) -> Real {
    let load: Real = load.iter().map(|f| f.norm_squared()).sum::<Real>().sqrt();
    first.max(load).max(elastic).max(1e-12)
}

/// Why the potential is not finite at `x`, for a message: the first pair in contact or
/// crossed (a vertex through the ground or an obstacle, where the barrier is infinite), else
/// the first triangle inverted under an energy that forbids it, else the first vertex whose
/// coordinates are not finite or so large that the terms overflow.
pub(crate) fn start_cause<E: Energy>(
    p: &Potential<'_, E>,
    x: &[Vec2],
    contact: Option<&BarrierContact>,
) -> String {
    if let Some(at) = contact.and_then(|c| c.start_overlap(x)) {
        return format!("{at}, where the contact barrier is infinite");
    }
    let mesh = p.mesh;
    for (t, el) in mesh.elements().iter().enumerate() {
        let f = el.deformation_gradient(mesh.gather(t, x));
        let psi = p.energy.energy_of(t).psi(&f);
        if !psi.is_finite() {
            return format!(
                "triangle {t} has det F = {:.3e}, where its energy is not finite",
                f.determinant()
            );
        }
    }
    match x
        .iter()
        .position(|v| !(v.x.abs() < 1e150 && v.y.abs() < 1e150))
    {
        Some(v) => format!(
            "vertex {v} is at [{:e}, {:e}], beyond what double precision can square",
            x[v].x, x[v].y
        ),
        None => "its terms overflow double precision".to_owned(),
    }
}

/// The diagonal of the bounding box of `x`, m.
pub(crate) fn body_size(x: &[Vec2]) -> Real {
    let (mut lo, mut hi) = (
        Vec2::repeat(Real::INFINITY),
        Vec2::repeat(Real::NEG_INFINITY),
    );
    for p in x {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (hi - lo).norm()
}

/// The scale of the elastic potential's terms, `sum_e M_e a_e` with `M_e` the rest P-wave
/// modulus of element `e`'s region (`psi`'s terms are of that order, whatever `psi` is): the
/// size its round-off is measured against.
fn potential_scale<E: Energy>(mesh: &Mesh, energies: &ElementEnergies<E>) -> Real {
    // Region by region (a handful), so nothing is allocated per solve.
    (energies.energies().iter().enumerate())
        .map(|(k, e)| {
            let modulus = e.dpk1(&fem_core::math::Mat2::identity())[(0, 0)].abs();
            let area: Real = (mesh.elements().iter().enumerate())
                .filter(|&(t, _)| energies.tag(t) as usize == k)
                .map(|(_, el)| el.area)
                .sum();
            modulus * area
        })
        .sum()
}
