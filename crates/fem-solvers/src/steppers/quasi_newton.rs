//! Quasi-Newton implicit Euler: L-BFGS on the incremental potential with Projective Dynamics'
//! matrix as the initial Hessian (Liu, Bouaziz & Kavan, "Quasi-Newton Methods for Real-Time
//! Simulation of Hyperelastic Materials", ACM TOG 36(3), 2017), for every energy.
//!
//! Each step of length `h` minimises implicit Euler's incremental potential
//! `G(x) = sum m/(2 h^2) |x - x_hat|^2 - f . x + sum_e a_e psi(F_e)` ([`crate::implicit`]) over
//! the free vertices, from `x_hat + h^2 f / m` (or, when that inverts a triangle of an energy
//! forbidding inversion, from the current positions with the kinematic vertices moved). Each
//! iteration:
//! - the direction `d = -H g` by L-BFGS's two-loop recursion over the last `history` pairs
//!   `(s, y)` of position and gradient changes, with the initial inverse Hessian `A^-1`,
//!   `A = M / h^2 + L` the Projective Dynamics matrix of the energy's Lamé parameters at rest
//!   (`PdSystem` in `pd_system.rs`; for the co-rotational energy the exact PD matrix),
//!   factorised once when the stepper is built, so an iteration costs a gradient, one or more
//!   potential evaluations and two triangular solves;
//! - a backtracking (Armijo) line search: the step is halved until the potential is finite and
//!   decreases enough, so a state that inverts a triangle of an energy forbidding inversion
//!   (Neo-Hookean's `log J`) is never accepted;
//! - a pair is kept only when `s . y > 0` (curvature), so `H` stays positive definite.
//!
//! It stops after `iterations` iterations, or earlier when the gradient's norm falls below
//! `tolerance` times the force scale (the largest of the first gradient, the external load,
//! the elastic forces on the free vertices at the start and 1e-12 N; with rigid bodies and
//! contact, the first gradient of the body's own unknowns: an obstacle's tether would dwarf
//! it), the same test as Newton's ([`crate::newton`]). Unlike implicit Euler, not reaching the tolerance is not an
//! error: a real-time step has a fixed budget, and the report's residual says how far it got:
//! the step's iterations are those taken (a line search that found no acceptable step counts
//! and ends the step; with contact or rigid bodies, one that fails with pairs kept restarts from
//! the initial Hessian first), its residual the gradient's norm at the positions it ends at, N.
//! With enough iterations it reaches Newton's step to Newton's tolerance for every energy
//! (`tests/suite/quasi_newton.rs`), with contact and rigid bodies too
//! (`tests/suite/quasi_newton_coupled.rs`).
//!
//! **Contact and rigid regions** (a ground, obstacles or free rigid bodies; `coupled.rs`). The
//! potential, its gradient and its unknowns are implicit Euler's ([`crate::newton`]): barrier
//! contact and lagged friction (`contact/barrier.rs`, built on [`crate::ipc`]), the moving
//! obstacles' poses
//! (a dynamic body's inertia and weight, a kinematic one's tether to its schedule), and three
//! unknowns per free rigid body, its centroid and angle, its vertices slaved. The elastic
//! energy is the elastic mesh's (a rigid triangle has none). The initial Hessian stays
//! symmetric positive definite and is factorised once: the PD matrix over the free vertices;
//! for the bodies the same quadratic model in their reduced coordinates at the step's start,
//! `J^T (M' / h^2 + L) J + diag(M, M, I) / h^2`, through a `3 n_b` Schur complement each step
//! (`A^-1` of four coupling columns per body is solved when the stepper is built, so the
//! bodies' rotation costs no solve; left out, the block's diagonal alone, one step of a beam
//! with two bodies is 0.6 to 0.8 off the model's solve, relative); for the obstacles their
//! inertia or tether weights. The start is the prediction plus the load's acceleration for the
//! bodies too, so a free fall is exact from the start. As in
//! Newton, the starting guess is the prediction only as far as the CCD lets it move free of
//! contact, a step may only start with everything apart (else `quasi-newton.contact` names the
//! pair), every line search starts at the largest step the CCD allows (closing no gap by more
//! than 90 %), a rotating obstacle's direction is shortened so its corners stay near their
//! chords, and within the potential's round-off a trial that lowers the gradient is taken while
//! the lower potential stays the reference. So every accepted iterate is free of contact,
//! whatever the budget: the body never penetrates the ground or an obstacle.
//!
//! **What contact costs.** The barrier's Hessian is not in the initial matrix (it changes every
//! step and with every iterate; refactorising would make this Newton): L-BFGS learns its
//! curvature from its pairs, and the CCD bound and the line search keep the steps short where
//! the barrier is stiff. Each contact pair is a direction in which `A` underestimates the
//! curvature by orders of magnitude (the barrier's stiffness at a small gap against the
//! tissue's), so the iterations a step needs grow with the number of pairs and their
//! stiffness, where without contact they depend on the energy's nonlinearity alone. Measured at
//! 90 Hz (`tests/suite/quasi_newton_coupled.rs`): a 1 kg block resting on the ground (9 ground
//! pairs) needs 136 iterations a step on average to reach the tolerance 1e-8 with `history =
//! 5` (45 with 50 pairs kept), where implicit Euler takes 2 to 4 Newton iterations; at the
//! default 10 iterations its ground force ends about 20 % short of its weight (still apart). A
//! kinematic wedge driven into a coarse soft edge stalls with 5 pairs (its line searches halve
//! to the potential's round-off) and converges with 20. So in contact the history should be as
//! long as the iterations: on case D (`docs/solvers.md`) 50 iterations with 50 pairs end at
//! implicit Euler's converged step (stress within 0.03 %) at about twice its cost, the defaults
//! (10 and 5) stay apart and stable at a rough rest state. The defaults are those of the scenes
//! without contact, unchanged.
//!
//! **BDF2** (`integrator = "bdf2"`, [`crate::integrator`]): L-BFGS minimises BDF2's
//! potential (inertia weight `9 / (4 h^2)`, BDF2's target and velocity) with the initial Hessian
//! `9 M / (4 h^2) + L`, factorised with backward Euler's when the stepper is built; the first
//! step, and any step from a state the stepper did not commit, is backward Euler. The free
//! rigid bodies and the dynamic obstacles take BDF2's target, weight and velocity on their
//! poses, as under implicit Euler, contact included.
//!
//! Registered as `quasi-newton` ([`Solver`]); scene keys `dt`, `iterations`, `history`,
//! `damping`, `tolerance`, `max_halvings`, `integrator`.

use fem_core::assembly::{Scratch, populate_forces};
use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2, exp};

use super::{Stepper, check_step_inputs};
use crate::contact::Contact;
use crate::error::{SolverError, check_at_most, check_count, check_non_negative, check_positive};
use crate::kernel::{PackedElement, pack};
use crate::model::Model;
use crate::model::grab::spring_of;
use crate::model::limits;
use crate::model::state::State;
use crate::optim::newton::{Potential, force_scale};
use crate::optim::pd_system::{PdSystem, element_lame};
use crate::steppers::implicit::external_load;
use crate::steppers::integrator::{History, Integrator, pd_systems};
use crate::steppers::registry::{Capabilities, Clock, Solver};
use crate::steppers::report::StepReport;
use crate::steppers::vbd::{commit_positions, forbids_inversion, inversion};
use coupled::Coupled;

mod coupled;

/// Most `(s, y)` pairs L-BFGS may keep.
pub const MAX_HISTORY: usize = 100;

/// Parameters of [`QuasiNewtonStepper`] (scene keys: the field names).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct QuasiNewtonParams {
    /// Time step, s (finite, > 0). Default `1e-3`.
    pub dt: Real,
    /// Most L-BFGS iterations per step (>= 1). Default 10.
    pub iterations: usize,
    /// `(s, y)` pairs kept (0 to 100; 0 iterates with the PD matrix alone). Default 5.
    pub history: usize,
    /// Velocity damping rate `c`, 1/s (`v <- v exp(-c dt)` each step). Default 0.
    pub damping: Real,
    /// Stop when the gradient's norm is below `tolerance` times the force scale; in the open
    /// interval `(0, 1)`. Default `1e-8`.
    pub tolerance: Real,
    /// Most halvings of the line search. Default 40.
    pub max_halvings: usize,
    /// The time integrator: backward Euler (default) or BDF2 (second order; see
    /// [`crate::integrator`]). Under BDF2 the initial Hessian is factorised for each of the
    /// two inertia weights (backward Euler's first step and fall-backs, BDF2's steps).
    pub integrator: Integrator,
}

impl Default for QuasiNewtonParams {
    fn default() -> Self {
        QuasiNewtonParams {
            dt: 1e-3,
            iterations: 10,
            history: 5,
            damping: 0.0,
            tolerance: 1e-8,
            max_halvings: 40,
            integrator: Integrator::BackwardEuler,
        }
    }
}

impl QuasiNewtonParams {
    /// Check every field; errors name `quasi-newton.<field>`.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.validate_as(QuasiNewtonStepper::NAME)
    }

    /// Check every field; errors name `<prefix>.<field>`.
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        let field = |name: &str| format!("{prefix}.{name}");
        check_positive(&field("dt"), self.dt)?;
        check_count(
            &field("iterations"),
            self.iterations,
            limits::MAX_NEWTON_ITERATIONS,
        )?;
        check_at_most(&field("history"), self.history, MAX_HISTORY)?;
        check_non_negative(&field("damping"), self.damping)?;
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(SolverError::invalid(
                field("tolerance"),
                self.tolerance,
                "must be in the open interval (0, 1)",
            ));
        }
        check_at_most(
            &field("max_halvings"),
            self.max_halvings,
            limits::MAX_HALVINGS,
        )
    }
}

/// What the last step did, beyond its [`StepReport`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QuasiNewtonReport {
    /// Iterations taken.
    pub iterations: usize,
    /// Whether the gradient reached the tolerance.
    pub converged: bool,
    /// Gradient norm after every iteration (the first entry before any), N.
    pub residuals: Vec<Real>,
    /// Potential evaluations of the line searches.
    pub evaluations: usize,
    /// Whether the starting guess was replaced by the current positions.
    pub fallback_guess: bool,
    /// The force scale of the residual test, N (Newton's: the largest of the first gradient,
    /// the external load, the elastic forces on the free vertices at the start, 1e-12 N).
    pub force_scale: Real,
}

/// L-BFGS with the Projective Dynamics matrix; see the module docs.
#[derive(Debug)]
pub struct QuasiNewtonStepper {
    params: QuasiNewtonParams,
    decay: Real,
    n_triangles: usize,
    els: Vec<PackedElement>,
    /// `M / h^2 + L`, factorised.
    system: PdSystem,
    /// Under BDF2, `9 M / (4 h^2) + L`, factorised.
    bdf2_system: Option<PdSystem>,
    /// The previous step's state (BDF2).
    history: History,
    /// Whether the current (or last) step is a BDF2 step: which matrix the direction uses.
    bdf2: bool,
    forbids_inversion: bool,
    /// The modulus times the body's area: the scale of the round-off of the elastic energy.
    psi_scale: Real,
    /// Free vertices, increasing; packed vectors are `[x of each, then y of each]`.
    free: Vec<u32>,
    target: Vec<Vec2>,
    load: Vec<Vec2>,
    x: Vec<Vec2>,
    trial: Vec<Vec2>,
    v_new: Vec<Vec2>,
    forces: Vec<Vec2>,
    scratch: Scratch,
    g: Vec<Real>,
    g_new: Vec<Real>,
    d: Vec<Real>,
    lbfgs: Lbfgs,
    last: QuasiNewtonReport,
    /// The model layout the matrix was factorised for.
    layout: u64,
    /// With contact or free rigid bodies: their unknowns, Newton's gradient and the barrier
    /// (`coupled.rs`); `None` takes the path without them.
    coupled: Option<Coupled>,
}

/// L-BFGS's pairs: a ring of the last `(s, y, 1 / (s . y))`, oldest first from `head`.
#[derive(Debug)]
pub(crate) struct Lbfgs {
    s: Vec<Vec<Real>>,
    y: Vec<Vec<Real>>,
    rho: Vec<Real>,
    alpha: Vec<Real>,
    pairs: usize,
    head: usize,
}

impl Lbfgs {
    /// Room for `history` pairs of vectors of length `m`.
    pub(crate) fn new(history: usize, m: usize) -> Self {
        Lbfgs {
            s: vec![vec![0.0; m]; history],
            y: vec![vec![0.0; m]; history],
            rho: vec![0.0; history],
            alpha: vec![0.0; history],
            pairs: 0,
            head: 0,
        }
    }

    /// Forget every pair.
    pub(crate) fn clear(&mut self) {
        self.pairs = 0;
        self.head = 0;
    }

    /// `d = -H g` by the two-loop recursion, `h0` applying the initial inverse Hessian in
    /// place.
    pub(crate) fn direction(&mut self, g: &[Real], d: &mut [Real], h0: impl FnOnce(&mut [Real])) {
        let hist = self.s.len();
        for (d, g) in d.iter_mut().zip(g) {
            *d = -g;
        }
        // Newest to oldest.
        for k in (0..self.pairs).rev() {
            let i = (self.head + k) % hist.max(1);
            let a = self.rho[i] * dot(&self.s[i], d);
            self.alpha[i] = a;
            for (d, y) in d.iter_mut().zip(&self.y[i]) {
                *d -= a * y;
            }
        }
        h0(d);
        // Oldest to newest.
        for k in 0..self.pairs {
            let i = (self.head + k) % hist.max(1);
            let b = self.rho[i] * dot(&self.y[i], d);
            let a = self.alpha[i];
            for (d, s) in d.iter_mut().zip(&self.s[i]) {
                *d += (a - b) * s;
            }
        }
    }

    /// The slot of a new pair (history > 0), replacing the oldest when the ring is full.
    fn next_slot(&mut self) -> usize {
        let hist = self.s.len();
        let slot = (self.head + self.pairs) % hist;
        if self.pairs == hist {
            self.head = (self.head + 1) % hist;
        } else {
            self.pairs += 1;
        }
        slot
    }

    /// Keep the pair `(s, g_new - g)` if its curvature `s . y` is positive (beyond round-off).
    pub(crate) fn remember(&mut self, s: &[Real], g_new: &[Real], g: &[Real]) {
        if self.s.is_empty() {
            return;
        }
        let (mut sy, mut yy) = (0.0, 0.0);
        for ((s, a), b) in s.iter().zip(g_new).zip(g) {
            let dy = a - b;
            sy += s * dy;
            yy += dy * dy;
        }
        if !(sy.is_finite() && sy > Real::EPSILON * yy) {
            return;
        }
        let slot = self.next_slot();
        self.s[slot].copy_from_slice(s);
        for ((y, a), b) in self.y[slot].iter_mut().zip(g_new).zip(g) {
            *y = a - b;
        }
        self.rho[slot] = 1.0 / sy;
    }
}

pub(crate) fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl QuasiNewtonStepper {
    /// A stepper for `model`: validates the parameters, assembles and factorises the
    /// Projective Dynamics matrix, and with a ground, obstacles or free rigid bodies sets up
    /// their unknowns, barrier contact and the bodies' part of the initial Hessian.
    pub fn new<E: Energy>(
        model: &Model<E>,
        params: QuasiNewtonParams,
    ) -> Result<Self, SolverError> {
        params.validate()?;
        // Contact and free rigid bodies take the coupled path over the elastic mesh (a rigid
        // triangle has no energy); without them the mesh is the whole one, as it always was.
        let coupled = model.has_contact() || model.rigid_bodies().iter().any(|b| b.is_free());
        let (mesh, energies) = if coupled {
            (model.elastic_mesh(), model.elastic_energies())
        } else {
            (model.mesh(), model.energies())
        };
        let n = mesh.n_vertices();
        // Each element's weight from its region's Lamé parameters.
        let lame = element_lame(energies, mesh.n_triangles());
        let weights: Vec<Real> = (mesh.elements().iter().zip(&lame))
            .map(|(e, &(mu, lambda))| 2.0 * e.area * (mu + lambda))
            .collect();
        let psi_scale = (mesh.elements().iter().zip(&lame))
            .map(|(e, &(mu, lambda))| (2.0 * mu + lambda).abs() * e.area)
            .sum();
        let mut kinematic = vec![false; n];
        for v in model.kinematics().vertices() {
            kinematic[v] = true;
        }
        let h = params.dt;
        let (mut system, mut bdf2_system) = pd_systems(
            mesh,
            model.masses(),
            &weights,
            h,
            params.integrator,
            model.springs(),
            &kinematic,
            "quasi-newton",
        )?;
        let free: Vec<u32> = (0..n as u32).filter(|&v| !kinematic[v as usize]).collect();
        let coupled = match coupled {
            true => Some(Coupled::new(
                model,
                &params,
                &free,
                &weights,
                &mut system,
                bdf2_system.as_mut(),
            )?),
            false => None,
        };
        let m = 2 * free.len() + coupled.as_ref().map_or(0, Coupled::n_extra);
        Ok(QuasiNewtonStepper {
            layout: model.layout(),
            decay: exp(-params.damping * h),
            params,
            n_triangles: model.mesh().n_triangles(),
            els: pack(model.mesh(), model.energies().tags()),
            system,
            bdf2_system,
            history: History::new(params.integrator),
            bdf2: false,
            forbids_inversion: forbids_inversion(model.energy()),
            psi_scale,
            free,
            target: vec![Vec2::zeros(); n],
            load: vec![Vec2::zeros(); n],
            x: vec![Vec2::zeros(); n],
            trial: vec![Vec2::zeros(); n],
            v_new: vec![Vec2::zeros(); n],
            forces: vec![Vec2::zeros(); n],
            scratch: Scratch::new(),
            g: vec![0.0; m],
            g_new: vec![0.0; m],
            d: vec![0.0; m],
            lbfgs: Lbfgs::new(params.history, m),
            last: QuasiNewtonReport::default(),
            coupled,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &QuasiNewtonParams {
        &self.params
    }

    /// What the last step did.
    pub fn last_report(&self) -> &QuasiNewtonReport {
        &self.last
    }

    /// Numeric factorisations of the initial Hessian since the stepper was built: one, plus one
    /// for each change of the model's layout (a grab started or ended); twice that under BDF2
    /// (backward Euler's matrix and BDF2's).
    pub fn factorisations(&self) -> usize {
        self.system.factorisations() + self.bdf2_system.as_ref().map_or(0, |s| s.factorisations())
    }

    /// Whether the last step was a BDF2 step (see [`crate::integrator`]).
    pub fn last_step_bdf2(&self) -> bool {
        self.bdf2
    }

    /// The smallest distance between the soft body and the ground or an obstacle over the
    /// candidate pairs at the end of the last step, m (infinite when nothing is near, or
    /// without contact). Barrier contact keeps it positive.
    pub fn min_distance(&self) -> Real {
        self.coupled
            .as_ref()
            .map_or(Real::INFINITY, Coupled::min_distance)
    }

    /// The potential at `x` (load work measured from the rest positions, as Newton's) and the
    /// sum of its terms' magnitudes (the scale of its round-off); when `gradient` is given,
    /// also its gradient over the free vertices, packed.
    fn evaluate<E: Energy>(
        &mut self,
        model: &Model<E>,
        w: Real,
        which: Which,
        gradient: Option<Which>,
    ) -> (Real, Real) {
        let x = match which {
            Which::X => &self.x,
            Which::Trial => &self.trial,
        };
        let mesh = model.mesh();
        let potential = Potential {
            mesh,
            energy: model.energies(),
            masses: model.masses(),
            weight: w,
            target: &self.target,
            load: &self.load,
            springs: model.springs(),
        };
        let (e, magnitude) = potential.value(x, &mut self.scratch);
        if gradient.is_some() && e.is_finite() {
            populate_forces(
                mesh,
                model.energies(),
                x,
                &mut self.forces,
                &mut self.scratch,
            );
            let n = self.free.len();
            let out = match gradient {
                Some(Which::X) => &mut self.g,
                _ => &mut self.g_new,
            };
            for (k, &v) in self.free.iter().enumerate() {
                let v = v as usize;
                let mut gv = (x[v] - self.target[v]) * (w * model.masses()[v])
                    - self.load[v]
                    - self.forces[v];
                if let Some(s) = spring_of(model.springs(), v) {
                    gv += (x[v] - s.goal) * s.stiffness;
                }
                out[k] = gv.x;
                out[n + k] = gv.y;
            }
        }
        (e, magnitude)
    }

    /// `d = -H g` by the two-loop recursion with `H0 = A^-1`.
    fn direction(&mut self) {
        let (be, bdf2_system, bdf2) = (&mut self.system, &mut self.bdf2_system, self.bdf2);
        self.lbfgs
            .direction(&self.g, &mut self.d, |d| match (bdf2_system, bdf2) {
                (Some(system), true) => system.solve(d),
                _ => be.solve(d),
            });
    }

    /// Keep the pair `(s, y)` = (trial - x, g_new - g) if its curvature `s . y` is positive
    /// (beyond round-off), replacing the oldest when the history is full.
    fn remember(&mut self) {
        let hist = self.params.history;
        if hist == 0 {
            return;
        }
        let n = self.free.len();
        let (mut sy, mut yy) = (0.0, 0.0);
        for (k, &v) in self.free.iter().enumerate() {
            let ds = self.trial[v as usize] - self.x[v as usize];
            let dy = Vec2::new(self.g_new[k] - self.g[k], self.g_new[n + k] - self.g[n + k]);
            sy += ds.dot(&dy);
            yy += dy.norm_squared();
        }
        if !(sy.is_finite() && sy > Real::EPSILON * yy) {
            return;
        }
        let slot = self.lbfgs.next_slot();
        for (k, &v) in self.free.iter().enumerate() {
            let ds = self.trial[v as usize] - self.x[v as usize];
            self.lbfgs.s[slot][k] = ds.x;
            self.lbfgs.s[slot][n + k] = ds.y;
        }
        for ((y, a), b) in self.lbfgs.y[slot].iter_mut().zip(&self.g_new).zip(&self.g) {
            *y = a - b;
        }
        self.lbfgs.rho[slot] = 1.0 / sy;
    }
}

/// Which position buffer an evaluation reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Which {
    X,
    Trial,
}

impl Stepper for QuasiNewtonStepper {
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
            let earlier = self.factorisations();
            *self = QuasiNewtonStepper::new(model, self.params)?;
            self.system.add_earlier(earlier);
        }
        if self.coupled.is_some() {
            return self.step_coupled(model, state);
        }
        let (h, t) = (self.params.dt, state.t);
        let bdf2 = self.history.begin(state, h, model.layout());
        self.bdf2 = bdf2;
        let (w, hh) = self.history.targets(bdf2, state, h, &mut self.target);
        external_load(model, &mut self.load);
        let masses = model.masses();
        // The start: the inertial target plus the external load's acceleration over the step.
        for (i, xh) in self.target.iter().enumerate() {
            self.x[i] = *xh + self.load[i] * (hh / masses[i]);
        }
        let kinematics = model.kinematics();
        kinematics.apply(t, h, t + h, &state.x, &mut self.x, &mut self.v_new);
        let mut report = QuasiNewtonReport::default();
        let (mut energy, mut magnitude) = self.evaluate(model, w, Which::X, Some(Which::X));
        if !energy.is_finite()
            || (self.forbids_inversion && inversion(&self.els, &self.x).inverted > 0)
        {
            self.x.copy_from_slice(&state.x);
            kinematics.apply(t, h, t + h, &state.x, &mut self.x, &mut self.v_new);
            (energy, magnitude) = self.evaluate(model, w, Which::X, Some(Which::X));
            report.fallback_guess = true;
        }
        self.lbfgs.clear();
        // Newton's force scale: the first gradient, the load, and the elastic forces on the
        // free vertices at the start (`self.forces`, from the evaluation above).
        let elastic = (self.free.iter())
            .map(|&v| self.forces[v as usize].norm_squared())
            .sum::<Real>()
            .sqrt();
        let mut gnorm = dot(&self.g, &self.g).sqrt();
        let scale = force_scale(gnorm, &self.load, elastic);
        overflowing_start(gnorm, scale)?;
        // Whether any trial of the step had a finite potential, and whether any was taken.
        let (mut finite_trial, mut moved) = (false, false);
        report.force_scale = scale;
        report.residuals.push(gnorm);
        while report.iterations < self.params.iterations && energy.is_finite() {
            if gnorm <= self.params.tolerance * scale {
                report.converged = true;
                break;
            }
            self.direction();
            let mut slope = dot(&self.g, &self.d);
            if slope >= 0.0 || !slope.is_finite() {
                // Not a descent direction (round-off in the history): restart from A^-1.
                self.lbfgs.clear();
                self.direction();
                slope = dot(&self.g, &self.d);
            }
            let n = self.free.len();
            let mut alpha = 1.0;
            let mut accepted = false;
            for _ in 0..=self.params.max_halvings {
                self.trial.copy_from_slice(&self.x);
                for (k, &v) in self.free.iter().enumerate() {
                    self.trial[v as usize] += Vec2::new(self.d[k], self.d[n + k]) * alpha;
                }
                let (e, m) = self.evaluate(model, w, Which::Trial, None);
                report.evaluations += 1;
                if !e.is_finite() {
                    alpha *= 0.5;
                    continue;
                }
                finite_trial = true;
                // Near the minimum the change of the potential falls below its round-off (eps
                // times its terms, and psi's terms are of the order of the modulus, not of
                // psi): there the trial is accepted if it lowers the gradient instead, as in
                // Newton's line search.
                let armijo = e <= energy + 1e-4 * alpha * slope;
                let in_round_off = (e - energy).abs() <= 1e-12 * (magnitude + m + self.psi_scale);
                let lowers_gradient = !armijo && in_round_off && {
                    self.evaluate(model, w, Which::Trial, Some(Which::Trial));
                    dot(&self.g_new, &self.g_new).sqrt() < gnorm
                };
                if armijo || lowers_gradient {
                    (energy, magnitude) = (e, m);
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            report.iterations += 1;
            moved |= accepted;
            if !accepted {
                break;
            }
            self.evaluate(model, w, Which::Trial, Some(Which::Trial));
            self.remember();
            std::mem::swap(&mut self.x, &mut self.trial);
            std::mem::swap(&mut self.g, &mut self.g_new);
            gnorm = dot(&self.g, &self.g).sqrt();
            report.residuals.push(gnorm);
        }
        if gnorm <= self.params.tolerance * scale {
            report.converged = true;
        }
        if !moved && (report.fallback_guess || !finite_trial) && !report.converged {
            let (halvings, forbids) = (self.params.max_halvings, self.forbids_inversion);
            stalled(&self.x, &self.trial, &self.els, forbids, halvings, gnorm)?;
        }
        let inv = commit_positions(
            model,
            state,
            &self.els,
            &mut self.x,
            &mut self.v_new,
            None,
            None,
            h,
            t + h,
            self.decay,
            true,
            bdf2.then_some(&self.history.prev.x[..]),
        )?;
        self.history.commit(state);
        let out = StepReport {
            min_det_f: inv.min_det_f,
            inverted: inv.inverted,
            iterations: report.iterations,
            residual: gnorm,
            contacts: 0,
        };
        self.last = report;
        Ok(out)
    }

    fn contacts(&self) -> &[Contact] {
        self.coupled.as_ref().map_or(&[], Coupled::contacts)
    }
}

impl Solver for QuasiNewtonStepper {
    type Params = QuasiNewtonParams;
    const NAME: &'static str = "quasi-newton";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "Quasi-Newton",
        summary: "implicit Euler by L-BFGS with the Projective Dynamics matrix as initial Hessian (Liu et al. 2017), every energy; barrier contact and rigid bodies as implicit Euler's unknowns",
        paper: false,
        contact: true,
        rigid_regions: true,
        averaged_pressure: true,
        dims: 3,
        implicit: true,
        iterations: true,
        substeps: false,
        factorisation: true,
        deterministic_across_threads: true,
        clock: Clock::Time,
        converges_to: "each step to implicit Euler's (BDF2's with integrator = bdf2; Newton's step to its tolerance) as iterations grow",
    };

    fn validate_params(p: &QuasiNewtonParams, prefix: &str) -> Result<(), SolverError> {
        p.validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &QuasiNewtonParams) -> Result<Self, SolverError> {
        QuasiNewtonStepper::new(model, *p)
    }

    fn dt_mut(p: &mut QuasiNewtonParams) -> Option<&mut Real> {
        Some(&mut p.dt)
    }

    fn integrator_mut(p: &mut QuasiNewtonParams) -> Option<&mut Integrator> {
        Some(&mut p.integrator)
    }
}

/// The start of a step whose gradient or force scale overflowed: an error (it would read as
/// anything from converged to blown up).
pub(crate) fn overflowing_start(gnorm: Real, scale: Real) -> Result<(), SolverError> {
    if gnorm.is_finite() && scale.is_finite() {
        return Ok(());
    }
    Err(SolverError::invalid(
        "quasi-newton.forces",
        fem_core::math::readable(gnorm.max(scale)),
        "the forces at the starting positions overflow double precision \
         (a load, a modulus, a spring or a barrier stiffness too large)",
    ))
}

/// A step that took no trial, from a start that is the current state (the prediction was not
/// finite) or with every trial's potential infinite, leaves the body at `x` under a load it
/// did not resist: no step of the problem posed, so an error, unless the smallest trial
/// (`trial`) inverts an element under an energy that forbids it within the body's size of
/// the start (a stall of the fixed budget, reported by its residual).
pub(super) fn stalled(
    x: &[Vec2],
    trial: &[Vec2],
    els: &[PackedElement],
    forbids_inversion: bool,
    max_halvings: usize,
    gnorm: Real,
) -> Result<(), SolverError> {
    let reach = (x.iter().zip(trial))
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, Real::max);
    let size = crate::optim::newton::body_size(x);
    if forbids_inversion && reach <= size && inversion(els, trial).inverted > 0 {
        return Ok(());
    }
    Err(SolverError::BeyondPrecision {
        prefix: "quasi-newton",
        detail: format!(
            "the step did not move the body: no trial along the search direction has a \
             finite, lower potential (halved {max_halvings} times; residual {gnorm:.3e} N)"
        ),
    })
}
