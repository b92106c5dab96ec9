//! Vertex Block Descent in either dimension: the 2D [`crate::vbd`] solver (Chen, Liu, Yang &
//! Yuksel, ACM TOG 43(4), 2024) on a simplex mesh, for a plain body (no contact, no rigid
//! regions, no grab, no averaged pressure).
//!
//! Each (sub)step of length `h` minimises implicit Euler's incremental potential
//!
//! `G(x) = sum_i m_i / (2 h^2) |x_i - x_hat_i|^2 - sum_i f_i . x_i + sum_e V_e psi(F_e)`,
//! `x_hat = x + h v`, `f = m g` plus the nodal loads,
//!
//! by Gauss-Seidel over vertex blocks: vertex `i`'s local potential (its inertia, its load and
//! the energy of the cells around it, the other vertices held) gets one Newton step with the
//! `D x D` block
//!
//! `H_i = m_i / h^2 I + sum_e V_e B_e`,  `(B_e)_ik = sum_jl g_j dP_ij/dF_kl g_l`
//! (`D::contract(dP/dF, g, g)`, the exact tangent) and the gradient
//! `m_i / h^2 (x_i - x_hat_i) - f_i + sum_e V_e P_e g` (the corner forces are `-V P g`), with
//! `g` the shape-function gradient of the vertex's corner. As in 2D, each cell's block is
//! symmetrised and its negative eigenvalues clamped to zero before it is summed (in 2D the 2D
//! solver's closed form; in 3D a symmetric eigendecomposition when a principal minor is
//! negative), so `H_i` is positive definite and the step a descent direction. A degree of
//! freedom held by the model ([`NdModel::fixed`]) keeps its value: its gradient entry is zero
//! and its row and column of `H_i` are the identity's, so the step solves the free components'
//! block; a vertex with every component held is not swept. In 2D this is the 2D solver's
//! arithmetic but for the corner block (fem-core's closed forms there): the generic test
//! measures 2e-15 m between the two over 20 steps of the cantilever.
//!
//! The corner block takes the full `D^2 x D^2` tangent per cell corner, which is most of a
//! sweep's cost in 3D (about 80 % with Neo-Hookean; the co-rotational tangent, nine rotation
//! derivatives, about ten times more).
//!
//! **Line search** (`line_search`, default off): the step is halved (up to 8 times) until the
//! local potential is finite and not above its start (within `1e-12` of its terms' scale, the
//! cells' `M V` with `M` the rest P-wave modulus); otherwise the vertex stays. Without it a
//! step is still halved while it would invert a cell of an energy that forbids inversion, tested
//! exactly by the rank-one update `det(F + s g^T) = det F + s . cof(F) g` (in any dimension).
//!
//! **Sweeps.** The free vertices are coloured greedily in index order so that no two of one
//! colour share a cell ([`VertexColouring`], the 2D solver's greedy colouring, on the cells'
//! vertex graph). A 3D vertex has more than twice the neighbours (up to 14 in the structured
//! box of tetrahedra, against 6 in the triangle beams), and the colouring takes about twice the
//! colours: measured 8 on an 8 x 4 x 4 box, 4 on the 20 x 4 triangle cantilever. Within a
//! colour the updates are computed in parallel from the same positions (fixed chunks of 512
//! vertices) and written after the colour, so a sweep equals the serial sweep in colour order,
//! bit for bit, for any number of threads.
//!
//! **Initial guess** (`init`), **Chebyshev acceleration** (`chebyshev_rho`), **substeps**,
//! **damping** (`v <- v exp(-c h)` per substep) and the **residual tolerance** (`tolerance`:
//! stop once the gradient's norm over the free degrees of freedom is at most `tolerance` times
//! Newton's force scale, the largest of the first residual, the external load's norm, the free
//! elastic forces' norm at the initial guess and `1e-12` N; 0 runs exactly `iterations` sweeps)
//! mean what they mean in 2D ([`crate::vbd`]). As there, each step converges to implicit
//! Euler's as `iterations` grow (`tests/suite/nd_vbd.rs` measures it in 3D).
//!
//! Backward Euler only: `integrator = bdf2` is refused in one line. The state is written only
//! after every substep's positions and velocities are finite; otherwise the step is an error
//! and the state stays as it was. Nothing is allocated per step after the first.

use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::{Real, exp};
use fem_core::par::prelude::*;
use fem_core::simplex::SimplexMesh;
use fem_core::simplex::assembly::{Scratch, populate_forces};
use nalgebra::{Matrix3, SymmetricEigen};

use super::{NdModel, NdState, NdStepper, check_finite, step_number};
use crate::error::SolverError;
use crate::steppers::colour::VertexColouring;
use crate::steppers::integrator::Integrator;
use crate::steppers::report::StepReport;
use crate::steppers::vbd::{VbdInit, VbdParams, VbdStats, psd2};

/// Vertices per parallel task of a colour (the 2D solver's): fixed, so the split never depends
/// on the thread count.
const VBD_CHUNK: usize = 512;
/// Halvings of a local step before the vertex is left where it is.
const LOCAL_HALVINGS: usize = 8;
/// Cells around a vertex whose orientation data an update keeps on the stack; a vertex with
/// more recomputes `det F` at each trial position instead.
const FAN: usize = 32;
/// Cells per parallel task of the inversion count.
const CELL_CHUNK: usize = 1024;

/// One vertex update: the gradient's norm before it (N), and how it went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Outcome {
    gradient: Real,
    halved: bool,
    rejected: bool,
}

/// Vertex Block Descent on a [`NdModel`]; see the module docs.
pub struct NdVbd<D: Dim> {
    params: VbdParams,
    h: Real,
    decay: Real,
    colouring: VertexColouring,
    /// Per vertex, bit `i` set when component `i` is free.
    mask: Vec<u8>,
    forbids_inversion: bool,
    /// The rest P-wave modulus of the energy, Pa: the scale of `psi`'s terms.
    modulus: Real,
    target: Vec<D::Vector>,
    load: Vec<D::Vector>,
    /// The iterate.
    x: Vec<D::Vector>,
    v_new: Vec<D::Vector>,
    /// The substep's start (positions, velocities), the step's working state.
    xs: Vec<D::Vector>,
    vs: Vec<D::Vector>,
    /// Per colour slot: the vertex's new position and its update's outcome.
    buf: Vec<D::Vector>,
    outcome: Vec<Outcome>,
    chebyshev: Chebyshev<D>,
    /// The velocities at the start of the last substep (adaptive guess), if any.
    v_prev: Option<Vec<D::Vector>>,
    stats: VbdStats,
    /// The residual test's elastic forces and assembly buffers.
    forces: Vec<D::Vector>,
    scratch: Scratch<D>,
}

impl<D: Dim> NdVbd<D> {
    /// With validated parameters, for `model`: colours the free vertices. `integrator = bdf2`
    /// is refused, naming `<prefix>.integrator`.
    pub fn new<E: Hyperelastic<D>>(
        model: &NdModel<D, E>,
        params: VbdParams,
        prefix: &str,
    ) -> Result<Self, SolverError> {
        params.validate_as(prefix)?;
        if params.integrator != Integrator::BackwardEuler {
            return Err(SolverError::invalid(
                format!("{prefix}.integrator"),
                "bdf2",
                format!("is not available in {} yet (use backward-euler)", D::NAME),
            ));
        }
        let mesh = model.mesh();
        let n = mesh.n_vertices();
        let fixed = model.fixed();
        let mask: Vec<u8> = (0..n)
            .map(|v| {
                (0..D::D)
                    .filter(|&i| !fixed[D::D * v + i])
                    .fold(0u8, |m, i| m | (1 << i))
            })
            .collect();
        let free: Vec<bool> = mask.iter().map(|&m| m != 0).collect();
        let colouring = colour(mesh, &free);
        let slots = colouring.order.len();
        let h = params.dt / params.substeps as Real;
        let energy = model.energy();
        let mut flip = D::identity();
        flip.set_at((D::D - 1) * (D::D + 1), -1.0);
        Ok(NdVbd {
            h,
            decay: exp(-params.damping * h),
            params,
            colouring,
            mask,
            forbids_inversion: !energy.density(&flip).is_finite(),
            modulus: energy.piola_tangent(&D::identity()).at(0).abs(),
            target: Vec::new(),
            load: Vec::new(),
            x: Vec::new(),
            v_new: Vec::new(),
            xs: Vec::new(),
            vs: Vec::new(),
            buf: vec![D::Vector::zeros(); slots],
            outcome: vec![Outcome::default(); slots],
            chebyshev: Chebyshev::default(),
            v_prev: None,
            stats: VbdStats::default(),
            forces: Vec::new(),
            scratch: Scratch::new(),
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

    /// The colouring of the free vertices: no two of a colour share a cell.
    pub fn colouring(&self) -> &VertexColouring {
        &self.colouring
    }

    /// What the last step did (halved and rejected updates, Chebyshev restarts, a replaced
    /// guess, the residual test's force scale).
    pub fn last_stats(&self) -> VbdStats {
        self.stats
    }

    /// Forget the previous step's velocity: the adaptive guess starts afresh.
    pub fn reset(&mut self) {
        self.v_prev = None;
    }

    /// The initial guess of a substep into `self.x` (the 2D solver's; fixed components are
    /// set by the caller).
    fn initial_guess(&mut self, masses: &[Real]) {
        let h = self.h;
        let hh = h * h;
        match self.params.init {
            VbdInit::Previous => self.x.copy_from_slice(&self.xs),
            VbdInit::Inertia => {
                for (i, x) in self.x.iter_mut().enumerate() {
                    *x = self.target[i] + self.load[i] * (hh / masses[i]);
                }
            }
            VbdInit::Adaptive => {
                for (i, x) in self.x.iter_mut().enumerate() {
                    let a_ext = self.load[i] / masses[i];
                    let norm = a_ext.norm2().sqrt();
                    let along = if norm > 0.0 {
                        let dir = a_ext / norm;
                        let along = match &self.v_prev {
                            Some(vp) => ((self.vs[i] - vp[i]) / h).inner(&dir).clamp(0.0, norm),
                            None => norm,
                        };
                        dir * along
                    } else {
                        D::Vector::zeros()
                    };
                    *x = self.target[i] + along * hh;
                }
            }
        }
    }
}

/// The greedy vertex colouring of the free vertices of `mesh`: two vertices of one cell never
/// share a colour.
fn colour<D: Dim>(mesh: &SimplexMesh<D>, free: &[bool]) -> VertexColouring {
    let cells = mesh.cells();
    VertexColouring::greedy_by(mesh.n_vertices(), free, |v| {
        mesh.cells_of(v)
            .iter()
            .flat_map(move |&(c, _)| cells[c as usize].as_ref().iter().copied())
    })
}

/// `p` with its components not in `mask` taken from `q`.
#[inline(always)]
fn hold<D: Dim>(p: &mut D::Vector, q: &D::Vector, mask: u8) {
    for i in 0..D::D {
        if mask & (1 << i) == 0 {
            p.set_at(i, q.at(i));
        }
    }
}

/// `sum_i v_i^2` over the components in `mask`.
#[inline(always)]
fn masked_norm2<D: Dim>(v: &D::Vector, mask: u8) -> Real {
    if mask as usize == (1 << D::D) - 1 {
        return v.norm2();
    }
    (0..D::D)
        .filter(|&i| mask & (1 << i) != 0)
        .map(|i| v.at(i) * v.at(i))
        .sum()
}

/// The symmetric part of `b` with its negative eigenvalues set to zero: in 2D the 2D solver's
/// closed form ([`psd2`]); in 3D unchanged when every principal minor is non-negative (it is
/// positive semi-definite), else by a symmetric eigendecomposition.
#[inline]
fn psd_block<D: Dim>(b: &D::Matrix) -> D::Matrix {
    let d = D::D;
    let mut out = D::Matrix::zeros();
    if d == 2 {
        let (p00, p01, p11) = psd2(b.at(0), 0.5 * (b.at(2) + b.at(1)), b.at(3));
        out.set_at(0, p00);
        out.set_at(1, p01);
        out.set_at(2, p01);
        out.set_at(3, p11);
        return out;
    }
    let s = Matrix3::from_fn(|i, j| {
        if i == j {
            b.at(i + d * i)
        } else {
            0.5 * (b.at(i + d * j) + b.at(j + d * i))
        }
    });
    let minor = |i: usize, j: usize| s[(i, i)] * s[(j, j)] - s[(i, j)] * s[(i, j)];
    let psd = (0..3).all(|i| s[(i, i)] >= 0.0)
        && minor(0, 1) >= 0.0
        && minor(0, 2) >= 0.0
        && minor(1, 2) >= 0.0
        && s.determinant() >= 0.0;
    let p = if psd {
        s
    } else {
        let mut eig = SymmetricEigen::new(s);
        eig.eigenvalues.iter_mut().for_each(|l| *l = l.max(0.0));
        let r = eig.recompose();
        (r + r.transpose()) * 0.5
    };
    for j in 0..3 {
        for i in 0..3 {
            out.set_at(i + d * j, p[(i, j)]);
        }
    }
    out
}

/// `H s = -g` for a symmetric positive definite `D x D` block `H`, or `None` when it is not
/// (numerically) positive definite or not finite. In 2D the 2D solver's closed form.
#[inline]
#[allow(clippy::needless_range_loop)]
fn solve_block<D: Dim>(hm: &D::Matrix, g: &D::Vector) -> Option<D::Vector> {
    let d = D::D;
    let mut s = D::Vector::zeros();
    if d == 2 {
        let (h00, h01, h11) = (hm.at(0), hm.at(2), hm.at(3));
        let det = h00 * h11 - h01 * h01;
        if det.is_nan() || det <= 0.0 {
            return None;
        }
        s.set_at(0, (h11 * g.at(0) - h01 * g.at(1)) / -det);
        s.set_at(1, (h00 * g.at(1) - h01 * g.at(0)) / -det);
        return Some(s);
    }
    // Cholesky, lower: H = L L^T.
    let mut l = [[0.0; 3]; 3];
    for j in 0..d {
        let mut diag = hm.at(j + d * j);
        for k in 0..j {
            diag -= l[j][k] * l[j][k];
        }
        if diag.is_nan() || diag <= 0.0 {
            return None;
        }
        let ljj = diag.sqrt();
        l[j][j] = ljj;
        for i in j + 1..d {
            let mut e = hm.at(i + d * j);
            for k in 0..j {
                e -= l[i][k] * l[j][k];
            }
            l[i][j] = e / ljj;
        }
    }
    let mut y = [0.0; 3];
    for i in 0..d {
        let mut e = -g.at(i);
        for k in 0..i {
            e -= l[i][k] * y[k];
        }
        y[i] = e / l[i][i];
    }
    for i in (0..d).rev() {
        let mut e = y[i];
        for k in i + 1..d {
            e -= l[k][i] * s.at(k);
        }
        s.set_at(i, e / l[i][i]);
    }
    Some(s)
}

/// The corners of cell `c` at `x`, with `corner` moved to `p` when given.
#[inline(always)]
fn corners<D: Dim>(
    mesh: &SimplexMesh<D>,
    c: usize,
    x: &[D::Vector],
    moved: Option<(u8, D::Vector)>,
) -> [D::Vector; 4] {
    let mut out = [D::Vector::zeros(); 4];
    for (k, &i) in mesh.cells()[c].as_ref().iter().enumerate() {
        out[k] = x[i as usize];
    }
    if let Some((corner, p)) = moved {
        out[corner as usize] = p;
    }
    out
}

/// `F` of cell `c` at `x`, with `corner` moved to `p` when given.
#[inline(always)]
fn deformation_gradient<D: Dim>(
    mesh: &SimplexMesh<D>,
    c: usize,
    x: &[D::Vector],
    moved: Option<(u8, D::Vector)>,
) -> D::Matrix {
    let k = corners(mesh, c, x, moved);
    mesh.elements()[c].deformation_gradient(&k[..D::NODES])
}

/// The smallest `det F` over the cells at `x` and the number with `det F <= 0` (exact, so the
/// same for any split).
fn inversion<D: Dim>(mesh: &SimplexMesh<D>, x: &[D::Vector]) -> (Real, usize) {
    let n = mesh.n_cells();
    mesh.elements()
        .par_chunks(CELL_CHUNK)
        .enumerate()
        .map(|(k, _)| {
            let mut s = (Real::INFINITY, 0usize);
            for c in k * CELL_CHUNK..((k + 1) * CELL_CHUNK).min(n) {
                let j = D::det(&deformation_gradient(mesh, c, x, None));
                s.0 = s.0.min(j);
                s.1 += usize::from(j <= 0.0);
            }
            s
        })
        .reduce(|| (Real::INFINITY, 0), |a, b| (a.0.min(b.0), a.1 + b.1))
}

/// What a vertex update reads.
struct Local<'a, D: Dim, E> {
    model: &'a NdModel<D, E>,
    mask: &'a [u8],
    /// The inertia weight `1 / h^2`.
    w: Real,
    target: &'a [D::Vector],
    load: &'a [D::Vector],
    line_search: bool,
    forbids_inversion: bool,
    modulus: Real,
}

impl<D: Dim, E: Hyperelastic<D>> Local<'_, D, E> {
    /// The local potential of vertex `v` at `p` (the others at `x`), measured from its inertia
    /// and load terms at `x[v]` so that round-off stays that of the changes.
    fn potential(&self, v: usize, x: &[D::Vector], p: D::Vector) -> Real {
        let mesh = self.model.mesh();
        let mw = self.model.masses()[v] * self.w;
        let mut e = 0.5 * mw * (p - self.target[v]).norm2() - self.load[v].inner(&(p - x[v]));
        for &(c, corner) in mesh.cells_of(v) {
            let f = deformation_gradient(mesh, c as usize, x, Some((corner, p)));
            e += mesh.elements()[c as usize].measure * self.model.energy().density(&f);
        }
        e
    }

    /// Whether moving vertex `v` to `p` keeps every cell around it uninverted.
    fn keeps_orientation(&self, v: usize, x: &[D::Vector], p: D::Vector) -> bool {
        let mesh = self.model.mesh();
        mesh.cells_of(v).iter().all(|&(c, corner)| {
            D::det(&deformation_gradient(
                mesh,
                c as usize,
                x,
                Some((corner, p)),
            )) > 0.0
        })
    }

    /// One Newton step on vertex `v`'s local potential: the new position and the outcome.
    #[inline]
    fn update(&self, v: usize, x: &[D::Vector]) -> (D::Vector, Outcome) {
        let mesh = self.model.mesh();
        let energy = self.model.energy();
        let mask = self.mask[v];
        let xi = x[v];
        let mw = self.model.masses()[v] * self.w;
        let mut g = (xi - self.target[v]) * mw - self.load[v];
        let mut hm = D::identity() * mw;
        let search = self.line_search;
        let (mut elastic, mut elastic_magnitude, mut local_scale) = (0.0, 0.0, 0.0);
        // For the orientation test: per cell, det F and w = cof(F) g, since moving the vertex
        // by s gives det(F + s g^T) = det F + s . w exactly (a rank-one update).
        let mut fan_det = [0.0; FAN];
        let mut fan_w = [D::Vector::zeros(); FAN];
        let fan = mesh.cells_of(v);
        let cheap_orientation = self.forbids_inversion && !search && fan.len() <= FAN;
        for (i, &(c, corner)) in fan.iter().enumerate() {
            let el = &mesh.elements()[c as usize];
            local_scale += self.modulus * el.measure;
            let f = deformation_gradient(mesh, c as usize, x, None);
            if search {
                let psi = energy.density(&f);
                elastic += el.measure * psi;
                elastic_magnitude += el.measure * psi.abs();
            }
            let ga = el.gradient(corner as usize);
            let p = energy.piola(&f);
            let block = D::contract(&energy.piola_tangent(&f), &ga, &ga);
            if cheap_orientation {
                fan_det[i] = D::det(&f);
                fan_w[i] = D::cofactor(&f) * ga;
            }
            g += (p * ga) * el.measure;
            hm += psd_block::<D>(&(block * el.measure));
        }
        // Held components: no gradient, an identity row and column (the free block is solved).
        if mask as usize != (1 << D::D) - 1 {
            for i in (0..D::D).filter(|&i| mask & (1 << i) == 0) {
                g.set_at(i, 0.0);
                for j in 0..D::D {
                    hm.set_at(i + D::D * j, 0.0);
                    hm.set_at(j + D::D * i, 0.0);
                }
                hm.set_at(i + D::D * i, 1.0);
            }
        }
        let gradient = g.norm2().sqrt();
        let mut out = Outcome {
            gradient,
            halved: false,
            rejected: false,
        };
        // A NaN gradient or block fails here too: the vertex stays, the NaN is reported.
        let step = match solve_block::<D>(&hm, &g) {
            Some(s) if gradient.is_finite() => {
                let mut s = s;
                hold::<D>(&mut s, &D::Vector::zeros(), mask);
                s
            }
            _ => {
                out.rejected = gradient.is_finite();
                return (xi, out);
            }
        };
        if !search && !self.forbids_inversion {
            return (xi + step, out);
        }
        // The starting value, in the same frame as `potential` (inertia and load from x[v]).
        let inertia = 0.5 * mw * (xi - self.target[v]).norm2();
        let start = inertia + elastic;
        // The round-off of the local potential: eps times its terms, psi's of the order of
        // the modulus (the 2D solver's floor).
        let floor = 1e-12 * (inertia + elastic_magnitude + local_scale);
        let mut fan_rate = [0.0; FAN];
        if cheap_orientation {
            for (r, w) in fan_rate.iter_mut().zip(&fan_w[..fan.len()]) {
                *r = step.inner(w);
            }
        }
        let mut alpha = 1.0;
        for k in 0..=LOCAL_HALVINGS {
            let p = xi + step * alpha;
            let ok = if search {
                let e = self.potential(v, x, p);
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
}

/// One sweep over the colours of `c`, moving `x`; returns the largest gradient norm seen (NaN
/// if any was NaN).
fn sweep<D: Dim, E: Hyperelastic<D>>(
    local: &Local<'_, D, E>,
    c: &VertexColouring,
    x: &mut [D::Vector],
    (buf, outcome): (&mut [D::Vector], &mut [Outcome]),
    stats: &mut VbdStats,
) -> Real {
    let mut largest: Real = 0.0;
    for k in 0..c.n_colours() {
        let (a, b) = (c.offsets[k], c.offsets[k + 1]);
        let order = &c.order[a..b];
        let xr = &*x;
        buf[a..b]
            .par_chunks_mut(VBD_CHUNK)
            .zip(outcome[a..b].par_chunks_mut(VBD_CHUNK))
            .zip(order.par_chunks(VBD_CHUNK))
            .for_each(|((buf, outcome), order)| {
                for ((p, o), &v) in buf.iter_mut().zip(outcome.iter_mut()).zip(order) {
                    (*p, *o) = local.update(v as usize, xr);
                }
            });
        for ((&v, p), o) in order.iter().zip(&buf[a..b]).zip(&outcome[a..b]) {
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

/// The residual test: the norm of the gradient of the substep's potential at `local`'s
/// iterate `x` over the free degrees of freedom (N), summed in colour order, and with
/// `elastic` also the norm of the elastic forces on them (else 0).
fn gradient_norm<D: Dim, E: Hyperelastic<D>>(
    local: &Local<'_, D, E>,
    x: &[D::Vector],
    free: &[u32],
    (forces, scratch): (&mut [D::Vector], &mut Scratch<D>),
    elastic: bool,
) -> (Real, Real) {
    let model = local.model;
    populate_forces(model.mesh(), model.energy(), x, scratch, forces);
    let masses = model.masses();
    let mut elastic_sq = 0.0;
    if elastic {
        for &v in free {
            elastic_sq += masked_norm2::<D>(&forces[v as usize], local.mask[v as usize]);
        }
    }
    let mut sq = 0.0;
    for &v in free {
        let v = v as usize;
        let g = (x[v] - local.target[v]) * (masses[v] * local.w) - local.load[v] - forces[v];
        sq += masked_norm2::<D>(&g, local.mask[v]);
    }
    (sq.sqrt(), elastic_sq.sqrt())
}

/// Chebyshev's iterates (the 2D solver's): the positions after sweeps `k - 2` and `k - 1`,
/// the plain result of sweep `k`, and the sequence's state.
struct Chebyshev<D: Dim> {
    prev: Vec<D::Vector>,
    last: Vec<D::Vector>,
    plain: Vec<D::Vector>,
    k: usize,
    omega: Real,
}

impl<D: Dim> Default for Chebyshev<D> {
    fn default() -> Self {
        Chebyshev {
            prev: Vec::new(),
            last: Vec::new(),
            plain: Vec::new(),
            k: 0,
            omega: 1.0,
        }
    }
}

impl<D: Dim> Chebyshev<D> {
    /// Start a sequence at `x`.
    fn start(&mut self, x: &[D::Vector]) {
        if self.prev.len() != x.len() {
            self.prev = vec![D::Vector::zeros(); x.len()];
            self.last = vec![D::Vector::zeros(); x.len()];
            self.plain = vec![D::Vector::zeros(); x.len()];
        }
        self.last.copy_from_slice(x);
        self.k = 0;
        self.omega = 1.0;
    }

    /// Extrapolate the free vertices (`free`) of `x`, just iterated; an extrapolation that
    /// inverts a cell (when `forbids_inversion`) is dropped and the sequence restarts
    /// (returns true). Held components stay: they are equal in every iterate.
    fn apply(
        &mut self,
        rho: Real,
        x: &mut [D::Vector],
        free: &[u32],
        mesh: &SimplexMesh<D>,
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
            if forbids_inversion && inversion(mesh, x).1 > 0 {
                x.copy_from_slice(&self.plain);
                self.start(x);
                return true;
            }
        }
        std::mem::swap(&mut self.prev, &mut self.last);
        self.last.copy_from_slice(x);
        false
    }
}

impl<D: Dim, E: Hyperelastic<D>> NdStepper<D, E> for NdVbd<D> {
    fn step(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        let mesh = model.mesh();
        let n = mesh.n_vertices();
        if state.x.len() != n || state.v.len() != n {
            return Err(SolverError::invalid(
                "state",
                format!("{} positions, {} velocities", state.x.len(), state.v.len()),
                format!("needs one per mesh vertex ({n})"),
            ));
        }
        for buf in [
            &mut self.target,
            &mut self.load,
            &mut self.x,
            &mut self.v_new,
        ] {
            buf.resize(n, D::Vector::zeros());
        }
        self.xs.clear();
        self.xs.extend_from_slice(&state.x);
        self.vs.clear();
        self.vs.extend_from_slice(&state.v);
        if self.params.tolerance > 0.0 {
            self.forces.resize(n, D::Vector::zeros());
        }
        let step = step_number(state.t, self.params.dt);
        let h = self.h;
        let (w, rho, tolerance) = (
            1.0 / (h * h),
            self.params.chebyshev_rho,
            self.params.tolerance,
        );
        for (v, l) in self.load.iter_mut().enumerate() {
            *l = model.external_force(v);
        }
        let mut stats = VbdStats::default();
        let mut report = StepReport {
            min_det_f: Real::INFINITY,
            inverted: 0,
            iterations: 0,
            residual: 0.0,
            contacts: 0,
        };
        let mut t = state.t;
        for _ in 0..self.params.substeps {
            for (v, xh) in self.target.iter_mut().enumerate() {
                *xh = self.xs[v] + self.vs[v] * h;
                hold::<D>(xh, &self.xs[v], self.mask[v]);
            }
            self.initial_guess(model.masses());
            for (v, x) in self.x.iter_mut().enumerate() {
                hold::<D>(x, &self.xs[v], self.mask[v]);
            }
            if self.forbids_inversion && inversion(mesh, &self.x).1 > 0 {
                self.x.copy_from_slice(&self.xs);
                stats.fallback_guess = true;
            }
            let local = Local {
                model,
                mask: &self.mask,
                w,
                target: &self.target,
                load: &self.load,
                line_search: self.params.line_search,
                forbids_inversion: self.forbids_inversion,
                modulus: self.modulus,
            };
            if rho > 0.0 {
                self.chebyshev.start(&self.x);
            }
            let mut residual = 0.0;
            let mut goal = 0.0;
            let mut converged = false;
            if tolerance > 0.0 {
                let (first, elastic) = gradient_norm(
                    &local,
                    &self.x,
                    &self.colouring.order,
                    (&mut self.forces, &mut self.scratch),
                    true,
                );
                // Newton's force scale (the 2D solver's `force_scale`): the load's norm over
                // every vertex, as there.
                let load: Real = self.load.iter().map(Dense::norm2).sum::<Real>().sqrt();
                stats.force_scale = first.max(load).max(elastic).max(1e-12);
                goal = tolerance * stats.force_scale;
                residual = first;
                converged = first <= goal;
            }
            for _ in 0..self.params.iterations {
                if converged {
                    break;
                }
                residual = sweep(
                    &local,
                    &self.colouring,
                    &mut self.x,
                    (&mut self.buf, &mut self.outcome),
                    &mut stats,
                );
                if rho > 0.0 {
                    let restarted = self.chebyshev.apply(
                        rho,
                        &mut self.x,
                        &self.colouring.order,
                        mesh,
                        self.forbids_inversion,
                    );
                    stats.chebyshev_restarts += usize::from(restarted);
                }
                report.iterations += 1;
                if tolerance > 0.0 {
                    residual = gradient_norm(
                        &local,
                        &self.x,
                        &self.colouring.order,
                        (&mut self.forces, &mut self.scratch),
                        false,
                    )
                    .0;
                    converged = residual <= goal;
                }
            }
            // The adaptive guess of the next substep reads this substep's starting velocity.
            let prev_v = self
                .v_prev
                .get_or_insert_with(|| vec![D::Vector::zeros(); n]);
            prev_v.copy_from_slice(&self.vs);
            // The end of the substep: velocities, held components at rest, the finite check.
            let (min_det_f, inverted) = inversion(mesh, &self.x);
            for v in 0..n {
                let mut vel = (self.x[v] - self.xs[v]) / h * self.decay;
                hold::<D>(&mut vel, &D::Vector::zeros(), self.mask[v]);
                self.v_new[v] = vel;
            }
            report.min_det_f = min_det_f;
            report.inverted = inverted;
            report.residual = residual;
            check_finite::<D>(&self.x, &self.v_new, step, t, &report)?;
            std::mem::swap(&mut self.xs, &mut self.x);
            std::mem::swap(&mut self.vs, &mut self.v_new);
            t += h;
        }
        self.stats = stats;
        std::mem::swap(&mut state.x, &mut self.xs);
        std::mem::swap(&mut state.v, &mut self.vs);
        state.t = t;
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fem_core::dim::{D2, D3, Mat3, Vec3};
    use fem_core::math::{Mat2, Vec2};

    #[test]
    fn psd_block_keeps_psd_blocks_and_clamps_negative_eigenvalues() {
        // 2D: the 2D solver's closed form.
        let b = Mat2::new(2.0, 0.4, 0.6, 1.0);
        assert_eq!(psd_block::<D2>(&b), Mat2::new(2.0, 0.5, 0.5, 1.0));
        // 3D: a PSD (singular) block is kept; diag(3, -1, 2) rotated keeps 3 and 2.
        let s = Mat3::new(1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 2.0);
        assert_eq!(psd_block::<D3>(&s), s);
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.7).into_inner();
        let d = r * Mat3::from_diagonal(&Vec3::new(3.0, -1.0, 2.0)) * r.transpose();
        let want = r * Mat3::from_diagonal(&Vec3::new(3.0, 0.0, 2.0)) * r.transpose();
        assert!((psd_block::<D3>(&d) - want).norm() < 1e-13);
    }

    #[test]
    fn solve_block_is_the_inverse_and_refuses_indefinite_blocks() {
        let h = Mat3::new(4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 2.0);
        let g = Vec3::new(0.3, -1.0, 2.0);
        let s = solve_block::<D3>(&h, &g).unwrap();
        assert!((h * s + g).norm() < 1e-14);
        let s2 = solve_block::<D2>(&Mat2::new(2.0, 0.5, 0.5, 1.0), &Vec2::new(1.0, 1.0)).unwrap();
        assert!((Mat2::new(2.0, 0.5, 0.5, 1.0) * s2 + Vec2::new(1.0, 1.0)).norm() < 1e-15);
        assert!(solve_block::<D3>(&Mat3::from_diagonal(&Vec3::new(1.0, -1.0, 1.0)), &g).is_none());
        assert!(solve_block::<D3>(&(h * Real::NAN), &g).is_none());
    }
}
