//! Vertex Block Descent (Chen, Liu, Yang & Yuksel, "Vertex Block Descent", ACM TOG 43(4),
//! 2024): implicit Euler's incremental potential minimised one vertex at a time.
//!
//! Each (sub)step of length `h` minimises the potential implicit Euler minimises
//! ([`crate::implicit`]),
//!
//! `G(x) = sum_i m_i / (2 h^2) |x_i - x_hat_i|^2 - sum_i f_i . x_i + sum_e a_e psi(F_e)`,
//! `x_hat = x + h v`, `f` = gravity `m g` plus the nodal loads (with the averaged nodal
//! pressure triangle, the formulation's elastic energy in place of `sum_e a_e psi(F_e)`, see
//! below),
//!
//! by Gauss-Seidel over vertex blocks: vertex `i`'s local potential `G_i(x_i)` (its inertia,
//! its load, the energy of the triangles around it, the other vertices held, and the drag
//! attachment's spring `k_i / 2 |x_i - goal_i|^2` when a spring grab holds it, see
//! [`crate::grab`]) gets one Newton step with the 2x2 block
//!
//! `H_i = (m_i / h^2 + k_i) I + sum_e a_e B_e`,  `(B_e)_ik = sum_jl g_j dP_ij/dF_kl g_l`,
//!
//! from every energy's `P` and corner block `B_e` ([`Energy::pk1_corner_block`], in closed
//! form for four of the five energies), with `g` the shape-function gradient of the vertex's
//! corner. **Definiteness fix:** each triangle's block `B_e` has its negative eigenvalue
//! clamped to zero before it is summed (StVK's, under compression, and every energy's under
//! large shear can be indefinite), so `H_i` is always positive definite and the step a descent
//! direction. **Line search** (`line_search`, default off, as in the paper): the step is
//! halved (up to 8 times) until `G_i` is finite and not above its value at the start (within
//! its round-off); otherwise the vertex stays. With it every vertex update lowers `G`, so the
//! sweeps descend monotonically, at 2 to 3 times the cost of a sweep; without it a step is
//! still halved while it would invert a triangle of an energy that forbids inversion (its
//! `psi` infinite at `det F <= 0`), tested exactly and cheaply by the rank-one update
//! `det(F + s g^T) = det F + s . cof(F) g`. Both reach the same step on every test.
//!
//! **What it converges to.** As `iterations` grow, each step converges to a stationary point
//! of `G`: the implicit Euler step, which Newton finds to its tolerance. The stepper battery's
//! rollout (`tests/suite/battery.rs`) and `tests/suite/vbd.rs` measure the gap: one step from
//! a stretched beam reaches implicit Euler's to round-off, the gap shrinking geometrically
//! with the iterations (Gauss-Seidel's linear rate).
//!
//! **Parallel sweeps.** The free vertices are coloured so that no two of one colour share a
//! triangle ([`VertexColouring`]); within a colour the updates are independent, so they are
//! computed in parallel from the same positions and then written. The result equals the
//! serial sweep in colour order, bit for bit, for any number of threads.
//!
//! **The averaged nodal pressure triangle** ([`fem_core::nodal_pressure`],
//! [`Model::set_averaged_pressure`]): the potential's elastic part is the formulation's,
//! `sum_e a_e [psi(F_e) - U(theta_e)] + sum_n V_n U(theta_n)`, the same one implicit Euler
//! minimises. Vertex `i`'s local potential holds its triangles' `psi - U(theta_e)` and the
//! nodal term of every node whose patch holds it (its **ring**: the nodes of its triangles), so
//! the vertex block sees the patch: with `w_e = dtheta_e/dF g` and
//! `h_n = sum_{e at n and i} a_e / 3 w_e = V_n dtheta_n/dx_i`, the gradient adds
//! `-a_e U'(theta_e) w_e` per triangle and `U'(theta_n) h_n` per ring node, and the block
//! `-a_e U''(theta_e) w_e w_e^T` inside each triangle's clamped block and
//! `max(U''(theta_n), 0) / V_n h_n h_n^T` per ring node (`theta_e` is linear in one vertex's
//! position, so its curvature adds nothing to a vertex block). The line search's potential
//! moves each ring node's `theta_n` by its triangles' change of `theta_e`. The stepper keeps
//! `theta_e` of every element and `theta_n` of every node current: measured at the initial
//! guess; after each colour, for the moved vertices' triangles and rings (each `theta_n` summed
//! afresh in its node's triangle order, so no round-off accumulates over the sweeps); after
//! each free body's step, for the triangles it touches and their nodes; after each Chebyshev
//! extrapolation, for all. A vertex's local potential reads the nodal volumes of its ring,
//! which every vertex of the ring's patches moves (up to two edges away), so the colouring is
//! stricter: no two vertices of one colour share a node's patch
//! ([`VertexColouring::greedy_patches`]; 9 colours instead of 4 on the structured cantilevers),
//! and a colour's parallel updates are again exactly the serial sweep's, bit-identical for any
//! number of threads. A free body's block takes the same terms: each triangle's element part
//! of the formulation's Hessian (`dP/dF - U''(theta_e) t t^T + (p_e - U'(theta_e)) d2theta`,
//! exact, or projected when the 3x3 matrix is indefinite) and per node
//! `U''(theta_n) / V_n u u^T`, `u = sum_a J_a^T h_n[a]` over the body's corners (`U''`
//! clamped at zero when projected). Contact, the grab's springs and Chebyshev acceleration
//! are unchanged; the residual test's forces are fem-core's under the formulation. Plain
//! models take none of this (the same bits as without it). Measured in `tests/suite/vbd.rs`
//! (nu = 0.49, three 10 ms steps of the 10 x 2 cantilever): the gap to implicit Euler with the
//! formulation is 6e-5 after 100 sweeps and 3e-10 (Newton's own round-off floor) from 1000,
//! where plain VBD ends 6e-2 away. A sweep costs about twice a plain one (160 x 32
//! cantilever, one thread: 56 ms against 25 ms per step of 10 sweeps): the ring's nodal
//! terms, a logarithm per node and triangle for the Neo-Hookean energies, and the measures
//! kept current in each colour's serial write-back.
//!
//! **Initial guess** (`init`): `previous` (the positions at the start of the step),
//! `inertia` (`x_hat + h^2 f / m`, the paper's inertia-and-acceleration guess with the
//! external acceleration), or `adaptive` (default; the paper's Sec. 3.6): `x_hat + h^2 a~`
//! with `a~` the last step's acceleration `(v_t - v_{t-1}) / h` projected on the external
//! acceleration's direction and clamped between zero and its magnitude, so a body resting on
//! a support does not start each step pushed into it; the first step uses the full external
//! acceleration. A guess that inverts a triangle of an energy forbidding inversion is replaced
//! by the previous positions (kinematic vertices moved), which are valid. The adaptive guess
//! reads the previous step's velocity, kept by the stepper: it changes only where the
//! iterations start, never what they converge to.
//!
//! **Chebyshev acceleration** (`chebyshev_rho`, 0 = off; Wang 2015, as the VBD paper uses it):
//! after sweep `k` the free positions become `x_k = w_k (x~_k - x_{k-2}) + x_{k-2}` with
//! `w_1 = 1`, `w_2 = 2 / (2 - rho^2)`, `w_k = 4 / (4 - rho^2 w_{k-1})`. It helps when `rho` is
//! near the sweeps' true spectral radius (stiff, slowly converging steps); with `rho` above it,
//! the extrapolation overshoots and the iterations oscillate or diverge (measured in
//! `tests/suite/vbd.rs`). An extrapolation that would invert a triangle of an energy
//! forbidding inversion is dropped (that sweep's plain result is kept) and the sequence
//! restarts.
//!
//! **Contact** (a ground or obstacles) is implicit Euler's barrier term (IPC-style, built on
//! [`crate::ipc`]) in each vertex's local potential: its pairs' barrier and lagged friction
//! join the vertex's gradient and (projected) block, every vertex move is limited by
//! the CCD of its pairs (the others held) and to `2 d_hat` per sweep (the broad phase before
//! each sweep reaches `3 d_hat`, so no pair it missed can come close), and a vertex with pairs
//! always takes the line search. Dynamic and kinematic obstacles take one Newton step on
//! their pose after each sweep, closing at most half of any gap (a vertex's Newton step on the
//! barrier about doubles its gap, so both sides keep pace); a kinematic obstacle is tethered
//! to its schedule at ten times the body's modulus. The initial guess (and the obstacles'
//! predicted poses) are taken only as far as the CCD allows, and Chebyshev acceleration is
//! off. What this converges to is implicit Euler's step with barrier contact; an obstacle
//! pushed faster than the gaps let the sweeps follow lags its schedule (measured in
//! `tests/suite/barrier_contact.rs`).
//!
//! **Rigid regions** ([`crate::rigid::body`], after Augmented VBD: Giles, Diaz & Yuksel 2025,
//! which treats a rigid body as one more block). The elements and energies are those of the
//! elastic mesh ([`Model::elastic_mesh`]): a rigid triangle carries no energy. Each free body
//! is a block of three unknowns `q = (p, theta)`, its vertices slaved, `x_v = p + R(theta) r_v`,
//! so `dx_v = J_v dq` with `J_v = [I | perp(x_v - p)]`, `perp(u) = (-u_y, u_x)`. Its local
//! potential is its inertia `M / (2 h^2) |p - y_p|^2 + I / (2 h^2) (theta - y_theta)^2`
//! (`y = (p + h v + h^2 g, theta + h omega)`; in 2D `diag(M, M, I)` in `(p, theta)` is exact),
//! the nodal loads and grab springs on its vertices, and the energy of every deformable
//! triangle with a corner on it (the other vertices held). One Newton step on it: gradient
//! `sum_v J_v^T g_v`, 3x3 matrix `diag(M, M, I) / h^2 + sum_e sum_ab J_a^T H_ab J_b` with
//! `H_ab` the 2x2 blocks between the body's corners of the triangle's Hessian built from the
//! projected `dP/dF` ([`Energy::dpk1_projected`], so each triangle's part is positive
//! semi-definite, as the vertex blocks' are), plus the rotation's curvature
//! `-sum_v g_v . (x_v - p)` on the angle when positive; solved by Cholesky (a failure leaves
//! the body in place), halved as a vertex step is (line search, inversion), and the body's
//! vertices placed on the new pose. After each sweep's colours the free bodies take their
//! step one after another in the order of [`Model::rigid_bodies`] (serial, so the bits do not
//! depend on the threads); the next sweep's vertices see them. The first pose is the initial
//! guess's counterpart (`previous`: the pose; `inertia`: `y` plus the loads' acceleration;
//! `adaptive`: `y` with the clamped last acceleration along the external one); with contact
//! it is the pose, so the CCD of the start never moves a body's vertices apart. Chebyshev
//! acceleration extrapolates the free vertices only (the bodies are left out). At the end
//! the body's velocities are `(q - q_t) / h` damped as the vertices', and the step's end places
//! its vertices. Contact acts on the soft vertices only: the barrier and friction of a body's
//! slaved vertices are ignored (they are neither pushed nor checked by the CCD).
//!
//! **Residual tolerance** (`tolerance`, scene key `residual_tolerance`; 0 = off, the
//! default). With a positive tolerance each substep evaluates, at its initial guess and after
//! each sweep (with its free bodies' and obstacles' steps and Chebyshev's extrapolation), the
//! norm of the gradient of the potential the sweeps descend over the free degrees of freedom
//! (N): the free vertices' `m / h^2 (x - x_hat) - f + dPsi/dx + k (x - goal)` plus their
//! contact pairs' barrier and friction terms, each free body's three reduced components
//! `sum_v J_v^T g_v` plus its inertia (its slaved vertices' contact left out, as its block leaves
//! it out), and the moving obstacles' poses. It stops sweeping once that norm is at most
//! `tolerance` times Newton's force scale ([`crate::newton::NewtonParams::tolerance`]: the
//! largest of the first residual, the norm of the external load, the norm of the elastic forces
//! on the free vertices and bodies at the initial guess, and 1e-12 N); `iterations` is then the
//! most sweeps per substep, and the step's report gives the sweeps done (summed over substeps)
//! and that norm. One evaluation costs one elastic force assembly (a `P` per triangle, where a
//! sweep takes a `P` and a corner block per triangle corner), the contact gradient and a pass
//! over the vertices; nothing is allocated. With tolerance 0 no gradient is evaluated and the
//! sweeps, the bits and the report are those of a fixed count.
//!
//! **BDF2** (`integrator = "bdf2"`, [`crate::integrator`]): each substep descends BDF2's
//! potential instead (inertia weight `9 / (4 h^2)`, BDF2's target for the vertices, the free
//! bodies' poses and the dynamic obstacles, BDF2's velocities; the initial guesses use
//! `4 h^2 / 9` where they used `h^2`); a substep whose incoming state is not the one the
//! stepper committed last (the first, a restored state) is backward Euler.
//!
//! Registered as `vbd` ([`Solver`]); scene keys `dt`, `substeps`, `iterations`, `damping`,
//! `init`, `chebyshev_rho`, `line_search`, `residual_tolerance`, `integrator`.

use fem_core::assembly::{Scratch, populate_forces};
use fem_core::energy::{
    ElementEnergies, Energy, EnergyOf, VolumeMeasure, Volumetric, project_psd,
    project_psd_isotropic,
};
use fem_core::math::{Mat2, Mat4, Real, Vec2, exp, ln, vec, vec_index};
use fem_core::mesh::{Mesh, VertexAdjacency};
use fem_core::nodal_pressure::NodalPressure;
use fem_core::par::prelude::*;
use nalgebra::{Matrix3, Vector3};

use super::{Stepper, check_step_inputs};
use crate::contact::Contact;
use crate::contact::barrier::{BarrierContact, Dof, end_poses, step_targets};
use crate::error::{
    SolverError, check_count, check_non_negative, check_positive, check_residual_tolerance,
    check_rho,
};
use crate::kernel::{
    ELEMENT_CHUNK, Inversion, PackedElement, corner_gradient, deformation_gradient, pack,
};
use crate::model::Model;
use crate::model::grab::{Spring, spring_of};
use crate::model::limits;
use crate::model::state::State;
use crate::optim::newton::force_scale;
use crate::rigid::{BodyState, Frame, RigidBody, cross};
use crate::steppers::colour::VertexColouring;
use crate::steppers::commit::{Kinematic, StepEnd};
use crate::steppers::implicit::external_load;
use crate::steppers::integrator::{
    History, Integrator, bdf2_body_velocity, bdf2_obstacle_targets, bdf2_obstacle_velocities,
    bdf2_pose_target, bdf2_velocity, bdf2_weight,
};
use crate::steppers::registry::{Capabilities, Clock, Solver};
use crate::steppers::report::StepReport;

/// Vertices per parallel task of a colour. Fixed, so the split never depends on the thread
/// count (the updates of one colour are independent anyway).
const VBD_CHUNK: usize = 512;
/// Halvings of a local step before the vertex is left where it is.
const LOCAL_HALVINGS: usize = 8;

/// Where the iterations of a step start. Serde names: `previous`, `inertia`, `adaptive`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
#[non_exhaustive]
pub enum VbdInit {
    /// The positions at the start of the step.
    Previous,
    /// `x + h v + h^2 f / m`: inertia and the external acceleration.
    Inertia,
    /// Inertia plus the last step's acceleration along the external one, clamped (the VBD
    /// paper's adaptive initialisation). Default.
    #[default]
    Adaptive,
}

/// Parameters of [`VbdStepper`] (scene keys: the field names).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct VbdParams {
    /// Time step, s (finite, > 0). Default `1e-3`.
    pub dt: Real,
    /// Substeps per step (>= 1); each is a full VBD step of `dt / substeps`. Default 1.
    pub substeps: usize,
    /// Sweeps over all free vertices per substep (>= 1). Default 10.
    pub iterations: usize,
    /// Velocity damping rate `c`, 1/s (`v <- v exp(-c h)` per substep). Default 0.
    pub damping: Real,
    /// The initial guess of each substep. Default adaptive.
    pub init: VbdInit,
    /// Chebyshev's spectral radius estimate `rho`, in `[0, 1)`; 0 turns the acceleration off.
    /// Default 0.
    pub chebyshev_rho: Real,
    /// Backtrack each vertex step until its local potential does not increase. Default false
    /// (the paper's full Newton steps, halved only to keep triangles uninverted).
    pub line_search: bool,
    /// Relative residual tolerance in `[0, 1)`, dimensionless (scene key
    /// `residual_tolerance`): when positive, a substep stops sweeping once the gradient of its
    /// incremental potential over the free degrees of freedom (N) is at most `tolerance` times
    /// the force scale (Newton's: the largest of the first residual, the external load, the
    /// elastic forces at the start, 1e-12 N); `iterations` is then the most sweeps. 0 runs
    /// exactly `iterations` sweeps and evaluates no gradient. Default 0.
    #[cfg_attr(feature = "serde", serde(rename = "residual_tolerance"))]
    pub tolerance: Real,
    /// The time integrator of each substep: backward Euler (default) or BDF2 (second order;
    /// see [`crate::integrator`]).
    pub integrator: Integrator,
}

impl Default for VbdParams {
    fn default() -> Self {
        VbdParams {
            dt: 1e-3,
            substeps: 1,
            iterations: 10,
            damping: 0.0,
            init: VbdInit::default(),
            chebyshev_rho: 0.0,
            line_search: false,
            tolerance: 0.0,
            integrator: Integrator::BackwardEuler,
        }
    }
}

impl VbdParams {
    /// Check every field; errors name `vbd.<field>`.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.validate_as(VbdStepper::NAME)
    }

    /// Check every field; errors name `<prefix>.<field>`.
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        let field = |name: &str| format!("{prefix}.{name}");
        check_positive(&field("dt"), self.dt)?;
        check_count(&field("substeps"), self.substeps, limits::MAX_SUBSTEPS)?;
        check_count(
            &field("iterations"),
            self.iterations,
            limits::MAX_ITERATIONS,
        )?;
        check_non_negative(&field("damping"), self.damping)?;
        check_rho(&field("chebyshev_rho"), self.chebyshev_rho)?;
        check_residual_tolerance(&field("residual_tolerance"), self.tolerance)
    }
}

/// What the last step did, beyond its [`StepReport`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VbdStats {
    /// Vertex updates whose step was halved at least once.
    pub halved: usize,
    /// Vertex updates left in place (no acceptable step, or a singular block).
    pub rejected: usize,
    /// Chebyshev extrapolations dropped because they inverted a triangle.
    pub chebyshev_restarts: usize,
    /// Whether an initial guess was replaced by the previous positions.
    pub fallback_guess: bool,
    /// The force scale of the last substep's residual test, N (0 when the tolerance is 0):
    /// the step's residual is at most `tolerance` times it when the sweeps stopped early.
    pub force_scale: Real,
}

/// Vertex Block Descent; see the module docs.
#[derive(Debug)]
pub struct VbdStepper {
    params: VbdParams,
    h: Real,
    decay: Real,
    n_triangles: usize,
    els: Vec<PackedElement>,
    /// The rest P-wave modulus of each region, Pa: the scale of `psi`'s terms.
    moduli: Vec<Real>,
    colouring: VertexColouring,
    forbids_inversion: bool,
    target: Vec<Vec2>,
    load: Vec<Vec2>,
    x: Vec<Vec2>,
    v_new: Vec<Vec2>,
    /// Per colour slot: the vertex's new position, written back after the colour.
    buf: Vec<Vec2>,
    /// Per colour slot: the outcome of the vertex update.
    outcome: Vec<Outcome>,
    /// Chebyshev's iterates (allocated on the first accelerated step).
    chebyshev: Chebyshev,
    /// The velocities at the start of the last substep (adaptive guess), if any.
    v_prev: Option<Vec<Vec2>>,
    stats: VbdStats,
    /// The model layout the vertices were coloured for.
    layout: u64,
    /// Barrier contact, when the model has a ground or obstacles.
    contact: Option<BarrierContact>,
    /// The obstacles' target poses of the substep and their new states.
    targets: Vec<[Real; 3]>,
    bodies_new: Vec<BodyState>,
    /// The smallest distance over the candidate pairs at the end of the last step, m.
    min_distance: Real,
    /// The free rigid bodies' blocks, in the order of [`Model::rigid_bodies`].
    blocks: Vec<BodyBlock>,
    /// The rigid bodies' poses being iterated (one per body; those of kinematic bodies are
    /// ignored by the step's end), then their new states.
    rigid_new: Vec<BodyState>,
    /// The rigid bodies' velocities at the start of the last substep (adaptive guess, read
    /// when `v_prev` is set).
    rigid_prev: Vec<Vec2>,
    /// The buffers of the residual test (sized only when the tolerance is positive).
    gradient: GradientBuffers,
    /// The previous substep's state (BDF2).
    history: History,
    /// Substeps of the last step that were BDF2 steps.
    last_bdf2: usize,
    /// The averaged nodal pressure triangle's rings (empty without it).
    rings: Rings,
    /// Its current volume measures (empty without it).
    measures: Measures,
}

/// The buffers of VBD's residual test, reused every sweep.
#[derive(Debug, Default)]
struct GradientBuffers {
    /// Elastic forces per vertex (then minus the contact gradient on the soft vertices), N.
    forces: Vec<Vec2>,
    scratch: Scratch,
    /// The contact gradient on the moving obstacles' poses.
    extra: Vec<Real>,
}

/// A free rigid body as one block of the sweeps (see the module docs).
#[derive(Clone, Debug)]
struct BodyBlock {
    /// The body's index in [`Model::rigid_bodies`].
    body: usize,
    /// The deformable elements with a corner on the body, increasing, with the corners that
    /// are the body's (bit `k` for corner `k`).
    elements: Vec<(u32, u8)>,
    /// The nodal loads on the body's vertices (gravity apart), refreshed each step.
    forces: Vec<(u32, Vec2)>,
    /// The inertial target of the substep: `p + h v + h^2 g` and `theta + h omega`.
    target: (Vec2, Real),
    /// With the averaged nodal pressure triangle: the nodes whose patch holds a vertex of the
    /// body (the nodes of `elements`), increasing; else empty.
    nodes: Vec<u32>,
    /// `node_offsets[k]..node_offsets[k + 1]` indexes node `k`'s triangles in `node_elements`.
    node_offsets: Vec<u32>,
    /// Positions in `elements` of each node's triangles, increasing per node.
    node_elements: Vec<u32>,
}

impl BodyBlock {
    /// The triangles at ring node `k` of the body, as positions in `elements`.
    #[inline]
    fn node_elements(&self, k: usize) -> &[u32] {
        &self.node_elements[self.node_offsets[k] as usize..self.node_offsets[k + 1] as usize]
    }
}

/// The averaged nodal pressure triangle in the sweeps ([`fem_core::nodal_pressure`]): each
/// vertex's **ring**, the nodes whose patch holds it (the nodes of the triangles around it),
/// each with the positions in the vertex's fan ([`VertexAdjacency::of`]) of its triangles at
/// that node; and each node's region and triangles with their weights `a_e / 3`. Built once
/// per model; empty without the formulation.
#[derive(Debug, Default)]
struct Rings {
    /// `offsets[v]..offsets[v + 1]` indexes vertex `v`'s ring entries in `nodes`.
    offsets: Vec<u32>,
    /// The ring nodes of each vertex, increasing per vertex.
    nodes: Vec<u32>,
    /// `fan_offsets[k]..fan_offsets[k + 1]` indexes ring entry `k`'s fan positions in `fan`.
    fan_offsets: Vec<u32>,
    /// Fan positions, increasing per ring entry.
    fan: Vec<u32>,
    /// The volumetric part of each region's energy.
    volumetric: Vec<Volumetric>,
    /// The region of each node.
    node_region: Vec<u32>,
    /// `node_offsets[n]..node_offsets[n + 1]` indexes node `n`'s triangles in `node_entries`.
    node_offsets: Vec<u32>,
    /// Each node's triangles (in [`NodalPressure::entries`] order) with their `a_e / 3`.
    node_entries: Vec<(u32, Real)>,
}

impl Rings {
    fn new<E: Energy>(
        mesh: &Mesh,
        np: &NodalPressure,
        energies: &ElementEnergies<E>,
        els: &[PackedElement],
    ) -> Self {
        let adj = mesh.adjacency();
        let mut r = Rings {
            offsets: vec![0],
            nodes: Vec::new(),
            fan_offsets: vec![0],
            fan: Vec::new(),
            volumetric: energies.energies().iter().map(|e| e.volumetric()).collect(),
            node_region: Vec::with_capacity(np.n_nodes()),
            node_offsets: vec![0],
            node_entries: Vec::new(),
        };
        for n in 0..np.n_nodes() {
            let entries = np.entries(n);
            r.node_region.push(els[entries[0].0 as usize].region);
            (r.node_entries).extend(
                entries
                    .iter()
                    .map(|&(t, _)| (t, els[t as usize].area / 3.0)),
            );
            r.node_offsets.push(r.node_entries.len() as u32);
        }
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        for v in 0..mesh.n_vertices() {
            pairs.clear();
            for (f, &(t, _)) in adj.of(v).iter().enumerate() {
                pairs.extend(np.corner_nodes(t as usize).map(|n| (n, f as u32)));
            }
            pairs.sort_unstable();
            for group in pairs.chunk_by(|a, b| a.0 == b.0) {
                r.nodes.push(group[0].0);
                r.fan.extend(group.iter().map(|&(_, f)| f));
                r.fan_offsets.push(r.fan.len() as u32);
            }
            r.offsets.push(r.nodes.len() as u32);
        }
        r
    }

    /// Vertex `v`'s ring entries (indices into `nodes`).
    #[inline]
    fn of(&self, v: usize) -> std::ops::Range<usize> {
        self.offsets[v] as usize..self.offsets[v + 1] as usize
    }

    /// Ring entry `k`'s fan positions.
    #[inline]
    fn fan(&self, k: usize) -> &[u32] {
        &self.fan[self.fan_offsets[k] as usize..self.fan_offsets[k + 1] as usize]
    }

    /// The volumetric part of node `n`'s energy (its region's).
    #[inline]
    fn node_volumetric(&self, n: usize) -> Volumetric {
        self.volumetric[self.node_region[n] as usize]
    }

    /// `theta_n` of node `n` from the elements' `theta`, summed in the node's triangle order
    /// (as fem-core sums it, to the same bits).
    #[inline]
    fn node_theta(&self, np: &NodalPressure, n: usize, theta: &[Real]) -> Real {
        let mut s = 0.0;
        for &(t, w) in
            &self.node_entries[self.node_offsets[n] as usize..self.node_offsets[n + 1] as usize]
        {
            s += w * theta[t as usize];
        }
        s / np.volume(n)
    }
}

/// `U'(theta)` and `U''(theta)` with one logarithm: [`Volumetric::du`] and
/// [`Volumetric::d2u`], the same bits (a unit test checks).
#[inline(always)]
fn du_d2u(vol: &Volumetric, theta: Real) -> (Real, Real) {
    match *vol {
        Volumetric::LogSquared { lambda } if theta > 0.0 => {
            let l = ln(theta);
            (lambda * l / theta, lambda * (1.0 - l) / (theta * theta))
        }
        _ => (vol.du(theta), vol.d2u(theta)),
    }
}

/// The current volume measures of the averaged nodal pressure triangle, kept up to date as the
/// sweeps move vertices: `theta_e` of every element and `theta_n` of every node.
#[derive(Debug, Default)]
struct Measures {
    element: Vec<Real>,
    node: Vec<Real>,
}

/// What a vertex update reads of the averaged nodal pressure triangle.
#[derive(Clone, Copy, Debug)]
struct Nodal<'a> {
    np: &'a NodalPressure,
    rings: &'a Rings,
}

/// `psi - U(theta)` of one element: `+inf` stays `+inf` (an inverted Neo-Hookean element).
#[inline(always)]
fn deviatoric(psi: Real, u: Real) -> Real {
    if psi == Real::INFINITY { psi } else { psi - u }
}

/// `sum_jl a_j D_(ij),(kl) b_l`: the 2x2 block of `dP/dF = D` between two corners with
/// shape-function gradients `a` and `b`.
#[inline]
fn contract_pair(d: &Mat4, a: &Vec2, b: &Vec2) -> Mat2 {
    let mut m = Mat2::zeros();
    for i in 0..2 {
        for k in 0..2 {
            let mut s = 0.0;
            for j in 0..2 {
                for l in 0..2 {
                    s += a[j] * d[(vec_index(i, j), vec_index(k, l))] * b[l];
                }
            }
            m[(i, k)] = s;
        }
    }
    m
}

/// `perp(u) = (-u_y, u_x)`: how a point at lever `u` moves per unit of rotation.
#[inline(always)]
fn perp(u: Vec2) -> Vec2 {
    Vec2::new(-u.y, u.x)
}

/// Add the gradient `gv` of a vertex at lever `r` from the centroid to a body's gradient `g`
/// (`J^T gv`) and `gv . r` to `lever` (the rotation's curvature is `-sum gv . r`).
#[inline(always)]
fn add_lever_gradient(g: &mut Vector3<Real>, lever: &mut Real, gv: Vec2, r: Vec2) {
    g.x += gv.x;
    g.y += gv.y;
    g.z += cross(r, gv);
    *lever += gv.dot(&r);
}

/// Add `J_a^T B J_b` to a body's 3x3 matrix, for the 2x2 block `B` between vertices at levers
/// `ra` and `rb`.
#[inline(always)]
fn add_lever_block(h: &mut Matrix3<Real>, b: &Mat2, ra: Vec2, rb: Vec2) {
    let (pa, pb) = (perp(ra), perp(rb));
    let col = b * pb;
    let row = b.transpose() * pa;
    h[(0, 0)] += b[(0, 0)];
    h[(0, 1)] += b[(0, 1)];
    h[(1, 0)] += b[(1, 0)];
    h[(1, 1)] += b[(1, 1)];
    h[(0, 2)] += col.x;
    h[(1, 2)] += col.y;
    h[(2, 0)] += row.x;
    h[(2, 1)] += row.y;
    h[(2, 2)] += pa.dot(&col);
}

/// One vertex update: gradient norm before it (N), and how it went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Outcome {
    gradient: Real,
    halved: bool,
    rejected: bool,
}

/// Whether `energy` forbids inversion: `psi` is infinite at `det F = -1`.
pub(crate) fn forbids_inversion<E: Energy>(energy: &E) -> bool {
    !energy.psi(&Mat2::new(1.0, 0.0, 0.0, -1.0)).is_finite()
}

/// `F` of `el` with the vertex at `corner` moved to `p`.
#[inline(always)]
fn deformation_gradient_with(el: &PackedElement, x: &[Vec2], corner: u8, p: Vec2) -> Mat2 {
    let mut v = [
        x[el.idx[0] as usize],
        x[el.idx[1] as usize],
        x[el.idx[2] as usize],
    ];
    v[corner as usize] = p;
    Mat2::from_columns(&[v[1] - v[0], v[2] - v[0]]) * el.dm_inv
}

/// The symmetric 2x2 matrix `[[a, b], [b, c]]` with negative eigenvalues set to zero.
#[inline(always)]
pub(crate) fn psd2(a: Real, b: Real, c: Real) -> (Real, Real, Real) {
    // Positive semidefinite already (the common case): no square root.
    if a >= 0.0 && c >= 0.0 && a * c >= b * b {
        return (a, b, c);
    }
    let mean = 0.5 * (a + c);
    let r = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (lo, hi) = (mean - r, mean + r);
    if lo >= 0.0 {
        (a, b, c)
    } else if hi <= 0.0 {
        (0.0, 0.0, 0.0)
    } else {
        // hi times the projector onto its eigenvector: (M - lo I) / (hi - lo).
        let s = hi / (2.0 * r);
        (s * (a - lo), s * b, s * (c - lo))
    }
}

/// Triangles around a vertex whose orientation data a vertex update keeps on the stack; a
/// vertex with more recomputes `det F` at each trial position instead.
const FAN: usize = 16;

/// What a vertex update reads.
struct Local<'a, E: Energy> {
    energy: &'a ElementEnergies<E>,
    els: &'a [PackedElement],
    adj: &'a VertexAdjacency,
    masses: &'a [Real],
    /// The inertia weight: `1 / h^2` (BDF2: `9 / (4 h^2)`).
    w: Real,
    target: &'a [Vec2],
    load: &'a [Vec2],
    line_search: bool,
    forbids_inversion: bool,
    /// The rest P-wave modulus of each region, Pa: the scale of `psi`'s terms.
    moduli: &'a [Real],
    /// The springs of a spring grab, sorted by vertex.
    springs: &'a [Spring],
    /// Barrier contact (pairs indexed by vertex) and the largest move of a boundary vertex
    /// per sweep, m.
    contact: Option<(&'a BarrierContact, Real)>,
    /// The averaged nodal pressure triangle, when the model uses it.
    nodal: Option<Nodal<'a>>,
}

impl<E: Energy> Local<'_, E> {
    /// The local potential of vertex `v` at `p` (the others at `x`, the formulation's measures
    /// `m`), measured from its inertia and load terms at `x[v]` so that round-off stays that
    /// of the changes. With the averaged nodal pressure triangle: the triangles' `psi - U` and
    /// the ring's nodal `V_n U(theta_n)`, `theta_n` moved by the fan's change of `theta_e`.
    fn potential(&self, v: usize, x: &[Vec2], p: Vec2, m: &Measures) -> Real {
        let mw = self.masses[v] * self.w;
        let mut e = 0.5 * mw * (p - self.target[v]).norm_squared() - self.load[v].dot(&(p - x[v]));
        if let Some(s) = spring_of(self.springs, v) {
            e += 0.5 * s.stiffness * (p - s.goal).norm_squared();
        }
        if let Some((c, _)) = self.contact {
            e += c.vertex_energy(v, x, p);
        }
        let fan = self.adj.of(v);
        let mut fan_theta = [0.0; FAN];
        for (i, &(t, corner)) in fan.iter().enumerate() {
            let el = &self.els[t as usize];
            let energy = el.energy(self.energy);
            let f = deformation_gradient_with(el, x, corner, p);
            let psi = energy.psi(&f);
            e += el.area
                * match self.nodal {
                    None => psi,
                    Some(nd) => {
                        let vol = nd.rings.volumetric[el.region as usize];
                        let theta = vol.theta(&f);
                        if i < FAN {
                            fan_theta[i] = theta;
                        }
                        deviatoric(psi, vol.u(theta))
                    }
                };
        }
        if let Some(nd) = self.nodal {
            for k in nd.rings.of(v) {
                let n = nd.rings.nodes[k] as usize;
                let mut d = 0.0;
                for &f in nd.rings.fan(k) {
                    let f = f as usize;
                    let (t, corner) = fan[f];
                    let el = &self.els[t as usize];
                    let theta = if f < FAN {
                        fan_theta[f]
                    } else {
                        let vol = nd.rings.volumetric[el.region as usize];
                        vol.theta(&deformation_gradient_with(el, x, corner, p))
                    };
                    d += el.area / 3.0 * (theta - m.element[t as usize]);
                }
                let vn = nd.np.volume(n);
                e += vn * nd.rings.node_volumetric(n).u(m.node[n] + d / vn);
            }
        }
        e
    }

    /// `theta_e` of element `t` at `x`.
    #[inline]
    fn element_theta(&self, nd: Nodal<'_>, t: usize, x: &[Vec2]) -> Real {
        let el = &self.els[t];
        nd.rings.volumetric[el.region as usize].theta(&deformation_gradient(el, x))
    }

    /// Every element's and node's measure at `x` (nothing without the formulation): in
    /// parallel, each written once, so the same for any number of threads.
    fn measure_all(&self, x: &[Vec2], m: &mut Measures) {
        let Some(nd) = self.nodal else { return };
        (m.element.par_chunks_mut(ELEMENT_CHUNK).enumerate()).for_each(|(c, out)| {
            for (k, o) in out.iter_mut().enumerate() {
                *o = self.element_theta(nd, c * ELEMENT_CHUNK + k, x);
            }
        });
        let theta = &m.element;
        (m.node.par_chunks_mut(ELEMENT_CHUNK).enumerate()).for_each(|(c, out)| {
            for (k, o) in out.iter_mut().enumerate() {
                *o = nd.rings.node_theta(nd.np, c * ELEMENT_CHUNK + k, theta);
            }
        });
    }

    /// After vertex `v` moved to `x[v]`: the measures of its triangles, then of its ring's
    /// nodes (the only ones that changed).
    fn measure_vertex(&self, v: usize, x: &[Vec2], m: &mut Measures) {
        let Some(nd) = self.nodal else { return };
        for &(t, _) in self.adj.of(v) {
            m.element[t as usize] = self.element_theta(nd, t as usize, x);
        }
        for k in nd.rings.of(v) {
            let n = nd.rings.nodes[k] as usize;
            m.node[n] = nd.rings.node_theta(nd.np, n, &m.element);
        }
    }

    /// After a free body moved: the measures of the triangles it touches and of their nodes.
    fn measure_body(&self, blk: &BodyBlock, x: &[Vec2], m: &mut Measures) {
        let Some(nd) = self.nodal else { return };
        for &(t, _) in &blk.elements {
            m.element[t as usize] = self.element_theta(nd, t as usize, x);
        }
        for &n in &blk.nodes {
            m.node[n as usize] = nd.rings.node_theta(nd.np, n as usize, &m.element);
        }
    }

    /// `(a_e / 3) dtheta_e/dF g`: fan entry `f` of vertex `v`'s part of `V_n dtheta_n/dx_v`
    /// for each node `n` of its triangle.
    fn fan_dtheta(&self, v: usize, f: usize, x: &[Vec2]) -> Vec2 {
        let (t, corner) = self.adj.of(v)[f];
        let el = &self.els[t as usize];
        let vol = self.nodal.expect("the formulation").rings.volumetric[el.region as usize];
        vol.dtheta(&deformation_gradient(el, x)) * corner_gradient(el, corner) * (el.area / 3.0)
    }

    /// Whether moving vertex `v` to `p` keeps every triangle around it uninverted.
    fn keeps_orientation(&self, v: usize, x: &[Vec2], p: Vec2) -> bool {
        self.adj.of(v).iter().all(|&(t, corner)| {
            deformation_gradient_with(&self.els[t as usize], x, corner, p).determinant() > 0.0
        })
    }

    /// One Newton step on vertex `v`'s local potential (with the formulation's measures `m`):
    /// the new position and the outcome.
    #[inline]
    fn update(&self, v: usize, x: &[Vec2], m: &Measures) -> (Vec2, Outcome) {
        let xi = x[v];
        let mw = self.masses[v] * self.w;
        let mut g = (xi - self.target[v]) * mw - self.load[v];
        let (mut h00, mut h01, mut h11) = (mw, 0.0, mw);
        // A grab's spring is one more quadratic term of the local potential.
        let spring = spring_of(self.springs, v);
        let mut spring_energy = 0.0;
        if let Some(s) = spring {
            g += (xi - s.goal) * s.stiffness;
            h00 += s.stiffness;
            h11 += s.stiffness;
            spring_energy = 0.5 * s.stiffness * (xi - s.goal).norm_squared();
        }
        // A vertex with contact pairs always searches its line: a Newton step on the log
        // barrier can overshoot towards it, and only the potential tells.
        let search = self.line_search || self.contact.is_some_and(|(c, _)| c.vertex_has_pairs(v));
        let mut elastic = 0.0;
        let mut elastic_magnitude = 0.0;
        // sum of M_e a_e over the fan (M_e the element's rest P-wave modulus).
        let mut local_scale = 0.0;
        // For the orientation test: per triangle, det F and w = cof(F) g, since moving the
        // vertex by s gives det(F + s g^T) = det F + s . w exactly (a rank-one update).
        let mut fan_det = [0.0; FAN];
        let mut fan_w = [Vec2::zeros(); FAN];
        let fan = self.adj.of(v);
        let cheap_orientation = self.forbids_inversion && !search && fan.len() <= FAN;
        // With the formulation, per triangle: (a/3) dtheta/dF g, its part of each of its
        // nodes' `V_n dtheta_n/dx_v`.
        let mut fan_dtheta = [Vec2::zeros(); FAN];
        for (i, &(t, corner)) in fan.iter().enumerate() {
            let el = &self.els[t as usize];
            let energy = el.energy(self.energy);
            local_scale += self.moduli[el.region as usize] * el.area;
            let f = deformation_gradient(el, x);
            // The formulation: the triangle keeps `psi - U(theta_e)`, its nodes take `U`.
            let vol = self.nodal.map(|nd| {
                let vol = nd.rings.volumetric[el.region as usize];
                (vol, vol.theta(&f))
            });
            if search {
                let psi = energy.psi(&f);
                match vol {
                    None => {
                        elastic += el.area * psi;
                        elastic_magnitude += el.area * psi.abs();
                    }
                    Some((vol, theta)) => {
                        let u = vol.u(theta);
                        elastic += el.area * deviatoric(psi, u);
                        elastic_magnitude += el.area * (psi.abs() + u);
                    }
                }
            }
            let ga = corner_gradient(el, corner);
            // P and the corner block sum_jl g_j dP_ij/dF_kl g_l in one call (closed forms
            // that share the energy's work, e.g. one polar decomposition).
            let (p, block) = energy.pk1_corner_block(&f, &ga);
            if cheap_orientation {
                fan_det[i] = f.determinant();
                fan_w[i] = Vec2::new(
                    f[(1, 1)] * ga.x - f[(1, 0)] * ga.y,
                    f[(0, 0)] * ga.y - f[(0, 1)] * ga.x,
                );
            }
            g += (p * ga) * el.area;
            let mut b = block * el.area;
            if let Some((vol, theta)) = vol {
                // Minus `U(theta_e)`'s gradient and block; `theta_e` is linear in one vertex's
                // position, so its curvature adds nothing to the block.
                let tg = vol.dtheta(&f) * ga;
                let (du, d2u) = du_d2u(&vol, theta);
                g -= tg * (du * el.area);
                b -= tg * tg.transpose() * (d2u * el.area);
                if i < FAN {
                    fan_dtheta[i] = tg * (el.area / 3.0);
                }
            }
            let (p00, p01, p11) = psd2(b[(0, 0)], 0.5 * (b[(0, 1)] + b[(1, 0)]), b[(1, 1)]);
            h00 += p00;
            h01 += p01;
            h11 += p11;
        }
        // The vertex block sees the patch: every node whose patch holds the vertex adds
        // `U'(theta_n) h` to the gradient and `U''(theta_n) / V_n h h^T` (clamped at zero) to
        // the block, `h = V_n dtheta_n/dx_v`.
        if let Some(nd) = self.nodal {
            for k in nd.rings.of(v) {
                let n = nd.rings.nodes[k] as usize;
                let mut h = Vec2::zeros();
                for &f in nd.rings.fan(k) {
                    let f = f as usize;
                    h += if f < FAN {
                        fan_dtheta[f]
                    } else {
                        self.fan_dtheta(v, f, x)
                    };
                }
                let vol = nd.rings.node_volumetric(n);
                let (theta, vn) = (m.node[n], nd.np.volume(n));
                let (du, d2u) = du_d2u(&vol, theta);
                g += h * du;
                let k = d2u.max(0.0) / vn;
                h00 += k * h.x * h.x;
                h01 += k * h.x * h.y;
                h11 += k * h.y * h.y;
                if search {
                    let u = vn * vol.u(theta);
                    elastic += u;
                    elastic_magnitude += u;
                }
            }
        }
        // Barrier and friction of the vertex's contact pairs, their block made positive
        // semi-definite like the triangles'.
        let mut contact_energy = 0.0;
        if let Some((c, _)) = self.contact {
            let (gc, [c00, c01, c11]) = c.vertex_terms(v, x);
            g += gc;
            let (p00, p01, p11) = psd2(c00, c01, c11);
            h00 += p00;
            h01 += p01;
            h11 += p11;
            if search {
                contact_energy = c.vertex_energy(v, x, xi);
            }
        }
        let gradient = g.norm();
        let mut out = Outcome {
            gradient,
            halved: false,
            rejected: false,
        };
        let det = h00 * h11 - h01 * h01;
        // A NaN gradient or block fails this test too: the vertex stays, the NaN is reported.
        if !(det > 0.0 && gradient.is_finite()) {
            out.rejected = gradient.is_finite();
            return (xi, out);
        }
        let mut step = Vec2::new(h11 * g.x - h01 * g.y, h00 * g.y - h01 * g.x) / -det;
        if let Some((c, cap)) = self.contact
            && c.on_boundary(v)
        {
            // No farther than the sweep's candidate pairs reach, and no crossing (CCD).
            let len = step.norm();
            if len > cap {
                step *= cap / len;
            }
            step *= c.vertex_max_step(v, x, step);
        }
        if !search && !self.forbids_inversion {
            return (xi + step, out);
        }
        // The starting value, in the same frame as `potential` (inertia and load from x[v]).
        let inertia = 0.5 * mw * (xi - self.target[v]).norm_squared() + spring_energy;
        let start = inertia + elastic + contact_energy;
        // The round-off of the local potential: eps times its terms, and psi's terms are of
        // the order of the modulus, not of psi (as in Newton's line search). A change below it
        // says nothing, and the step is taken when it is valid (finite).
        let floor = 1e-12 * (inertia + elastic_magnitude + local_scale);
        let mut fan_rate = [0.0; FAN];
        if cheap_orientation {
            for (r, w) in fan_rate.iter_mut().zip(&fan_w[..fan.len()]) {
                *r = step.dot(w);
            }
        }
        let mut alpha = 1.0;
        for k in 0..=LOCAL_HALVINGS {
            let p = xi + step * alpha;
            let ok = if search {
                let e = self.potential(v, x, p, m);
                e.is_finite() && e <= start + floor
            } else if cheap_orientation {
                fan_det[..fan.len()]
                    .iter()
                    .zip(&fan_rate)
                    .all(|(d, r)| d + alpha * r > 0.0)
            } else {
                self.keeps_orientation(v, x, p)
            };
            if ok {
                out.halved = k > 0;
                return (p, out);
            }
            alpha *= 0.5;
        }
        out.rejected = true;
        (xi, out)
    }

    /// The local potential of a free body at `pose` with its vertices placed in `x`, measured
    /// from its loads at `start` (the pose the update began at) as [`Local::potential`] is
    /// (with the formulation, its triangles' `psi - U` and its nodes' `V_n U(theta_n)` from the
    /// measures `m` of the start).
    fn body_potential(
        &self,
        blk: &BodyBlock,
        body: &RigidBody,
        (start, pose): (&BodyState, &BodyState),
        x: &[Vec2],
        m: &Measures,
    ) -> Real {
        let (tp, ta) = blk.target;
        let mut e = 0.5 * body.mass * self.w * (pose.position - tp).norm_squared()
            + 0.5 * body.inertia * self.w * (pose.angle - ta) * (pose.angle - ta);
        if !blk.forces.is_empty() {
            let frame = Frame::of(start);
            for &(v, f) in &blk.forces {
                let k = body
                    .vertices
                    .binary_search(&v)
                    .expect("a vertex of the body");
                e -= f.dot(&(x[v as usize] - frame.apply(body.offsets[k])));
            }
        }
        if !self.springs.is_empty() {
            for &v in &body.vertices {
                if let Some(s) = spring_of(self.springs, v as usize) {
                    e += 0.5 * s.stiffness * (x[v as usize] - s.goal).norm_squared();
                }
            }
        }
        for &(t, _) in &blk.elements {
            let el = &self.els[t as usize];
            let energy = el.energy(self.energy);
            let f = deformation_gradient(el, x);
            let psi = energy.psi(&f);
            e += el.area
                * match self.nodal {
                    None => psi,
                    Some(_) => {
                        let vol = energy.volumetric();
                        deviatoric(psi, vol.u(vol.theta(&f)))
                    }
                };
        }
        e + self.body_nodal_energy(blk, x, m)
    }

    /// `sum V_n U(theta_n)` over a free body's nodes at `x`, `theta_n` moved from the measures
    /// `m` by its triangles' change of `theta_e` (0 without the formulation).
    fn body_nodal_energy(&self, blk: &BodyBlock, x: &[Vec2], m: &Measures) -> Real {
        let Some(nd) = self.nodal else { return 0.0 };
        let mut e = 0.0;
        for (k, &n) in blk.nodes.iter().enumerate() {
            let n = n as usize;
            let mut d = 0.0;
            for &pos in blk.node_elements(k) {
                let t = blk.elements[pos as usize].0 as usize;
                d += self.els[t].area / 3.0 * (self.element_theta(nd, t, x) - m.element[t]);
            }
            let vn = nd.np.volume(n);
            e += vn * nd.rings.node_volumetric(n).u(m.node[n] + d / vn);
        }
        e
    }

    /// Triangle `t`'s `P` and area-weighted `dP/dF` under the formulation at `f`, the nodal
    /// pressures from the measures `m`: `P + c dtheta/dF` and
    /// `a (dP/dF - U''(theta_e) t t^T + c d2theta/dF2)` with `c = p_e - U'(theta_e)` (the
    /// element part of the Hessian, as fem-core's; projected when `projected`), and `a U(theta_e)`.
    fn pressure_element(
        &self,
        nd: Nodal<'_>,
        t: usize,
        f: &Mat2,
        m: &Measures,
        projected: bool,
    ) -> (Mat2, Mat4, Real) {
        let el = &self.els[t];
        let energy = el.energy(self.energy);
        let vol = energy.volumetric();
        let theta = vol.theta(f);
        let dt = vol.dtheta(f);
        let [a, b, c] = (nd.np.corner_nodes(t))
            .map(|n| nd.rings.node_volumetric(n as usize).du(m.node[n as usize]));
        let corr = (a + b + c) / 3.0 - vol.du(theta);
        let tv = vec(&dt);
        let d = energy.dpk1(f) - tv * tv.transpose() * vol.d2u(theta) + vol.d2theta() * corr;
        let d = match (projected, vol.measure()) {
            (false, _) => d,
            (true, VolumeMeasure::Determinant) => project_psd_isotropic(f, &d),
            (true, VolumeMeasure::Trace) => project_psd(&d),
        };
        (
            energy.pk1(f) + dt * corr,
            d * el.area,
            el.area * vol.u(theta),
        )
    }

    /// Add a free body's nodal terms `U''(theta_n) / V_n u u^T` to its 3x3 block `h`
    /// (`u = sum_a J_a^T h_n[a]` over the body's corners, `h_n = V_n dtheta_n/dx`; `U''` clamped
    /// at zero when `projected`). Nothing without the formulation.
    fn add_body_nodal_block(
        &self,
        blk: &BodyBlock,
        x: &[Vec2],
        p0: Vec2,
        m: &Measures,
        projected: bool,
        h: &mut Matrix3<Real>,
    ) {
        let Some(nd) = self.nodal else { return };
        for (k, &n) in blk.nodes.iter().enumerate() {
            let n = n as usize;
            let mut u = Vector3::zeros();
            for &pos in blk.node_elements(k) {
                let (t, mask) = blk.elements[pos as usize];
                let el = &self.els[t as usize];
                let vol = el.energy(self.energy).volumetric();
                let dt = vol.dtheta(&deformation_gradient(el, x));
                for corner in (0..3u8).filter(|k| mask & (1 << k) != 0) {
                    let w = dt * corner_gradient(el, corner) * (el.area / 3.0);
                    let r = x[el.idx[corner as usize] as usize] - p0;
                    u += Vector3::new(w.x, w.y, cross(r, w));
                }
            }
            let mut kn = nd.rings.node_volumetric(n).d2u(m.node[n]);
            if projected {
                kn = kn.max(0.0);
            }
            *h += u * u.transpose() * (kn / nd.np.volume(n));
        }
    }

    /// A free body's 3x3 block at positions `x` (centroid `p0`): its inertia, its grab springs,
    /// `sum J_a^T (dP/dF contracted) J_b` over the body's corners of each of its triangles
    /// (PSD-projected tangents when `projected`), and the rotation's curvature `-lever` where
    /// it is positive.
    #[allow(clippy::too_many_arguments)]
    fn body_block(
        &self,
        blk: &BodyBlock,
        body: &RigidBody,
        x: &[Vec2],
        p0: Vec2,
        lever: Real,
        projected: bool,
        m: &Measures,
    ) -> Matrix3<Real> {
        let (mw, iw) = (body.mass * self.w, body.inertia * self.w);
        let mut h = Matrix3::from_diagonal(&Vector3::new(mw, mw, iw));
        if !self.springs.is_empty() {
            for &v in &body.vertices {
                if let Some(s) = spring_of(self.springs, v as usize) {
                    let r = x[v as usize] - p0;
                    add_lever_block(&mut h, &(Mat2::identity() * s.stiffness), r, r);
                }
            }
        }
        for &(t, mask) in &blk.elements {
            let el = &self.els[t as usize];
            let energy = el.energy(self.energy);
            let f = deformation_gradient(el, x);
            let d = match self.nodal {
                Some(nd) => self.pressure_element(nd, t as usize, &f, m, projected).1,
                None if projected => energy.dpk1_projected(&f) * el.area,
                None => energy.dpk1(&f) * el.area,
            };
            let mut corners = [(Vec2::zeros(), Vec2::zeros()); 3];
            let mut n = 0;
            for k in 0..3u8 {
                if mask & (1 << k) != 0 {
                    corners[n] = (corner_gradient(el, k), x[el.idx[k as usize] as usize] - p0);
                    n += 1;
                }
            }
            for &(ga, ra) in &corners[..n] {
                for &(gb, rb) in &corners[..n] {
                    add_lever_block(&mut h, &contract_pair(&d, &ga, &gb), ra, rb);
                }
            }
        }
        self.add_body_nodal_block(blk, x, p0, m, projected, &mut h);
        if lever < 0.0 {
            h[(2, 2)] -= lever;
        }
        h
    }

    /// One Newton step on a free body's pose (see the module docs): `pose` moves and the
    /// body's vertices in `x` are placed on it. The outcome's gradient is the net force's norm.
    fn body_update(
        &self,
        blk: &BodyBlock,
        body: &RigidBody,
        pose: &mut BodyState,
        x: &mut [Vec2],
        m: &Measures,
    ) -> Outcome {
        let start = *pose;
        let p0 = start.position;
        let (tp, ta) = blk.target;
        let (mw, iw) = (body.mass * self.w, body.inertia * self.w);
        let mut g = Vector3::new(
            mw * (p0.x - tp.x),
            mw * (p0.y - tp.y),
            iw * (start.angle - ta),
        );
        let mut h = Matrix3::from_diagonal(&Vector3::new(mw, mw, iw));
        // sum_v g_v . (x_v - p): minus the rotation's curvature.
        let mut lever = 0.0;
        for &(v, f) in &blk.forces {
            add_lever_gradient(&mut g, &mut lever, -f, x[v as usize] - p0);
        }
        let mut spring_energy = 0.0;
        if !self.springs.is_empty() {
            for &v in &body.vertices {
                if let Some(s) = spring_of(self.springs, v as usize) {
                    let (xv, r) = (x[v as usize], x[v as usize] - p0);
                    add_lever_gradient(&mut g, &mut lever, (xv - s.goal) * s.stiffness, r);
                    add_lever_block(&mut h, &(Mat2::identity() * s.stiffness), r, r);
                    spring_energy += 0.5 * s.stiffness * (xv - s.goal).norm_squared();
                }
            }
        }
        let search = self.line_search;
        let (mut elastic, mut elastic_magnitude, mut local_scale) = (0.0, 0.0, 0.0);
        for &(t, mask) in &blk.elements {
            let el = &self.els[t as usize];
            let energy = el.energy(self.energy);
            local_scale += self.moduli[el.region as usize] * el.area;
            let f = deformation_gradient(el, x);
            // The exact tangent first (no eigen-decomposition per element: the body's
            // inertia usually keeps the 3x3 block positive definite); the projected one below
            // only when it does not. With the formulation, the element part of its Hessian.
            let (p, d, u) = match self.nodal {
                Some(nd) => self.pressure_element(nd, t as usize, &f, m, false),
                None => (energy.pk1(&f), energy.dpk1(&f) * el.area, 0.0),
            };
            if search {
                let psi = el.area * energy.psi(&f);
                elastic += deviatoric(psi, u);
                elastic_magnitude += psi.abs() + u;
            }
            let mut corners = [(Vec2::zeros(), Vec2::zeros()); 3];
            let mut n = 0;
            for k in 0..3u8 {
                if mask & (1 << k) != 0 {
                    let ga = corner_gradient(el, k);
                    let r = x[el.idx[k as usize] as usize] - p0;
                    add_lever_gradient(&mut g, &mut lever, (p * ga) * el.area, r);
                    corners[n] = (ga, r);
                    n += 1;
                }
            }
            for &(ga, ra) in &corners[..n] {
                for &(gb, rb) in &corners[..n] {
                    add_lever_block(&mut h, &contract_pair(&d, &ga, &gb), ra, rb);
                }
            }
        }
        self.add_body_nodal_block(blk, x, p0, m, false, &mut h);
        if search {
            let u = self.body_nodal_energy(blk, x, m);
            elastic += u;
            elastic_magnitude += u;
        }
        if lever < 0.0 {
            h[(2, 2)] -= lever;
        }
        if h.cholesky().is_none() {
            // Indefinite with the exact tangents: rebuild the block from PSD-projected ones.
            h = self.body_block(blk, body, x, p0, lever, true, m);
        }
        let gradient = Vec2::new(g.x, g.y).norm();
        let mut out = Outcome {
            gradient,
            halved: false,
            rejected: false,
        };
        let finite = gradient.is_finite() && g.z.is_finite();
        // A NaN gradient or matrix fails here too: the body stays, the NaN is reported.
        let Some(chol) = h.cholesky().filter(|_| finite) else {
            out.rejected = finite;
            return out;
        };
        let step = -chol.solve(&g);
        let trial = |alpha: Real| BodyState {
            position: p0 + Vec2::new(step.x, step.y) * alpha,
            angle: start.angle + step.z * alpha,
            ..start
        };
        if !search && !self.forbids_inversion {
            *pose = trial(1.0);
            body.place_positions(pose, x);
            return out;
        }
        let inertia = 0.5 * mw * (p0 - tp).norm_squared()
            + 0.5 * iw * (start.angle - ta) * (start.angle - ta)
            + spring_energy;
        let start_value = inertia + elastic;
        let floor = 1e-12 * (inertia + elastic_magnitude + local_scale);
        let mut alpha = 1.0;
        for k in 0..=LOCAL_HALVINGS {
            let q = trial(alpha);
            body.place_positions(&q, x);
            let ok = if search {
                let e = self.body_potential(blk, body, (&start, &q), x, m);
                e.is_finite() && e <= start_value + floor
            } else {
                (blk.elements.iter()).all(|&(t, _)| {
                    deformation_gradient(&self.els[t as usize], x).determinant() > 0.0
                })
            };
            if ok {
                *pose = q;
                out.halved = k > 0;
                return out;
            }
            alpha *= 0.5;
        }
        body.place_positions(&start, x);
        out.rejected = true;
        out
    }
}

/// The free bodies' steps of one sweep, in order (each body's move updates the formulation's
/// measures `m` before the next one reads them); returns the largest net force seen (NaN if
/// any was NaN), merged with `largest`.
#[allow(clippy::too_many_arguments)]
fn body_sweep<E: Energy>(
    local: &Local<'_, E>,
    blocks: &[BodyBlock],
    bodies: &[RigidBody],
    poses: &mut [BodyState],
    x: &mut [Vec2],
    m: &mut Measures,
    stats: &mut VbdStats,
    mut largest: Real,
) -> Real {
    for blk in blocks {
        let o = local.body_update(blk, &bodies[blk.body], &mut poses[blk.body], x, m);
        local.measure_body(blk, x, m);
        if o.gradient.is_nan() || largest.is_nan() {
            largest = Real::NAN;
        } else {
            largest = largest.max(o.gradient);
        }
        stats.halved += usize::from(o.halved);
        stats.rejected += usize::from(o.rejected);
    }
    largest
}

/// The residual test of a substep: the norm of the gradient of its incremental potential at
/// `x` over the free degrees of freedom, N, the potential VBD descends: the free vertices
/// `free` (inertia with weight `w = 1 / h^2` about `target`, the load `load`, the elastic
/// forces, the grab's springs, and the barrier and friction terms of their contact pairs), each
/// free body of `blocks` at its pose in `poses` as its three reduced components
/// `sum_v J_v^T g_v` plus its inertia (its slaved vertices' contact ignored, as its block
/// ignores it), and the moving obstacles' poses (their inertia or tether, weight, and contact).
/// With `elastic`, also the norm of the elastic forces on the free vertices and the free
/// bodies' vertices (the force scale's third term), else 0. Every sum runs in a fixed order
/// (the elastic forces are fem-core's, bit-identical for any thread count); nothing is
/// allocated after the first call.
#[allow(clippy::too_many_arguments)]
fn gradient_norm<E: Energy>(
    model: &Model<E>,
    x: &[Vec2],
    (w, target, load): (Real, &[Vec2], &[Vec2]),
    free: &[u32],
    blocks: &[BodyBlock],
    poses: &[BodyState],
    contact: Option<&mut BarrierContact>,
    buf: &mut GradientBuffers,
    elastic: bool,
) -> (Real, Real) {
    let forces = &mut buf.forces;
    populate_forces(
        model.elastic_mesh(),
        model.elastic_energies(),
        x,
        forces,
        &mut buf.scratch,
    );
    let (masses, springs) = (model.masses(), model.springs());
    let mut elastic_sq = 0.0;
    if elastic {
        for &v in free {
            elastic_sq += forces[v as usize].norm_squared();
        }
    }
    let mut sq = 0.0;
    for blk in blocks {
        let body = &model.rigid_bodies()[blk.body];
        let pose = &poses[blk.body];
        let p0 = pose.position;
        let (tp, ta) = blk.target;
        let (mw, iw) = (body.mass * w, body.inertia * w);
        let mut g = Vector3::new(
            mw * (p0.x - tp.x),
            mw * (p0.y - tp.y),
            iw * (pose.angle - ta),
        );
        let mut lever = 0.0;
        for &(v, f) in &blk.forces {
            add_lever_gradient(&mut g, &mut lever, -f, x[v as usize] - p0);
        }
        for &v in &body.vertices {
            let (xv, f) = (x[v as usize], forces[v as usize]);
            let mut gv = -f;
            if let Some(s) = spring_of(springs, v as usize) {
                gv += (xv - s.goal) * s.stiffness;
            }
            add_lever_gradient(&mut g, &mut lever, gv, xv - p0);
            if elastic {
                elastic_sq += f.norm_squared();
            }
        }
        sq += g.norm_squared();
    }
    if let Some(c) = contact {
        let extra = &mut buf.extra;
        extra.clear();
        extra.resize(c.n_extra(), 0.0);
        c.gradient(x, &mut |d, g| match d {
            // As a force, with the elastic ones (read below for the free vertices only).
            Dof::Soft(i) => forces[i / 2][i % 2] -= g,
            Dof::Extra(k) => extra[k] += g,
        });
        sq += extra.iter().map(|g| g * g).sum::<Real>();
    }
    for &v in free {
        let v = v as usize;
        let mut g = (x[v] - target[v]) * (masses[v] * w) - load[v] - forces[v];
        if let Some(s) = spring_of(springs, v) {
            g += (x[v] - s.goal) * s.stiffness;
        }
        sq += g.norm_squared();
    }
    (sq.sqrt(), elastic_sq.sqrt())
}

/// The end of a step of the solvers that minimise implicit Euler's potential by iterations
/// (VBD, Projective Dynamics, quasi-Newton): the inversion statistics of the new positions
/// `x`, the velocities `(x - x_t) / h` (with `prev`, the positions at the start of the previous
/// step: BDF2's `(3 x - 4 x_t + x_prev) / (2h)`) damped by `decay` into `v_new`, and the commit
/// (kinematic vertices on their schedule over `[t, t + h]` of a step that ends at `until`).
/// Returns the statistics.
#[allow(clippy::too_many_arguments)]
pub(crate) fn commit_positions<E: Energy>(
    model: &Model<E>,
    state: &mut State,
    els: &[PackedElement],
    x: &mut Vec<Vec2>,
    v_new: &mut Vec<Vec2>,
    bodies: Option<&mut Vec<BodyState>>,
    rigid: Option<&mut Vec<BodyState>>,
    h: Real,
    until: Real,
    decay: Real,
    count_step: bool,
    prev: Option<&[Vec2]>,
) -> Result<Inversion, SolverError> {
    let inv = inversion(els, x);
    match prev {
        Some(prev) => {
            for (i, v) in v_new.iter_mut().enumerate() {
                *v = bdf2_velocity(x[i], state.x[i], prev[i], h) * decay;
            }
        }
        None => {
            for ((v, xn), x0) in v_new.iter_mut().zip(x.iter()).zip(&state.x) {
                *v = (xn - x0) / h * decay;
            }
        }
    }
    let t = state.t;
    StepEnd {
        kinematics: Kinematic::Schedule { t, dt: h, until },
        x,
        v: v_new,
        bodies,
        rigid,
        known_finite: false,
        inverted: inv.inverted,
        min_det_f: inv.min_det_f,
        t_end: t + h,
        count_step,
    }
    .commit(model, state, || Ok(()))?;
    Ok(inv)
}

/// Smallest `det F` and inverted triangles of `els` at `x` (exact, so the same for any split).
pub(crate) fn inversion(els: &[PackedElement], x: &[Vec2]) -> Inversion {
    els.par_chunks(ELEMENT_CHUNK)
        .map(|chunk| {
            let mut s = Inversion::EMPTY;
            for el in chunk {
                s.add(deformation_gradient(el, x).determinant());
            }
            s
        })
        .reduce(|| Inversion::EMPTY, Inversion::merge)
}

impl VbdStepper {
    /// A stepper for `model`: validates the parameters, sets up barrier contact, packs the
    /// elements (of the elastic mesh) and colours the free vertices.
    pub fn new<E: Energy>(model: &Model<E>, params: VbdParams) -> Result<Self, SolverError> {
        params.validate()?;
        // With rigid regions, the deformable triangles only (the same vertices).
        let mesh = model.elastic_mesh();
        let n = mesh.n_vertices();
        let mut free = vec![true; n];
        for v in model.kinematics().vertices() {
            free[v] = false;
        }
        let np = model.elastic_energies().nodal_pressure();
        // With the averaged nodal pressure triangle a vertex's local energy reads the nodal
        // volumes of its ring, which every vertex of the ring's patches moves: no two vertices
        // of one colour may share a patch.
        let colouring = match np {
            Some(np) => VertexColouring::greedy_patches(mesh, np, &free),
            None => VertexColouring::greedy(mesh, &free),
        };
        let slots = colouring.order.len();
        let h = params.dt / params.substeps as Real;
        let contact = model.has_contact().then(|| {
            let mut c = BarrierContact::new(model, model.contact_params().friction_velocity * h);
            c.set_margin(CONTACT_MARGIN * model.contact_params().barrier_distance);
            // A rigid tether would drive a kinematic obstacle into its barrier faster than
            // vertex-by-vertex sweeps let the body answer (the gap collapses and both sides
            // jam): tether at ten times the body's modulus, so a contact force F lags the
            // obstacle F / (10 M) behind its schedule (it catches up when the force goes).
            c.set_tether(10.0 * model.p_wave_modulus());
            c
        });
        let els = pack(mesh, model.elastic_energies().tags());
        let blocks = (model.rigid_bodies().iter().enumerate())
            .filter(|(_, body)| body.is_free())
            .map(|(b, body)| {
                let mut touching: Vec<u32> = (body.interface.iter())
                    .flat_map(|&v| mesh.adjacency().of(v as usize).iter().map(|&(t, _)| t))
                    .collect();
                touching.sort_unstable();
                touching.dedup();
                let elements: Vec<(u32, u8)> = (touching.into_iter())
                    .map(|t| {
                        let idx = els[t as usize].idx;
                        let mask = (0..3)
                            .filter(|&k| model.rigid_body_of(idx[k] as usize) == Some(b))
                            .fold(0u8, |m, k| m | (1 << k));
                        (t, mask)
                    })
                    .collect();
                // The nodes of the body's triangles, each with its triangles among them.
                let mut pairs: Vec<(u32, u32)> = (elements.iter().enumerate())
                    .flat_map(|(pos, &(t, _))| {
                        let nodes = np.map(|np| np.corner_nodes(t as usize));
                        nodes.into_iter().flatten().map(move |n| (n, pos as u32))
                    })
                    .collect();
                pairs.sort_unstable();
                let (mut nodes, mut node_offsets, mut node_elements) =
                    (Vec::new(), vec![0u32], Vec::new());
                for group in pairs.chunk_by(|a, b| a.0 == b.0) {
                    nodes.push(group[0].0);
                    node_elements.extend(group.iter().map(|&(_, pos)| pos));
                    node_offsets.push(node_elements.len() as u32);
                }
                BodyBlock {
                    body: b,
                    elements,
                    forces: Vec::new(),
                    target: (Vec2::zeros(), 0.0),
                    nodes,
                    node_offsets,
                    node_elements,
                }
            })
            .collect();
        let rings = np.map_or_else(Rings::default, |np| {
            Rings::new(mesh, np, model.elastic_energies(), &els)
        });
        Ok(VbdStepper {
            blocks,
            rigid_new: Vec::new(),
            rigid_prev: Vec::new(),
            contact,
            targets: Vec::new(),
            bodies_new: Vec::new(),
            min_distance: Real::INFINITY,
            h,
            decay: exp(-params.damping * h),
            params,
            n_triangles: model.mesh().n_triangles(),
            els,
            moduli: (model.elastic_energies().energies().iter())
                .map(|e| e.dpk1(&Mat2::identity())[(0, 0)].abs())
                .collect(),
            colouring,
            forbids_inversion: forbids_inversion(model.energy()),
            target: vec![Vec2::zeros(); n],
            load: vec![Vec2::zeros(); n],
            x: vec![Vec2::zeros(); n],
            v_new: vec![Vec2::zeros(); n],
            buf: vec![Vec2::zeros(); slots],
            outcome: vec![Outcome::default(); slots],
            chebyshev: Chebyshev::default(),
            v_prev: None,
            stats: VbdStats::default(),
            layout: model.layout(),
            gradient: GradientBuffers {
                forces: if params.tolerance > 0.0 {
                    vec![Vec2::zeros(); n]
                } else {
                    Vec::new()
                },
                ..GradientBuffers::default()
            },
            history: History::new(params.integrator),
            last_bdf2: 0,
            rings,
            measures: Measures {
                element: vec![0.0; if np.is_some() { mesh.n_triangles() } else { 0 }],
                node: vec![0.0; np.map_or(0, NodalPressure::n_nodes)],
            },
        })
    }

    /// The parameters.
    pub fn params(&self) -> &VbdParams {
        &self.params
    }

    /// Number of vertex colours (sequential phases of a sweep).
    pub fn n_colours(&self) -> usize {
        self.colouring.n_colours()
    }

    /// The colouring of the free vertices: no two of a colour share a triangle, nor, with the
    /// averaged nodal pressure triangle, a node's patch.
    pub fn colouring(&self) -> &VertexColouring {
        &self.colouring
    }

    /// What the last step did.
    pub fn last_stats(&self) -> VbdStats {
        self.stats
    }

    /// The smallest distance between the soft body and the ground or an obstacle over the
    /// candidate pairs at the end of the last step, m (infinite when nothing is near, or
    /// without contact). Barrier contact keeps it positive.
    pub fn min_distance(&self) -> Real {
        self.min_distance
    }

    /// Forget the previous step's velocity (the adaptive guess then starts afresh) and, under
    /// BDF2, the previous state (the next step is backward Euler), e.g. after the state was
    /// replaced. (A BDF2 stepper also notices a replaced state by itself.)
    pub fn reset(&mut self) {
        self.v_prev = None;
        self.history.clear();
    }

    /// How many substeps of the last step were BDF2 steps (0 under backward Euler; see
    /// [`crate::integrator`]).
    pub fn last_bdf2_substeps(&self) -> usize {
        self.last_bdf2
    }

    /// The free bodies' loads, inertial targets and first poses of a substep (see the module
    /// docs) into `self.blocks` and `self.rigid_new`, their vertices placed in `self.x`.
    /// `previous`: every body starts at its pose (with contact, or after a guess that inverted
    /// a triangle). `bdf2`: BDF2's targets (from the history), with `hh = 4 h^2 / 9` in place
    /// of `h^2`.
    fn body_guesses<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &State,
        previous: bool,
        bdf2: bool,
    ) {
        let h = self.h;
        let gravity = model.gravity();
        self.rigid_new.clone_from(&state.rigid);
        let have_prev = self.v_prev.is_some() && self.rigid_prev.len() == state.rigid.len();
        for blk in &mut self.blocks {
            let k = blk.body;
            let body = &model.rigid_bodies()[k];
            let s = state.rigid[k];
            blk.forces.clear();
            blk.forces.extend(
                (model.external_forces().iter())
                    .filter(|(v, _)| model.rigid_body_of(*v as usize) == Some(k)),
            );
            let (mut force, mut torque) = (Vec2::zeros(), 0.0);
            for &(v, f) in &blk.forces {
                force += f;
                torque += cross(state.x[v as usize] - s.position, f);
            }
            let (y, hh) = if bdf2 {
                let [x, y, a] = bdf2_pose_target(&s, &self.history.prev.rigid[k], h);
                let hh = 1.0 / bdf2_weight(h);
                blk.target = (Vec2::new(x, y) + gravity * hh, a);
                (Vec2::new(x, y), hh)
            } else {
                let y = s.position + s.velocity * h;
                blk.target = (y + gravity * (h * h), s.angle + s.angular_velocity * h);
                (y, h * h)
            };
            let (position, angle) = match self.params.init {
                _ if previous => (s.position, s.angle),
                VbdInit::Previous => (s.position, s.angle),
                VbdInit::Inertia => (
                    blk.target.0 + force * (hh / body.mass),
                    blk.target.1 + torque * (hh / body.inertia),
                ),
                VbdInit::Adaptive => {
                    let a_ext = gravity + force / body.mass;
                    let norm = a_ext.norm();
                    let along = if norm > 0.0 {
                        let dir = a_ext / norm;
                        let along = if have_prev {
                            ((s.velocity - self.rigid_prev[k]) / h)
                                .dot(&dir)
                                .clamp(0.0, norm)
                        } else {
                            norm
                        };
                        dir * along
                    } else {
                        Vec2::zeros()
                    };
                    (y + along * hh, blk.target.1)
                }
            };
            let pose = &mut self.rigid_new[k];
            pose.position = position;
            pose.angle = angle;
            body.place_positions(pose, &mut self.x);
        }
    }

    /// The initial guess of a substep into `self.x` (free vertices; kinematic ones are placed
    /// by the caller); `hh` is `h^2` (BDF2: `4 h^2 / 9`, the inverse of the inertia weight).
    fn initial_guess<E: Energy>(&mut self, model: &Model<E>, state: &State, hh: Real) {
        let h = self.h;
        let masses = model.masses();
        match self.params.init {
            VbdInit::Previous => self.x.copy_from_slice(&state.x),
            VbdInit::Inertia => {
                for (i, x) in self.x.iter_mut().enumerate() {
                    *x = self.target[i] + self.load[i] * (hh / masses[i]);
                }
            }
            VbdInit::Adaptive => {
                for (i, x) in self.x.iter_mut().enumerate() {
                    let a_ext = self.load[i] / masses[i];
                    let norm = a_ext.norm();
                    let along = if norm > 0.0 {
                        let dir = a_ext / norm;
                        let along = match &self.v_prev {
                            Some(vp) => ((state.v[i] - vp[i]) / h).dot(&dir).clamp(0.0, norm),
                            None => norm,
                        };
                        dir * along
                    } else {
                        Vec2::zeros()
                    };
                    *x = self.target[i] + along * hh;
                }
            }
        }
    }
}

/// One sweep over the colours of `c`, moving `x` (and, with the formulation, keeping the
/// measures `m` of the moved vertices' triangles and rings current after each colour);
/// returns the largest gradient norm seen (NaN if any was NaN).
fn sweep<E: Energy>(
    local: &Local<'_, E>,
    c: &VertexColouring,
    x: &mut [Vec2],
    (buf, outcome): (&mut [Vec2], &mut [Outcome]),
    m: &mut Measures,
    stats: &mut VbdStats,
) -> Real {
    let mut largest: Real = 0.0;
    let nodal = local.nodal.is_some();
    for k in 0..c.n_colours() {
        let (a, b) = (c.offsets[k], c.offsets[k + 1]);
        let order = &c.order[a..b];
        let (xr, mr) = (&*x, &*m);
        buf[a..b]
            .par_chunks_mut(VBD_CHUNK)
            .zip(outcome[a..b].par_chunks_mut(VBD_CHUNK))
            .zip(order.par_chunks(VBD_CHUNK))
            .for_each(|((buf, outcome), order)| {
                for ((p, o), &v) in buf.iter_mut().zip(outcome.iter_mut()).zip(order) {
                    (*p, *o) = local.update(v as usize, xr, mr);
                }
            });
        for ((&v, p), o) in order.iter().zip(&buf[a..b]).zip(&outcome[a..b]) {
            // No two vertices of a colour share a node's patch: each one's triangles and ring
            // are its own, so the order of these updates does not matter.
            if nodal && x[v as usize] != *p {
                x[v as usize] = *p;
                local.measure_vertex(v as usize, x, m);
            }
            x[v as usize] = *p;
            if o.gradient.is_nan() || largest.is_nan() {
                largest = Real::NAN;
            } else {
                largest = largest.max(o.gradient);
            }
            stats.halved += usize::from(o.halved);
            stats.rejected += usize::from(o.rejected);
        }
    }
    largest
}

/// Chebyshev's iterates: the positions after sweeps `k - 2` and `k - 1`, the plain result of
/// sweep `k`, and the sequence's state.
#[derive(Debug, Default)]
pub(crate) struct Chebyshev {
    prev: Vec<Vec2>,
    last: Vec<Vec2>,
    plain: Vec<Vec2>,
    /// Sweeps in the current sequence.
    k: usize,
    omega: Real,
}

impl Chebyshev {
    /// Start a sequence at `x`.
    pub(crate) fn start(&mut self, x: &[Vec2]) {
        if self.prev.len() != x.len() {
            self.prev = vec![Vec2::zeros(); x.len()];
            self.last = vec![Vec2::zeros(); x.len()];
            self.plain = vec![Vec2::zeros(); x.len()];
        }
        self.last.copy_from_slice(x);
        self.k = 0;
        self.omega = 1.0;
    }

    /// Extrapolate the free vertices (`free`) of `x`, just iterated; an extrapolation that
    /// inverts a triangle (when `forbids_inversion`) is dropped and the sequence restarts
    /// (returns true).
    pub(crate) fn apply(
        &mut self,
        rho: Real,
        x: &mut [Vec2],
        free: &[u32],
        els: &[PackedElement],
        forbids_inversion: bool,
    ) -> bool {
        self.k += 1;
        self.omega = match self.k {
            1 => 1.0,
            2 => 2.0 / (2.0 - rho * rho),
            _ => 4.0 / (4.0 - rho * rho * self.omega),
        };
        if self.k > 1 {
            self.plain.copy_from_slice(x);
            for &v in free {
                let v = v as usize;
                x[v] = (x[v] - self.prev[v]) * self.omega + self.prev[v];
            }
            if forbids_inversion && inversion(els, x).inverted > 0 {
                x.copy_from_slice(&self.plain);
                self.start(x);
                return true;
            }
        }
        // x_{k-2} <- x_{k-1}; x_{k-1} <- x_k.
        std::mem::swap(&mut self.prev, &mut self.last);
        self.last.copy_from_slice(x);
        false
    }
}

impl Stepper for VbdStepper {
    fn dt(&self) -> Real {
        self.params.dt
    }

    fn step<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError> {
        check_step_inputs(model, self.n_triangles, state)?;
        if model.layout() != self.layout {
            // The free vertices changed (a pinning grab): colour them again.
            let v_prev = self.v_prev.take();
            let rigid_prev = std::mem::take(&mut self.rigid_prev);
            *self = VbdStepper::new(model, self.params)?;
            self.v_prev = v_prev;
            self.rigid_prev = rigid_prev;
        }
        let until = state.t + self.params.dt;
        let h = self.h;
        let n = model.mesh().n_vertices();
        let rho = self.params.chebyshev_rho;
        let tolerance = self.params.tolerance;
        let mut stats = VbdStats::default();
        let mut residual = 0.0;
        let mut sweeps = 0;
        let mut inv = Inversion::EMPTY;
        external_load(model, &mut self.load);
        self.last_bdf2 = 0;
        for sub in 0..self.params.substeps {
            let t = state.t;
            let bdf2 = self.history.begin(state, h, model.layout());
            // The inertia weight and its inverse: backward Euler's `1/h^2`, or BDF2's
            // `9/(4 h^2)`.
            let (w, hh) = self.history.targets(bdf2, state, h, &mut self.target);
            self.initial_guess(model, state, hh);
            let kinematics = model.kinematics();
            kinematics.apply(t, h, until, &state.x, &mut self.x, &mut self.v_new);
            let rigid = !self.blocks.is_empty();
            if rigid {
                self.body_guesses(model, state, self.contact.is_some(), bdf2);
            }
            if self.forbids_inversion && inversion(&self.els, &self.x).inverted > 0 {
                self.x.copy_from_slice(&state.x);
                kinematics.apply(t, h, until, &state.x, &mut self.x, &mut self.v_new);
                if rigid {
                    self.body_guesses(model, state, true, bdf2);
                }
                stats.fallback_guess = true;
            }
            if let Some(c) = self.contact.as_mut() {
                start_contact(
                    c,
                    model,
                    state,
                    h,
                    (w, bdf2.then_some(&self.history.prev.bodies[..])),
                    &mut self.targets,
                    &mut self.x,
                    &mut self.v_new,
                )?;
            }
            let cap = self
                .contact
                .as_ref()
                .map_or(0.0, |c| (CONTACT_MARGIN - 1.0) * c.d_hat());
            let local = Local {
                energy: model.elastic_energies(),
                els: &self.els,
                adj: model.elastic_mesh().adjacency(),
                masses: model.masses(),
                w,
                target: &self.target,
                load: &self.load,
                line_search: self.params.line_search,
                forbids_inversion: self.forbids_inversion,
                moduli: &self.moduli,
                springs: model.springs(),
                contact: None,
                nodal: (model.elastic_energies().nodal_pressure()).map(|np| Nodal {
                    np,
                    rings: &self.rings,
                }),
            };
            // The formulation's measures at the initial guess.
            local.measure_all(&self.x, &mut self.measures);
            // Chebyshev's extrapolation could carry a vertex across an obstacle: off with
            // contact.
            let rho = if self.contact.is_some() { 0.0 } else { rho };
            if rho > 0.0 {
                self.chebyshev.start(&self.x);
            }
            // The residual test (tolerance > 0 only): the gradient's norm at the initial guess
            // sets the force scale, and may already meet it.
            let mut goal = 0.0;
            let mut converged = false;
            if tolerance > 0.0 {
                let (first, elastic) = gradient_norm(
                    model,
                    &self.x,
                    (w, &self.target, &self.load),
                    &self.colouring.order,
                    &self.blocks,
                    &self.rigid_new,
                    self.contact.as_mut(),
                    &mut self.gradient,
                    true,
                );
                stats.force_scale = force_scale(first, &self.load, elastic);
                goal = tolerance * stats.force_scale;
                residual = first;
                converged = first <= goal;
            }
            for _ in 0..self.params.iterations {
                if converged {
                    break;
                }
                if let Some(c) = self.contact.as_mut() {
                    c.prepare(&self.x, None);
                    c.index_vertices(n);
                }
                let with_contact = Local {
                    contact: self.contact.as_ref().map(|c| (c, cap)),
                    ..local
                };
                residual = sweep(
                    &with_contact,
                    &self.colouring,
                    &mut self.x,
                    (&mut self.buf, &mut self.outcome),
                    &mut self.measures,
                    &mut stats,
                );
                if rigid {
                    // The free bodies, one after another, after the colours.
                    residual = body_sweep(
                        &with_contact,
                        &self.blocks,
                        model.rigid_bodies(),
                        &mut self.rigid_new,
                        &mut self.x,
                        &mut self.measures,
                        &mut stats,
                        residual,
                    );
                }
                if let Some(c) = self.contact.as_mut() {
                    // The moving obstacles' poses: one block Newton step each sweep.
                    c.prepare(&self.x, None);
                    c.body_step(&self.x, cap);
                }
                if rho > 0.0 {
                    let restarted = self.chebyshev.apply(
                        rho,
                        &mut self.x,
                        &self.colouring.order,
                        &self.els,
                        self.forbids_inversion,
                    );
                    stats.chebyshev_restarts += usize::from(restarted);
                    // Every free vertex moved (the measures read no contact).
                    local.measure_all(&self.x, &mut self.measures);
                }
                sweeps += 1;
                if tolerance > 0.0 {
                    residual = gradient_norm(
                        model,
                        &self.x,
                        (w, &self.target, &self.load),
                        &self.colouring.order,
                        &self.blocks,
                        &self.rigid_new,
                        self.contact.as_mut(),
                        &mut self.gradient,
                        false,
                    )
                    .0;
                    converged = residual <= goal;
                }
            }
            // The adaptive guess of the next substep reads this substep's starting velocity.
            let prev_v = self.v_prev.get_or_insert_with(|| vec![Vec2::zeros(); n]);
            prev_v.copy_from_slice(&state.v);
            if rigid {
                self.rigid_prev.clear();
                self.rigid_prev
                    .extend(state.rigid.iter().map(|b| b.velocity));
                // The bodies' velocities, as the vertices' (`commit_positions`).
                for blk in &self.blocks {
                    let (s, b) = (&state.rigid[blk.body], &mut self.rigid_new[blk.body]);
                    if bdf2 {
                        bdf2_body_velocity(b, s, &self.history.prev.rigid[blk.body], h);
                        b.velocity *= self.decay;
                        b.angular_velocity *= self.decay;
                    } else {
                        b.velocity = (b.position - s.position) / h * self.decay;
                        b.angular_velocity = (b.angle - s.angle) / h * self.decay;
                    }
                }
            }
            let bodies = match self.contact.as_mut() {
                Some(c) => {
                    end_poses(c, model, state, h, &mut self.bodies_new);
                    if bdf2 {
                        let prev = &self.history.prev.bodies;
                        bdf2_obstacle_velocities(
                            model,
                            &state.bodies,
                            prev,
                            h,
                            &mut self.bodies_new,
                        );
                    }
                    self.min_distance = c.record(&self.x);
                    Some(&mut self.bodies_new)
                }
                None => None,
            };
            inv = commit_positions(
                model,
                state,
                &self.els,
                &mut self.x,
                &mut self.v_new,
                bodies,
                rigid.then_some(&mut self.rigid_new),
                h,
                until,
                self.decay,
                sub + 1 == self.params.substeps,
                bdf2.then_some(&self.history.prev.x[..]),
            )?;
            self.history.commit(state);
            self.last_bdf2 += usize::from(bdf2);
        }
        self.stats = stats;
        Ok(StepReport {
            min_det_f: inv.min_det_f,
            inverted: inv.inverted,
            iterations: sweeps,
            residual,
            contacts: self.contacts().len(),
        })
    }

    fn contacts(&self) -> &[Contact] {
        match &self.contact {
            Some(c) => c.contacts(),
            None => &[],
        }
    }
}

/// Candidate pairs reach `CONTACT_MARGIN d_hat`; a boundary vertex (or an obstacle) moves at
/// most `(CONTACT_MARGIN - 1) d_hat` between two broad phases, so no pair outside the list can
/// come within `d_hat`.
const CONTACT_MARGIN: Real = 3.0;

/// The start of a substep with barrier contact: the obstacles' targets (inertial predictions
/// of dynamic bodies, the schedule's poses of kinematic ones) and lagged friction, the start
/// checked apart, and the initial guess `x` (and the obstacles' poses) moved from the state
/// towards it only as far as the CCD allows. `weight` is the inertia weight (`1/h^2`, BDF2's
/// `9/(4 h^2)`) and `prev`, under BDF2, the obstacles' states at the start of the previous
/// substep (BDF2's targets). `scratch` is a buffer of vertex vectors.
#[allow(clippy::too_many_arguments)]
pub(crate) fn start_contact<E: Energy>(
    c: &mut BarrierContact,
    model: &Model<E>,
    state: &State,
    h: Real,
    (weight, prev): (Real, Option<&[BodyState]>),
    targets: &mut Vec<[Real; 3]>,
    x: &mut [Vec2],
    scratch: &mut [Vec2],
) -> Result<(), SolverError> {
    step_targets(model, state, h, targets);
    if let Some(prev) = prev {
        bdf2_obstacle_targets(model, &state.bodies, prev, h, targets);
    }
    c.begin(&state.x, &state.bodies, targets, weight, model.gravity());
    if let Some(at) = c.start_overlap(&state.x) {
        return Err(SolverError::invalid(
            "vbd.contact",
            at,
            "barrier contact needs every soft vertex and obstacle apart at the start of a step (start the body above the ground and clear of obstacles)",
        ));
    }
    c.aim_at_targets();
    for ((d, xg), x0) in scratch.iter_mut().zip(x.iter()).zip(&state.x) {
        *d = xg - x0;
    }
    let limit = c.rotation_limit(&state.x);
    for d in scratch.iter_mut() {
        *d *= limit;
    }
    for d in c.dq.iter_mut() {
        *d *= limit;
    }
    c.prepare(&state.x, Some(scratch));
    // Half of each gap at most, as for the obstacles' steps within the sweeps (see
    // `BarrierContact::body_step`).
    let alpha = c.max_step_with(&state.x, scratch, 0.5);
    for ((xn, x0), d) in x.iter_mut().zip(&state.x).zip(scratch.iter()) {
        *xn = x0 + d * alpha;
    }
    let mut q = Vec::new();
    c.trial_poses(alpha, &mut q);
    c.q = q;
    Ok(())
}

impl Solver for VbdStepper {
    type Params = VbdParams;
    const NAME: &'static str = "vbd";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "VBD",
        summary: "Vertex Block Descent: Gauss-Seidel over vertices on implicit Euler's incremental potential, a 2x2 (3D: 3x3) Newton step each, vertex colouring",
        paper: false,
        contact: true,
        rigid_regions: true,
        averaged_pressure: true,
        dims: 3,
        implicit: true,
        iterations: true,
        substeps: true,
        factorisation: false,
        deterministic_across_threads: true,
        clock: Clock::Time,
        converges_to: "each step to implicit Euler's (BDF2's with integrator = bdf2) as iterations grow (monotone descent of the same incremental potential, Gauss-Seidel's linear rate)",
    };

    fn validate_params(p: &VbdParams, prefix: &str) -> Result<(), SolverError> {
        p.validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &VbdParams) -> Result<Self, SolverError> {
        VbdStepper::new(model, *p)
    }

    fn dt_mut(p: &mut VbdParams) -> Option<&mut Real> {
        Some(&mut p.dt)
    }

    fn integrator_mut(p: &mut VbdParams) -> Option<&mut Integrator> {
        Some(&mut p.integrator)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psd2_keeps_positive_matrices_and_clamps_negative_eigenvalues() {
        assert_eq!(psd2(2.0, 0.5, 1.0), (2.0, 0.5, 1.0));
        assert_eq!(psd2(-1.0, 0.0, -2.0), (0.0, 0.0, 0.0));
        // diag(3, -1) rotated by 30 degrees: the projection keeps 3 u u^T.
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let (a, b, d) = (3.0 * c * c - s * s, 4.0 * c * s, 3.0 * s * s - c * c);
        let (p00, p01, p11) = psd2(a, b, d);
        for (got, want) in [(p00, 3.0 * c * c), (p01, 3.0 * c * s), (p11, 3.0 * s * s)] {
            assert!((got - want).abs() < 1e-14, "{got} vs {want}");
        }
    }

    /// The one-logarithm `U'` and `U''` of the formulation's sweeps are the volumetric part's
    /// own, bit for bit, for every energy and for `theta` at and beyond the domain's edge.
    #[test]
    fn du_d2u_matches_the_volumetric_part_bit_for_bit() {
        use fem_core::PlaneModel;
        use fem_core::energy::EnergyKind;
        use fem_core::material::Material;
        let lame = Material::new(1e4, 0.49, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain);
        for kind in EnergyKind::ALL {
            let vol = kind.build(lame).unwrap().volumetric();
            for theta in [-0.5, 0.0, 1e-300, 0.3, 1.0, 1.0 + 1e-12, 2.7, 1e3] {
                let (du, d2u) = du_d2u(&vol, theta);
                assert_eq!(du.to_bits(), vol.du(theta).to_bits(), "{kind:?} {theta}");
                assert_eq!(d2u.to_bits(), vol.d2u(theta).to_bits(), "{kind:?} {theta}");
            }
        }
    }

    /// A pinned beam with a free rigid block in the middle, sagging under gravity: every
    /// initial guess, with or without the line search, reaches the same step (the body's block
    /// descends the same potential), and the block stays rigid.
    #[test]
    fn a_free_body_block_converges_the_same_with_and_without_line_search() {
        use crate::model::bc::Region;
        use fem_core::PlaneModel;
        use fem_core::energy::EnergyKind;
        use fem_core::material::Material;
        use fem_core::structured::{RectangleParams, rectangle};

        let mesh = rectangle(&RectangleParams::new(2.0, 0.2, 20, 2)).unwrap();
        let lame = Material::new(1e4, 0.3, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain);
        let energy = EnergyKind::NeoHookean.build(lame).unwrap();
        let tags: Vec<u32> = (0..mesh.n_triangles())
            .map(|t| {
                let c = mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0;
                u32::from((c.x - 1.2).abs() < 0.3)
            })
            .collect();
        let energies = ElementEnergies::new(vec![energy.clone(), energy], tags).unwrap();
        let masses = mesh.lumped_masses_from_density(100.0).unwrap();
        let mut model = Model::with_regions(mesh, energies, masses).unwrap();
        model.make_rigid(1, 100.0).unwrap();
        model.set_standard_gravity();
        model
            .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 0.2)))
            .unwrap();
        assert!(model.rigid_bodies()[0].is_free());
        let run = |init: VbdInit, line_search: bool| {
            let params = VbdParams {
                dt: 1e-2,
                iterations: 400,
                init,
                line_search,
                ..VbdParams::default()
            };
            let mut stepper = VbdStepper::new(&model, params).unwrap();
            let mut state = State::at_rest(&model);
            for _ in 0..5 {
                stepper.step(&model, &mut state).unwrap();
            }
            state
        };
        let reference = run(VbdInit::Adaptive, false);
        let body = &model.rigid_bodies()[0];
        assert!(
            reference.rigid[0].position.y < body.centroid.y - 1e-3,
            "it sags"
        );
        for init in [VbdInit::Previous, VbdInit::Inertia, VbdInit::Adaptive] {
            for line_search in [false, true] {
                let state = run(init, line_search);
                let gap = (state.x.iter().zip(&reference.x))
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, Real::max);
                let pose = (state.rigid[0].position - reference.rigid[0].position).norm()
                    + (state.rigid[0].angle - reference.rigid[0].angle).abs();
                assert!(
                    gap < 1e-9 && pose < 1e-9,
                    "{init:?} {line_search}: {gap:e} {pose:e}"
                );
                let frame = Frame::of(&state.rigid[0]);
                for (&v, &r) in body.vertices.iter().zip(&body.offsets) {
                    assert!((state.x[v as usize] - frame.apply(r)).norm() < 1e-15);
                }
            }
        }
    }
}
