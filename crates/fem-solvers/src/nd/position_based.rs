//! Energy-based PBD and XPBD in either dimension: the 2D [`crate::steppers::position_based`]
//! on a simplex mesh (triangles in 2D, tetrahedra in 3D), one constraint per cell.
//!
//! Each (sub)step of length `h`: predict `v' = v + h (g + M^-1 f_ext)`, `x* = x + h v'`; reset
//! the multipliers; run `iterations` sweeps over the cell constraints; then
//! `v = (x* - x) / h`, damped by `exp(-c h)`. Per cell of rest measure `V` (the triangle's area,
//! the tetrahedron's volume) with vertices `j`, `grad_j (V psi) = V P g_j` (`g_j` the
//! shape-function gradients, `g_0 = -(g_1 + ... + g_D)`) and `w_j = 1/m_j`:
//! - **PBD**: `C = V psi(F)`, `s = -C / sum_j w_j |grad_j C|^2`, `dx_j = k w_j s grad_j C`
//!   with the stiffness `k` in `(0, 1]` (the response depends on `dt` and the iteration count:
//!   there is no material limit);
//! - **XPBD, consistent form** (default): `C = sqrt(2 V psi)`, compliance
//!   `alpha~ = alpha / h^2`: the constraint energy `C^2 / (2 alpha)` is the cell's elastic
//!   energy at `alpha = 1`;
//! - **XPBD, literal form**: `C = V psi` with the same update (the paper's text; the compliance
//!   has no material meaning);
//! - both XPBD forms: `dlambda = (-C - alpha~ lambda) / (sum_j w_j |grad_j C|^2 + alpha~)`,
//!   `dx_j = w_j grad_j C dlambda`, `lambda` accumulated over the sweeps of a (sub)step.
//!
//! The formulas, the parameters ([`PbdParams`], [`XpbdParams`]) and their defaults are the 2D
//! solver's, and the projection rule is the very same function: see its module docs for what
//! XPBD converges to (a fixed point of the sweeps that satisfies every constraint equation but
//! neglects the primal residual, so it is not implicit Euler's step and depends on the
//! ordering), for the rest threshold (a cell is skipped when `psi <= rest_threshold * M`, `M`
//! the P-wave modulus `dP_00/dF_00` at rest; a NaN `psi` is not skipped), the XPBD schedule
//! (`small-steps`: `substeps x iterations` substeps of one sweep), the multiplier reset and the
//! residual tolerance (a substep stops its sweeps once a sweep's residual
//! `sqrt(sum (C + alpha~ lambda)^2)` is at most `tolerance` times its first sweep's).
//!
//! **Orderings**, all three of the 2D solver, each meaningful on a simplex mesh of either
//! dimension: Gauss-Seidel in cell order (serial); coloured Gauss-Seidel (default: the cells
//! greedily coloured in index order so that no two cells of a colour share a vertex, each
//! colour's projections computed in parallel from the same positions and then applied, which
//! equals the in-place serial sweep of the colour; the structured tetrahedral beams need 26 to
//! 28 colours, the triangle beam 7); Jacobi (every cell from the same positions,
//! each step scaled by `relaxation / max_j n_j`, `n_j` the number of cells at vertex `j`,
//! corrections summed per vertex in cell order). In 2D each is the 2D solver's, colouring
//! included. States are bit-identical for any number of threads. Nothing is refused: every
//! value of every parameter has its 2D meaning here.
//!
//! **Fixed degrees of freedom.** The model fixes components, not vertices (a plane-strain
//! side face holds `u_z` alone). The inverse mass becomes diagonal per degree of freedom: a
//! fixed component has `w = 0`, so its gradient component is dropped from the denominator
//! `sum_j w_j |grad_j C|^2` and from the correction; its position is kept and its velocity is
//! zero. A vertex fixed in every component is the 2D solver's pinned vertex (`w_j = 0`), bits
//! included.
//!
//! What the 2D solver has and [`NdModel`] does not (contact, rigid regions, the grab, the
//! averaged nodal pressure triangle, prescribed motion) has no counterpart here. Unlike the 2D
//! solver, which commits each substep, a step whose substep fails leaves the state as it was
//! before the step (the nd contract); a substep whose positions or velocities are not finite is
//! that error ([`SolverError::NonFiniteVertex`]). A step allocates nothing after the first.

use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::{Real, exp};
use fem_core::par::prelude::*;
use fem_core::simplex::{Simplex, SimplexMesh};

use super::{NdModel, NdState, NdStepper, check_finite, step_number};
use crate::error::SolverError;
use crate::kernel::{ELEMENT_CHUNK, Inversion, VERTEX_CHUNK};
use crate::steppers::position_based::{
    LambdaReset, Ordering, PbdParams, Rule, XpbdForm, XpbdParams, XpbdSchedule, multiplier,
};
use crate::steppers::report::StepReport;

/// Most vertices of a simplex (the tetrahedron's four).
const MAX_NODES: usize = 4;

/// The rule with what selects the constraints: the rest threshold on `psi` (times the modulus).
#[derive(Clone, Copy, Debug)]
struct Law {
    rule: Rule,
    psi_threshold: Real,
}

/// What one cell projection produced.
#[derive(Clone, Copy, Debug)]
struct Projection<D: Dim> {
    dx: [D::Vector; MAX_NODES],
    active: bool,
    det: Real,
    residual2: Real,
}

impl<D: Dim> Projection<D> {
    fn skip(det: Real, residual2: Real) -> Self {
        Projection {
            dx: [D::Vector::zeros(); MAX_NODES],
            active: false,
            det,
            residual2,
        }
    }
}

/// Statistics of one sweep, accumulated per fixed chunk of cells so sums do not depend on the
/// number of threads (and match the 2D solver's).
#[derive(Clone, Copy, Debug)]
struct SweepStats {
    inv: Inversion,
    residual2: Real,
}

impl SweepStats {
    const EMPTY: SweepStats = SweepStats {
        inv: Inversion::EMPTY,
        residual2: 0.0,
    };

    #[inline(always)]
    fn add<D: Dim>(&mut self, p: &Projection<D>) {
        self.inv.add(p.det);
        self.residual2 += p.residual2;
    }

    fn merge(&mut self, other: &SweepStats) {
        self.inv = Inversion::merge(self.inv, other.inv);
        self.residual2 += other.residual2;
    }
}

/// What a projection reads: the energy, the mesh, the inverse masses and the law.
struct Cells<'a, D: Dim, E> {
    energy: &'a E,
    cells: &'a [D::Cell],
    elements: &'a [Simplex<D>],
    /// `1/m` per vertex, 0 when every component is fixed.
    w: &'a [Real],
    /// Per vertex, bit `i` set when component `i` is fixed.
    fixed: &'a [u8],
    law: Law,
}

impl<D: Dim, E: Hyperelastic<D>> Cells<'_, D, E> {
    /// Project cell `c` from positions `x` (read only); updates its multiplier.
    #[inline(always)]
    fn project(&self, c: usize, x: &[D::Vector], scale: Real, lambda: &mut Real) -> Projection<D> {
        let idx = self.cells[c].as_ref();
        let el = &self.elements[c];
        let mut corners = [D::Vector::zeros(); MAX_NODES];
        for (p, &i) in corners.iter_mut().zip(idx) {
            *p = x[i as usize];
        }
        let f = el.deformation_gradient(&corners[..D::NODES]);
        let det = D::det(&f);
        let psi = self.energy.density(&f);
        if psi <= self.law.psi_threshold {
            return Projection::skip(det, 0.0);
        }
        let p = self.energy.piola(&f);
        // grad_a (V psi) = V P g_a; corner 0's is minus the others' sum (as the 2D kernel).
        let mut g = [D::Vector::zeros(); MAX_NODES];
        for (a, ga) in g.iter_mut().enumerate().take(D::NODES).skip(1) {
            *ga = p * el.gradient(a) * el.measure;
        }
        let mut sum = g[1];
        for ga in &g[2..D::NODES] {
            sum += *ga;
        }
        g[0] = -sum;
        let mut wk = [0.0; MAX_NODES];
        let mut s = 0.0;
        for k in 0..D::NODES {
            let v = idx[k] as usize;
            wk[k] = self.w[v];
            let bits = self.fixed[v];
            if bits != 0 && wk[k] != 0.0 {
                for i in 0..D::D {
                    if bits >> i & 1 == 1 {
                        g[k].set_at(i, 0.0);
                    }
                }
            }
            s += wk[k] * g[k].norm2();
        }
        let (m, residual2) = match multiplier(self.law.rule, el.measure, psi, s, scale, lambda) {
            Ok(m) => m,
            Err(residual2) => return Projection::skip(det, residual2),
        };
        let mut dx = [D::Vector::zeros(); MAX_NODES];
        for k in 0..D::NODES {
            dx[k] = g[k] * (wk[k] * m);
        }
        Projection {
            dx,
            active: true,
            det,
            residual2,
        }
    }
}

#[inline(always)]
fn apply<D: Dim>(x: &mut [D::Vector], idx: &[u32], p: &Projection<D>) {
    if p.active {
        for (&i, d) in idx.iter().zip(&p.dx) {
            x[i as usize] += *d;
        }
    }
}

/// Greedy colouring of the cells in index order, each with the smallest colour no earlier
/// cell sharing a vertex has (the 2D [`Colouring::greedy`](crate::steppers::colour::Colouring)
/// on any simplex mesh): the cells sorted by (colour, index) and the colour offsets.
fn greedy_colouring<D: Dim>(mesh: &SimplexMesh<D>) -> (Vec<u32>, Vec<usize>) {
    let nc = mesh.n_cells();
    let mut colour = vec![u32::MAX; nc];
    // stamp[c] == t marks colour c as taken for cell t.
    let mut stamp: Vec<usize> = Vec::new();
    for (t, cell) in mesh.cells().iter().enumerate() {
        for &v in cell.as_ref() {
            for &(e, _) in mesh.cells_of(v as usize) {
                let c = colour[e as usize];
                if c != u32::MAX {
                    stamp[c as usize] = t;
                }
            }
        }
        let c = (0..stamp.len())
            .find(|&c| stamp[c] != t)
            .unwrap_or_else(|| {
                stamp.push(usize::MAX);
                stamp.len() - 1
            });
        colour[t] = c as u32;
    }
    let n_colours = stamp.len();
    let mut offsets = vec![0usize; n_colours + 1];
    for &c in &colour {
        offsets[c as usize + 1] += 1;
    }
    for c in 0..n_colours {
        offsets[c + 1] += offsets[c];
    }
    let mut next = offsets.clone();
    let mut order = vec![0u32; nc];
    for (t, &c) in colour.iter().enumerate() {
        order[next[c as usize]] = t as u32;
        next[c as usize] += 1;
    }
    (order, offsets)
}

/// The engine PBD and XPBD share.
struct Engine<D: Dim> {
    dt: Real,
    substeps: usize,
    iterations: usize,
    damping: Real,
    rest_threshold: Real,
    ordering: Ordering,
    /// The rule with the compliance before scaling by `h`.
    rule: Rule,
    /// Zero the multipliers before every sweep ([`LambdaReset::Iteration`]).
    reset_lambda_each_sweep: bool,
    /// XPBD's relative residual tolerance (0: every sweep; always 0 for PBD).
    tolerance: Real,
    n_vertices: usize,
    /// The cells in sweep order (by colour for the coloured ordering, else cell order) and the
    /// colour ranges into it (one range for the other orderings).
    order: Vec<u32>,
    ranges: Vec<(usize, usize)>,
    /// Jacobi only, per cell: `relaxation / max_j n_j`.
    jacobi_scale: Vec<Real>,
    lambda: Vec<Real>,
    w: Vec<Real>,
    fixed: Vec<u8>,
    /// The step's positions and velocities (the state is written once, at its end).
    x: Vec<D::Vector>,
    v: Vec<D::Vector>,
    x_pred: Vec<D::Vector>,
    v_new: Vec<D::Vector>,
    corrections: Vec<Projection<D>>,
    chunk_stats: Vec<SweepStats>,
}

impl<D: Dim> Engine<D> {
    #[allow(clippy::too_many_arguments)]
    fn new<E: Hyperelastic<D>>(
        model: &NdModel<D, E>,
        dt: Real,
        substeps: usize,
        iterations: usize,
        damping: Real,
        rest_threshold: Real,
        ordering: Ordering,
        relaxation: Real,
        rule: Rule,
    ) -> Self {
        let mesh = model.mesh();
        let nc = mesh.n_cells();
        let (order, ranges) = match ordering {
            Ordering::Coloured => {
                let (order, offsets) = greedy_colouring(mesh);
                let ranges = offsets.windows(2).map(|w| (w[0], w[1])).collect();
                (order, ranges)
            }
            _ => ((0..nc as u32).collect(), vec![(0, nc)]),
        };
        let jacobi_scale = match ordering {
            Ordering::Jacobi => (mesh.cells().iter())
                .map(|cell| {
                    let n = (cell.as_ref().iter())
                        .map(|&v| mesh.cells_of(v as usize).len())
                        .max()
                        .unwrap_or(1);
                    relaxation / n as Real
                })
                .collect(),
            _ => Vec::new(),
        };
        Engine {
            dt,
            substeps,
            iterations,
            damping,
            rest_threshold,
            ordering,
            rule,
            reset_lambda_each_sweep: false,
            tolerance: 0.0,
            n_vertices: mesh.n_vertices(),
            order,
            ranges,
            jacobi_scale,
            lambda: Vec::new(),
            w: Vec::new(),
            fixed: Vec::new(),
            x: Vec::new(),
            v: Vec::new(),
            x_pred: Vec::new(),
            v_new: Vec::new(),
            corrections: Vec::new(),
            chunk_stats: Vec::new(),
        }
    }

    fn n_colours(&self) -> usize {
        match self.ordering {
            Ordering::Coloured => self.ranges.len(),
            _ => 1,
        }
    }

    fn colours(&self) -> Vec<Vec<usize>> {
        (self.ranges.iter())
            .map(|&(a, b)| self.order[a..b].iter().map(|&c| c as usize).collect())
            .collect()
    }

    fn rule_for(&self, h: Real) -> Rule {
        match self.rule {
            Rule::Pbd { stiffness } => Rule::Pbd { stiffness },
            Rule::Consistent { alpha_tilde } => Rule::Consistent {
                alpha_tilde: alpha_tilde / (h * h),
            },
            Rule::Literal { alpha_tilde } => Rule::Literal {
                alpha_tilde: alpha_tilde / (h * h),
            },
        }
    }

    fn step<E: Hyperelastic<D>>(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        let mesh = model.mesh();
        let n = mesh.n_vertices();
        if n != self.n_vertices || mesh.n_cells() != self.order.len() {
            return Err(SolverError::invalid(
                "model",
                format!("{} vertices, {} cells", n, mesh.n_cells()),
                "differs from the mesh the stepper was built for: build the stepper again",
            ));
        }
        if state.x.len() != n || state.v.len() != n {
            return Err(SolverError::invalid(
                "state",
                format!("{} positions, {} velocities", state.x.len(), state.v.len()),
                format!("needs one of each per mesh vertex ({n})"),
            ));
        }
        // Inverse masses per vertex, and the fixed components.
        self.w.clear();
        self.fixed.clear();
        for (v, &m) in model.masses().iter().enumerate() {
            let bits = (0..D::D)
                .filter(|&i| model.fixed()[D::D * v + i])
                .fold(0u8, |b, i| b | 1 << i);
            self.fixed.push(bits);
            self.w.push(if bits == (1u8 << D::D) - 1 {
                0.0
            } else {
                1.0 / m
            });
        }
        let h = self.dt / self.substeps as Real;
        // The P-wave modulus `dP_00/dF_00` at rest, as the 2D model's.
        let modulus = model.energy().piola_tangent(&D::identity()).at(0);
        let law = Law {
            rule: self.rule_for(h),
            psi_threshold: self.rest_threshold * modulus,
        };
        let step = step_number(state.t, self.dt);
        self.x.clone_from(&state.x);
        self.v.clone_from(&state.v);
        let mut t = state.t;
        let mut report = StepReport {
            min_det_f: Real::INFINITY,
            inverted: 0,
            iterations: 0,
            residual: 0.0,
            contacts: 0,
        };
        for _ in 0..self.substeps {
            let r = self.substep(model, law, h, step, state.t)?;
            report = StepReport {
                iterations: report.iterations + r.iterations,
                ..r
            };
            t += h;
        }
        std::mem::swap(&mut state.x, &mut self.x);
        std::mem::swap(&mut state.v, &mut self.v);
        state.t = t;
        Ok(report)
    }

    fn substep<E: Hyperelastic<D>>(
        &mut self,
        model: &NdModel<D, E>,
        law: Law,
        h: Real,
        step: u64,
        time: Real,
    ) -> Result<StepReport, SolverError> {
        let n = self.n_vertices;
        let g = model.gravity();
        self.x_pred.resize(n, D::Vector::zeros());
        self.v_new.resize(n, D::Vector::zeros());
        self.lambda.clear();
        self.lambda.resize(self.order.len(), 0.0);

        // Prediction (fixed components keep their position, with zero velocity).
        for v in 0..n {
            let wi = self.w[v];
            let mut vn = if wi > 0.0 {
                self.v[v] + g * h
            } else {
                self.v[v]
            };
            let load = model.loads()[v];
            if load != D::Vector::zeros() {
                vn += load * (wi * h);
            }
            let x = self.x[v];
            let mut xp = x + vn * h;
            let bits = self.fixed[v];
            if bits != 0 {
                for i in 0..D::D {
                    if bits >> i & 1 == 1 {
                        vn.set_at(i, 0.0);
                        xp.set_at(i, x.at(i));
                    }
                }
            }
            self.v_new[v] = vn;
            self.x_pred[v] = xp;
        }

        // Constraint sweeps.
        let mut stats = SweepStats::EMPTY;
        let (mut sweeps, mut first) = (0, 0.0);
        for k in 0..self.iterations {
            if self.reset_lambda_each_sweep && k > 0 {
                self.lambda.fill(0.0);
            }
            stats = self.sweep(model, law);
            sweeps += 1;
            if self.tolerance > 0.0 {
                let r = stats.residual2.sqrt();
                if k == 0 {
                    first = r;
                }
                if r <= self.tolerance * first {
                    break;
                }
            }
        }

        // Velocities.
        let decay = exp(-self.damping * h);
        for ((vn, xp), x) in self.v_new.iter_mut().zip(&self.x_pred).zip(&self.x) {
            *vn = (*xp - *x) * (decay / h);
        }
        let report = StepReport {
            min_det_f: stats.inv.min_det_f,
            inverted: stats.inv.inverted,
            iterations: sweeps,
            residual: stats.residual2.sqrt(),
            contacts: 0,
        };
        check_finite::<D>(&self.x_pred, &self.v_new, step, time, &report)?;
        std::mem::swap(&mut self.x, &mut self.x_pred);
        std::mem::swap(&mut self.v, &mut self.v_new);
        Ok(report)
    }

    /// One sweep over every cell constraint in the configured order.
    fn sweep<E: Hyperelastic<D>>(&mut self, model: &NdModel<D, E>, law: Law) -> SweepStats {
        let mesh = model.mesh();
        let ctx = Cells {
            energy: model.energy(),
            cells: mesh.cells(),
            elements: mesh.elements(),
            w: &self.w,
            fixed: &self.fixed,
            law,
        };
        let mut total = SweepStats::EMPTY;
        match self.ordering {
            Ordering::GaussSeidel => {
                for (ids, lam) in
                    (self.order.chunks(ELEMENT_CHUNK)).zip(self.lambda.chunks_mut(ELEMENT_CHUNK))
                {
                    let mut st = SweepStats::EMPTY;
                    for (&c, l) in ids.iter().zip(lam) {
                        let p = ctx.project(c as usize, &self.x_pred, 1.0, l);
                        st.add(&p);
                        apply(&mut self.x_pred, ctx.cells[c as usize].as_ref(), &p);
                    }
                    total.merge(&st);
                }
            }
            Ordering::Coloured => {
                for &(a, b) in &self.ranges {
                    let ids = &self.order[a..b];
                    let len = ids.len();
                    fill(&mut self.corrections, len);
                    self.chunk_stats.clear();
                    (self.chunk_stats).resize(len.div_ceil(ELEMENT_CHUNK), SweepStats::EMPTY);
                    let x: &[D::Vector] = &self.x_pred;
                    self.corrections[..len]
                        .par_chunks_mut(ELEMENT_CHUNK)
                        .zip(self.lambda[a..b].par_chunks_mut(ELEMENT_CHUNK))
                        .zip(ids.par_chunks(ELEMENT_CHUNK))
                        .zip(self.chunk_stats.par_iter_mut())
                        .for_each(|(((out, lam), ids), st)| {
                            for ((o, l), &c) in out.iter_mut().zip(lam).zip(ids) {
                                *o = ctx.project(c as usize, x, 1.0, l);
                                st.add(o);
                            }
                        });
                    // No two cells of a colour share a vertex: applying after computing is
                    // the in-place serial sweep.
                    for (p, &c) in self.corrections[..len].iter().zip(ids) {
                        apply(&mut self.x_pred, ctx.cells[c as usize].as_ref(), p);
                    }
                    for st in &self.chunk_stats {
                        total.merge(st);
                    }
                }
            }
            Ordering::Jacobi => {
                let nc = self.order.len();
                fill(&mut self.corrections, nc);
                self.chunk_stats.clear();
                (self.chunk_stats).resize(nc.div_ceil(ELEMENT_CHUNK), SweepStats::EMPTY);
                let x: &[D::Vector] = &self.x_pred;
                let scales = &self.jacobi_scale;
                self.corrections[..nc]
                    .par_chunks_mut(ELEMENT_CHUNK)
                    .zip(self.lambda.par_chunks_mut(ELEMENT_CHUNK))
                    .zip(self.chunk_stats.par_iter_mut())
                    .enumerate()
                    .for_each(|(chunk, ((out, lam), st))| {
                        let base = chunk * ELEMENT_CHUNK;
                        for (k, (o, l)) in out.iter_mut().zip(lam).enumerate() {
                            let c = base + k;
                            *o = ctx.project(c, x, scales[c], l);
                            st.add(o);
                        }
                    });
                for st in &self.chunk_stats {
                    total.merge(st);
                }
                // Gather per vertex in cell order.
                let corr = &self.corrections[..nc];
                self.x_pred
                    .par_chunks_mut(VERTEX_CHUNK)
                    .enumerate()
                    .for_each(|(chunk, xs)| {
                        for (k, xv) in xs.iter_mut().enumerate() {
                            let v = chunk * VERTEX_CHUNK + k;
                            let mut s = D::Vector::zeros();
                            for &(c, corner) in mesh.cells_of(v) {
                                let p = &corr[c as usize];
                                if p.active {
                                    s += p.dx[corner as usize];
                                }
                            }
                            *xv += s;
                        }
                    });
            }
        }
        total
    }
}

fn fill<D: Dim>(buf: &mut Vec<Projection<D>>, n: usize) {
    if buf.len() < n {
        buf.resize_with(n, || Projection::skip(0.0, 0.0));
    }
}

/// Energy-based PBD ([`PbdParams`]) on a [`NdModel`]: one `C = V psi` constraint per cell.
pub struct NdPbd<D: Dim> {
    params: PbdParams,
    engine: Engine<D>,
}

/// Energy-based XPBD ([`XpbdParams`]) on a [`NdModel`]: one compliant `C = sqrt(2 V psi)`
/// constraint per cell (the literal `C = V psi` selectable).
pub struct NdXpbd<D: Dim> {
    params: XpbdParams,
    engine: Engine<D>,
}

impl<D: Dim> NdPbd<D> {
    /// Validate the parameters (errors name `<prefix>.<field>`) and prepare the sweep order
    /// for `model`.
    pub fn new<E: Hyperelastic<D>>(
        model: &NdModel<D, E>,
        params: PbdParams,
        prefix: &str,
    ) -> Result<Self, SolverError> {
        params.validate_as(prefix)?;
        Ok(NdPbd {
            engine: Engine::new(
                model,
                params.dt,
                params.substeps,
                params.iterations,
                params.damping,
                params.rest_threshold,
                params.ordering,
                params.relaxation,
                Rule::Pbd {
                    stiffness: params.stiffness,
                },
            ),
            params,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &PbdParams {
        &self.params
    }

    /// Number of colour classes of the coloured ordering (1 for the others).
    pub fn n_colours(&self) -> usize {
        self.engine.n_colours()
    }

    /// The cells of each class in sweep order (the colours of the coloured ordering, in which
    /// no two cells share a vertex; one class in cell order for the others).
    pub fn colours(&self) -> Vec<Vec<usize>> {
        self.engine.colours()
    }
}

impl<D: Dim> NdXpbd<D> {
    /// Validate the parameters (errors name `<prefix>.<field>`) and prepare the sweep order
    /// for `model`.
    pub fn new<E: Hyperelastic<D>>(
        model: &NdModel<D, E>,
        params: XpbdParams,
        prefix: &str,
    ) -> Result<Self, SolverError> {
        params.validate_as(prefix)?;
        let rule = match params.form {
            XpbdForm::Consistent => Rule::Consistent {
                alpha_tilde: params.compliance,
            },
            XpbdForm::Literal => Rule::Literal {
                alpha_tilde: params.compliance,
            },
        };
        let (substeps, iterations) = match params.schedule {
            XpbdSchedule::Iterations => (params.substeps, params.iterations),
            XpbdSchedule::SmallSteps => (params.substeps * params.iterations, 1),
        };
        let mut engine = Engine::new(
            model,
            params.dt,
            substeps,
            iterations,
            params.damping,
            params.rest_threshold,
            params.ordering,
            params.relaxation,
            rule,
        );
        engine.reset_lambda_each_sweep = params.lambda_reset == LambdaReset::Iteration;
        engine.tolerance = params.tolerance;
        Ok(NdXpbd { engine, params })
    }

    /// The parameters.
    pub fn params(&self) -> &XpbdParams {
        &self.params
    }

    /// Number of colour classes of the coloured ordering (1 for the others).
    pub fn n_colours(&self) -> usize {
        self.engine.n_colours()
    }

    /// The cells of each class in sweep order (the colours of the coloured ordering, in which
    /// no two cells share a vertex; one class in cell order for the others).
    pub fn colours(&self) -> Vec<Vec<usize>> {
        self.engine.colours()
    }
}

impl<D: Dim, E: Hyperelastic<D>> NdStepper<D, E> for NdPbd<D> {
    fn step(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        self.engine.step(model, state)
    }
}

impl<D: Dim, E: Hyperelastic<D>> NdStepper<D, E> for NdXpbd<D> {
    fn step(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        self.engine.step(model, state)
    }
}
