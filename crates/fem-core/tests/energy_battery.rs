//! The derivative battery, applied to every energy by one macro, in both dimensions.
//!
//! `energy_battery!` gives each energy a module (`stvk`, `corotational`, `neo_hookean`,
//! `stable_neo_hookean`, `linear`) with three groups of tests.
//!
//! **The 2D kernel** (`<energy>::*`, the [`Energy`] trait every 2D solver runs), at random
//! deformation gradients (and inverted ones where the energy is defined there: all but
//! neo-hookean):
//! - `P` equals the central-difference gradient of `psi`;
//! - `dP/dF` equals the central-difference Jacobian of `P`, and is symmetric;
//! - the rest state `F = I` is stress-free and has zero energy;
//! - frame indifference: `psi(Q F) = psi(F)` and `P(Q F) = Q P(F)` for rotations `Q`
//!   (linear elasticity must instead *fail* this, which is checked too);
//! - the linearisation at `F = I` equals linear elasticity with the same Lamé parameters;
//! - the projected `dP/dF` is symmetric positive semi-definite, equals `dP/dF` where that is
//!   already PSD, and is positive definite at rest;
//! - the closed-form projection each energy overrides `dpk1_projected` with equals the general
//!   one (an iterative eigendecomposition, `project_psd`) to `1e-10` relative to `|dP/dF|`, at
//!   random, inverted (where defined), near-isotropic (`s_1 = s_2`) and near-flip
//!   (`s_1 = -s_2`) deformation gradients, and the samples do exercise the clamping;
//! - the batched `pk1_lanes` equals `pk1` lane by lane, bit for bit;
//! - the corner block `pk1_corner_block` returns `pk1` bit for bit and the contraction of
//!   `dP/dF` with the corner gradient to round-off (`1e-12` relative to its largest entry),
//!   and is symmetric.
//!
//! **The generic definitions** (`<energy>::d2::*` and `<energy>::d3::*`: [`Hyperelastic<D>`],
//! written once over `F`, checked by the same generic functions instantiated with [`D2`] and
//! [`D3`]), at random `D x D` deformation gradients (and inverted ones where defined):
//! - `piola` equals the central-difference gradient of `density`, `piola_tangent` the
//!   central-difference Jacobian of `piola`, and `piola_tangent` is symmetric;
//! - `F = I` has zero energy and zero stress;
//! - frame indifference for random proper rotations (3D: uniform axis and angle), which
//!   linear elasticity must fail;
//! - the linearisation at `F = I` equals `Linear`'s tangent, whose spectrum is checked against
//!   the textbook one (`0` on the `D(D-1)/2` infinitesimal rotations, `2 mu` on the
//!   `D(D+1)/2 - 1` deviatoric strains, `D lambda + 2 mu` on the dilatation);
//! - `piola_tangent_projected` is symmetric PSD, equals the tangent where that is PSD, and has
//!   exactly `D(D+1)/2` positive eigenvalues at rest;
//! - the closed-form isotropic projection ([`Dim::project_psd_isotropic`]) equals the general
//!   one ([`Dim::project_psd`]) to `1e-10` relative at random, inverted (where defined),
//!   near-isotropic (two, and in 3D three, equal singular values; exactly and up to `1e-9`
//!   relative) and near-flip (`s_i = -s_j`) samples, and the samples exercise the clamp for
//!   every energy but the (constant, PSD) linear one, which must need none;
//! - in `d2` only: `Hyperelastic<D2>` agrees with the 2D [`Energy`] kernel (`psi`, `P`,
//!   `dP/dF`, the projected `dP/dF` and the Cauchy stress) to `1e-12` relative, at random and
//!   inverted samples (neo-hookean's `+inf`/NaN at inversion included).
//!
//! **Across dimensions** (`plane_strain::*`): the 3D body at `F = diag(F_2D, 1)` is the 2D
//! plane-strain body: same `psi`, in-plane block of `P` and of `dP/dF`, zero out-of-plane
//! shear stress, and `sigma_zz` equal to [`Energy::cauchy_zz`], to `1e-12` relative, for every
//! energy but stable Neo-Hookean, whose constants depend on the dimension (see
//! `energy/hyperelastic.rs`): there the 2D and 3D bodies are checked to agree to second order
//! at the identity (equal tangents, an `O(eps^3)` energy difference) and to differ at large
//! strain. Co-rotational agrees at inverted `F` only while the 3D reflection stays in the plane
//! (the smaller in-plane singular value below 1); past that the 3D polar rotation flips `z`
//! instead, a departure the tests pin down too.
//!
//! **Loose ends**: `any_energy_*` check the run-time dispatch against the concrete types, bit
//! for bit, for both traits (and `Hyperelastic<D>` in both dimensions); the generic Neo-Hookean
//! reports inversion in both dimensions; the generic sampler visits the 2D battery's matrices
//! in 2D.
//!
//! Tolerances. The FD oracle sweeps steps `1e-2..1e-8` and keeps the best: for these smooth
//! functions of O(1) arguments with O(1e3) values the best central difference is accurate to
//! about 1e-10 relative, so the threshold `FD_TOL = 1e-7` leaves three decades of margin while a
//! wrong term (a missing factor, a transposed index) gives errors of order 1e-2 to 1. The 3D
//! functions (9 arguments, an SVD inside co-rotational) are as smooth and land in the same
//! range (worst seen: 5e-10), so the same threshold holds. Identities that involve only
//! round-off (rest stress, frame indifference, the linearisation, 2D kernel vs generic code,
//! plane strain vs 3D) use `ROUND_OFF = 1e-12` relative to the modulus `lambda + 2 mu` (or to
//! the compared quantity when larger): the two sides differ only in the order of a few dozen
//! operations on O(1e3) numbers, so by a few ulps (worst seen, 2D kernel vs generic code and
//! plane strain vs 3D: 1e-15). The projections use
//! `1e-10` relative to `|dP/dF|`, as the 2D battery does: an iterative eigendecomposition is
//! accurate to a small multiple of `eps |dP/dF|` (worst seen: 4e-15), even at the repeated
//! eigenvalues of the near-isotropic samples where its eigenvectors (not the projection) are
//! ill-determined; a wrong eigenbasis or a missed clamp is off by O(1). A sample counts as
//! clamped when its tangent has an eigenvalue below `-1e-12 |dP/dF|` (the zero eigenvalues of
//! the rotations come out as `+-1e-13` in 3D).
//!
//! Lamé parameters are `E = 1000`, `nu = 0.3` in plane strain, which are the true 3D Lamé
//! parameters, so both dimensions use the same pair.

mod common;

use common::Rng;
use fem_core::dim::{D2, D3, Dense, Dim, Mat3, Mat9};
use fem_core::energy::{
    AnyEnergy, Corotational, Energy, Hyperelastic, Linear, NeoHookean, StableNeoHookean, Stvk,
    contract_corner, project_psd, svd_rotation_variant,
};
use fem_core::fd::{FdOptions, check_gradient, check_jacobian};
use fem_core::material::{Material, PlaneModel};
use fem_core::math::{LANES, Mat2, Mat2Lanes, Mat4, Real, Vec2, rotation, unvec, vec};
use fem_core::{Lame, dispatch_energy};
use nalgebra::SymmetricEigen;

const FD_TOL: Real = 1e-7;
const ROUND_OFF: Real = 1e-12;
const SAMPLES: usize = 40;

fn lame() -> Lame {
    // Case A's material: E = 1000 Pa, nu = 0.3 (mu ~ 385, lambda ~ 577).
    Material::new(1000.0, 0.3, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain)
}

fn modulus() -> Real {
    let l = lame();
    l.lambda() + 2.0 * l.mu()
}

/// Deformation gradients the battery visits: moderate and large strains, all with `J > 0.2`,
/// plus inverted ones when the energy is defined there.
fn samples(seed: u64, inverted: bool) -> Vec<Mat2> {
    let mut rng = Rng::new(seed);
    let mut fs: Vec<Mat2> = (0..SAMPLES)
        .map(|k| rng.deformation_gradient(if k % 2 == 0 { 0.3 } else { 0.8 }, 0.2))
        .collect();
    if inverted {
        for _ in 0..SAMPLES / 4 {
            let mut f = rng.deformation_gradient(0.3, 0.2);
            f.set_column(0, &(-f.column(0)));
            fs.push(f);
        }
    }
    fs
}

fn check_pk1_matches_fd_gradient_of_psi<E: Energy>(e: &E, fs: &[Mat2]) {
    for f in fs {
        let grad = vec(&e.pk1(f));
        let r = check_gradient(
            |v| e.psi(&unvec(&nalgebra::Vector4::from_column_slice(v))),
            vec(f).as_slice(),
            grad.as_slice(),
            &FdOptions::default(),
        );
        assert!(
            r.relative_error < FD_TOL,
            "{}: P differs from dpsi/dF at F = {f:?}: relative error {:e} (step {:e})",
            e.name(),
            r.relative_error,
            r.step
        );
    }
}

fn check_dpk1_matches_fd_jacobian_of_pk1<E: Energy>(e: &E, fs: &[Mat2]) {
    for f in fs {
        let jac = e.dpk1(f);
        // check_jacobian wants the Jacobian row-major; nalgebra stores column-major.
        let row_major: Vec<Real> = jac.transpose().as_slice().to_vec();
        let r = check_jacobian(
            |v| {
                vec(&e.pk1(&unvec(&nalgebra::Vector4::from_column_slice(v))))
                    .as_slice()
                    .to_vec()
            },
            vec(f).as_slice(),
            &row_major,
            &FdOptions::default(),
        );
        assert!(
            r.relative_error < FD_TOL,
            "{}: dP/dF differs from the FD Jacobian of P at F = {f:?}: relative error {:e}",
            e.name(),
            r.relative_error
        );
    }
}

fn check_rest_state_is_stress_free<E: Energy>(e: &E) {
    let i = Mat2::identity();
    assert!(
        e.psi(&i).abs() < ROUND_OFF * modulus(),
        "{}: psi(I) = {}",
        e.name(),
        e.psi(&i)
    );
    let p = e.pk1(&i);
    assert!(
        p.norm() < ROUND_OFF * modulus(),
        "{}: P(I) = {p:?}",
        e.name()
    );
}

fn check_frame_indifferent<E: Energy>(e: &E, fs: &[Mat2]) {
    for (k, f) in fs.iter().enumerate() {
        let q = rotation(0.37 + 1.1 * k as Real);
        let (psi, psi_q) = (e.psi(f), e.psi(&(q * f)));
        assert!(
            (psi - psi_q).abs() <= ROUND_OFF * modulus().max(psi.abs()),
            "{}: psi(QF) = {psi_q} but psi(F) = {psi} at F = {f:?}",
            e.name()
        );
        let (p, p_q) = (q * e.pk1(f), e.pk1(&(q * f)));
        assert!(
            (p - p_q).norm() <= ROUND_OFF * modulus().max(p.norm()),
            "{}: P(QF) != Q P(F) at F = {f:?}",
            e.name()
        );
    }
}

fn check_linearisation_is_linear_elasticity<E: Energy>(e: &E) {
    let reference = Linear::new(lame()).unwrap().dpk1(&Mat2::identity());
    let tangent = e.dpk1(&Mat2::identity());
    let err = (tangent - reference).norm() / reference.norm();
    assert!(
        err < ROUND_OFF,
        "{}: dP/dF(I) differs from linear elasticity by {err:e} relative:\n{tangent}\nvs\n{reference}",
        e.name()
    );
}

fn check_projected_dpk1_is_psd<E: Energy>(e: &E, fs: &[Mat2]) {
    for f in fs {
        let h = e.dpk1(f);
        let p = e.dpk1_projected(f);
        let scale = h.norm().max(1.0);
        assert!(
            (p - p.transpose()).norm() <= ROUND_OFF * scale,
            "{}: projected dP/dF is not symmetric",
            e.name()
        );
        let eig = SymmetricEigen::new(p).eigenvalues;
        assert!(
            eig.min() >= -ROUND_OFF * scale,
            "{}: projected dP/dF has eigenvalue {} at F = {f:?}",
            e.name(),
            eig.min()
        );
        let eig_h = SymmetricEigen::new((h + h.transpose()) * 0.5).eigenvalues;
        if eig_h.min() >= 0.0 {
            assert!(
                (p - h).norm() <= 1e-10 * scale,
                "{}: projection changed an already PSD dP/dF at F = {f:?}",
                e.name()
            );
        }
    }
    let at_rest = SymmetricEigen::new(e.dpk1_projected(&Mat2::identity())).eigenvalues;
    // At rest the tangent is linear elasticity: eigenvalues 2 mu (deviatoric, twice),
    // 2 (mu + lambda) (volumetric) and 0 (infinitesimal rotation), so PSD with one zero.
    let positive = at_rest.iter().filter(|&&l| l > 1e-9 * modulus()).count();
    assert_eq!(
        positive,
        3,
        "{}: rest tangent eigenvalues {at_rest}",
        e.name()
    );
}

/// The closed-form projection against the general one (see the module docs). Returns how many
/// samples had a negative eigenvalue clamped.
fn check_closed_form_projection<E: Energy>(e: &E, fs: &[Mat2], inverted: bool) -> usize {
    let mut rng = Rng::new(11);
    let mut fs = fs.to_vec();
    for k in 0..SAMPLES {
        let s = rng.uniform(0.3, 1.8);
        let q = rotation(rng.uniform(0.0, 6.0));
        // Equal singular values, and equal up to a relative 1e-9 (the twist eigenvalue's
        // `(psi_1 - psi_2) / (s_1 - s_2)` is a 0/0 there).
        let t = if k % 2 == 0 { 1.0 } else { 1.0 + 1e-9 };
        fs.push(q * Mat2::new(s, 0.0, 0.0, s * t) * rotation(rng.uniform(0.0, 6.0)));
        if inverted {
            // s_1 = -s_2: the flip eigenvalue's `(psi_1 + psi_2) / (s_1 + s_2)` is a 0/0.
            fs.push(q * Mat2::new(s, 0.0, 0.0, -s * t) * rotation(rng.uniform(0.0, 6.0)));
        }
    }
    let mut clamped = 0;
    for f in &fs {
        let (u, sv, v) = svd_rotation_variant(f);
        assert!(
            (u * Mat2::from_diagonal(&sv) * v.transpose() - f).norm() <= 1e-14 * f.norm(),
            "svd of {f:?}"
        );
        assert!((u.determinant() - 1.0).abs() < 1e-14 && (v.determinant() - 1.0).abs() < 1e-14);
        let h = e.dpk1(f);
        if !h.iter().all(|x| x.is_finite()) {
            continue;
        }
        let general = project_psd(&h);
        let closed = e.dpk1_projected(f);
        let err = (closed - general).norm() / h.norm().max(Real::MIN_POSITIVE);
        assert!(
            err <= 1e-10,
            "{}: closed-form projection differs from the general one by {err:e} relative at F = {f:?}:\n{closed}\nvs\n{general}",
            e.name()
        );
        let sym = (h + h.transpose()) * 0.5;
        if SymmetricEigen::new(sym).eigenvalues.min() < 0.0 {
            clamped += 1;
        }
    }
    clamped
}

/// The first Piola-Kirchhoff stress is the gradient of psi, so `dP/dF` must be symmetric.
fn check_dpk1_is_symmetric<E: Energy>(e: &E, fs: &[Mat2]) {
    for f in fs {
        let h: Mat4 = e.dpk1(f);
        assert!(
            (h - h.transpose()).norm() <= 1e-10 * h.norm().max(1.0),
            "{}: dP/dF is not symmetric at F = {f:?}",
            e.name()
        );
    }
}

/// The batched `pk1_lanes` equals `pk1` lane by lane, bit for bit (NaN where `pk1` is NaN), so
/// kernels may batch elements without changing results.
fn check_pk1_lanes_equals_pk1<E: Energy>(e: &E, fs: &[Mat2]) {
    for batch in fs.chunks(LANES) {
        let mut mats = [Mat2::identity(); LANES];
        mats[..batch.len()].copy_from_slice(batch);
        let p = e.pk1_lanes(&Mat2Lanes::from_mats(&mats));
        for (i, f) in mats.iter().enumerate() {
            let (got, want) = (p.lane(i), e.pk1(f));
            for (g, w) in got.iter().zip(want.iter()) {
                assert!(
                    g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan()),
                    "{}: pk1_lanes differs from pk1 at F = {f:?}: {got:?} vs {want:?}",
                    e.name()
                );
            }
        }
    }
}

/// `pk1_corner_block(F, g)`: `P` bit for bit, and the block equal to the contraction of
/// `dP/dF` (checked against finite differences above) to round-off, symmetric.
fn check_corner_block<E: Energy>(e: &E, fs: &[Mat2]) {
    let mut rng = Rng::new(11);
    for f in fs {
        for _ in 0..3 {
            let g = Vec2::new(rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0));
            let (p, b) = e.pk1_corner_block(f, &g);
            let want_p = e.pk1(f);
            for (x, y) in p.iter().zip(want_p.iter()) {
                assert!(
                    x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()),
                    "{}: P of the corner block differs from pk1 at F = {f:?}",
                    e.name()
                );
            }
            let want = contract_corner(&e.dpk1(f), &g);
            let scale = want.abs().max().max(modulus() * g.norm_squared());
            let err = (b - want).abs().max();
            assert!(
                err <= ROUND_OFF * scale,
                "{}: corner block at F = {f:?}, g = {g:?}: {b:?} vs {want:?} (error {err:e})",
                e.name()
            );
            assert!((b[(0, 1)] - b[(1, 0)]).abs() <= ROUND_OFF * scale);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The generic battery: `Hyperelastic<D>`, each check written once and run for `D2` and `D3`.

/// What the generic battery needs of a dimension beyond [`Dim`]: random samples and the whole
/// spectrum of a tangent.
trait Battery: Dim {
    /// [`Rng::deformation_gradient`] in this dimension.
    fn random_f(rng: &mut Rng, amp: Real, min_det: Real) -> Self::Matrix;
    /// A random proper rotation.
    fn random_rotation(rng: &mut Rng) -> Self::Matrix;
    /// The eigenvalues of the tangent's symmetric part, ascending.
    fn spectrum(t: &Self::Tangent) -> Vec<Real>;
}

impl Battery for D2 {
    fn random_f(rng: &mut Rng, amp: Real, min_det: Real) -> Mat2 {
        rng.deformation_gradient(amp, min_det)
    }
    fn random_rotation(rng: &mut Rng) -> Mat2 {
        rotation(rng.uniform(0.0, std::f64::consts::TAU))
    }
    fn spectrum(t: &Mat4) -> Vec<Real> {
        ascending(
            SymmetricEigen::new((t + t.transpose()) * 0.5)
                .eigenvalues
                .as_slice(),
        )
    }
}

impl Battery for D3 {
    fn random_f(rng: &mut Rng, amp: Real, min_det: Real) -> Mat3 {
        rng.deformation_gradient3(amp, min_det)
    }
    fn random_rotation(rng: &mut Rng) -> Mat3 {
        rng.rotation3()
    }
    fn spectrum(t: &Mat9) -> Vec<Real> {
        ascending(
            SymmetricEigen::new((t + t.transpose()) * 0.5)
                .eigenvalues
                .as_slice(),
        )
    }
}

fn ascending(v: &[Real]) -> Vec<Real> {
    let mut v = v.to_vec();
    v.sort_by(Real::total_cmp);
    v
}

/// The entries in column-major order (`vec(F)` for a matrix).
fn flat<M: Dense>(m: &M) -> Vec<Real> {
    (0..M::LEN).map(|k| m.at(k)).collect()
}

/// Inverse of [`flat`].
fn unflat<M: Dense>(v: &[Real]) -> M {
    let mut m = M::zeros();
    for (k, &x) in v.iter().enumerate() {
        m.set_at(k, x);
    }
    m
}

fn norm<M: Dense>(m: &M) -> Real {
    m.norm2().sqrt()
}

fn diagonal<D: Dim>(s: &[Real]) -> D::Matrix {
    let mut m = D::Matrix::zeros();
    for (i, &x) in s.iter().enumerate() {
        m.set_at(i + D::D * i, x);
    }
    m
}

/// `check_jacobian` wants the Jacobian row-major; a tangent is stored column-major (entry
/// `(r, c)` at `r + n c`).
fn row_major<D: Dim>(t: &D::Tangent) -> Vec<Real> {
    let n = D::D * D::D;
    (0..n * n).map(|k| t.at(k / n + n * (k % n))).collect()
}

fn label<D: Dim, E: Energy>(e: &E) -> String {
    format!("{} ({})", e.name(), D::NAME)
}

/// [`samples`] in any dimension (for `D2` the very same matrices): `SAMPLES` moderate and large
/// strains with `J > 0.2`, plus `SAMPLES / 4` inverted ones (column 0 negated) when asked.
fn samples_in<D: Battery>(seed: u64, inverted: bool) -> Vec<D::Matrix> {
    let mut rng = Rng::new(seed);
    let mut fs: Vec<D::Matrix> = (0..SAMPLES)
        .map(|k| D::random_f(&mut rng, if k % 2 == 0 { 0.3 } else { 0.8 }, 0.2))
        .collect();
    if inverted {
        for _ in 0..SAMPLES / 4 {
            let mut f = D::random_f(&mut rng, 0.3, 0.2);
            for i in 0..D::D {
                f.set_at(i, -f.at(i));
            }
            fs.push(f);
        }
    }
    fs
}

fn check_piola_is_gradient_of_density<D: Dim, E: Hyperelastic<D> + Energy>(
    e: &E,
    fs: &[D::Matrix],
) {
    for f in fs {
        let r = check_gradient(
            |v| Hyperelastic::<D>::density(e, &unflat(v)),
            &flat(f),
            &flat(&Hyperelastic::<D>::piola(e, f)),
            &FdOptions::default(),
        );
        assert!(
            r.relative_error < FD_TOL,
            "{}: piola differs from d density/dF at F = {f:?}: relative error {:e} (step {:e})",
            label::<D, E>(e),
            r.relative_error,
            r.step
        );
    }
}

fn check_tangent_is_jacobian_of_piola<D: Dim, E: Hyperelastic<D> + Energy>(
    e: &E,
    fs: &[D::Matrix],
) {
    for f in fs {
        let r = check_jacobian(
            |v| flat(&Hyperelastic::<D>::piola(e, &unflat(v))),
            &flat(f),
            &row_major::<D>(&Hyperelastic::<D>::piola_tangent(e, f)),
            &FdOptions::default(),
        );
        assert!(
            r.relative_error < FD_TOL,
            "{}: piola_tangent differs from the FD Jacobian of piola at F = {f:?}: relative error {:e}",
            label::<D, E>(e),
            r.relative_error
        );
    }
}

/// `P` is the gradient of `psi`, so `dP/dF` must be symmetric.
fn check_tangent_is_symmetric<D: Dim, E: Hyperelastic<D> + Energy>(e: &E, fs: &[D::Matrix]) {
    for f in fs {
        let h = Hyperelastic::<D>::piola_tangent(e, f);
        let asym = norm(&(h - D::tangent_transpose(&h)));
        assert!(
            asym <= 1e-10 * norm(&h).max(1.0),
            "{}: piola_tangent is not symmetric at F = {f:?} (|H - H^T| = {asym:e})",
            label::<D, E>(e)
        );
    }
}

fn check_rest_state_in<D: Dim, E: Hyperelastic<D> + Energy>(e: &E) {
    let i = D::identity();
    let psi = Hyperelastic::<D>::density(e, &i);
    assert!(
        psi.abs() < ROUND_OFF * modulus(),
        "{}: psi(I) = {psi}",
        label::<D, E>(e)
    );
    let p = Hyperelastic::<D>::piola(e, &i);
    assert!(
        norm(&p) < ROUND_OFF * modulus(),
        "{}: P(I) = {p:?}",
        label::<D, E>(e)
    );
}

fn check_frame_indifferent_in<D: Battery, E: Hyperelastic<D> + Energy>(e: &E, fs: &[D::Matrix]) {
    let mut rng = Rng::new(4);
    for f in fs {
        let q = D::random_rotation(&mut rng);
        // A proper rotation, or the check proves nothing.
        assert!((D::det(&q) - 1.0).abs() < 1e-14);
        assert!(norm(&(D::transpose(&q) * q - D::identity())) < 1e-14);
        let qf = q * *f;
        let (psi, psi_q) = (
            Hyperelastic::<D>::density(e, f),
            Hyperelastic::<D>::density(e, &qf),
        );
        assert!(
            (psi - psi_q).abs() <= ROUND_OFF * modulus().max(psi.abs()),
            "{}: psi(QF) = {psi_q} but psi(F) = {psi} at F = {f:?}",
            label::<D, E>(e)
        );
        let (p, p_q) = (
            q * Hyperelastic::<D>::piola(e, f),
            Hyperelastic::<D>::piola(e, &qf),
        );
        assert!(
            norm(&(p - p_q)) <= ROUND_OFF * modulus().max(norm(&p)),
            "{}: P(QF) != Q P(F) at F = {f:?}",
            label::<D, E>(e)
        );
    }
}

/// The expected spectrum of linear elasticity's tangent, ascending (see the module docs).
fn linear_elasticity_spectrum<D: Dim>() -> Vec<Real> {
    let (d, l) = (D::D, lame());
    let rotations = d * (d - 1) / 2;
    let deviatoric = d * (d + 1) / 2 - 1;
    let mut s = vec![0.0; rotations];
    s.extend(std::iter::repeat_n(2.0 * l.mu(), deviatoric));
    s.push(d as Real * l.lambda() + 2.0 * l.mu());
    s
}

fn check_linearisation_in<D: Battery, E: Hyperelastic<D> + Energy>(e: &E) {
    let i = D::identity();
    let reference = Hyperelastic::<D>::piola_tangent(&Linear::new(lame()).unwrap(), &i);
    // The reference itself: the textbook spectrum (the FD checks tie it to its density).
    let got = D::spectrum(&reference);
    let want = linear_elasticity_spectrum::<D>();
    for (g, w) in got.iter().zip(&want) {
        assert!(
            (g - w).abs() <= ROUND_OFF * modulus(),
            "linear ({}): spectrum {got:?}, expected {want:?}",
            D::NAME
        );
    }
    let tangent = Hyperelastic::<D>::piola_tangent(e, &i);
    let err = norm(&(tangent - reference)) / norm(&reference);
    assert!(
        err < ROUND_OFF,
        "{}: dP/dF(I) differs from linear elasticity by {err:e} relative:\n{tangent:?}\nvs\n{reference:?}",
        label::<D, E>(e)
    );
}

fn check_projected_tangent_is_psd<D: Battery, E: Hyperelastic<D> + Energy>(
    e: &E,
    fs: &[D::Matrix],
) {
    for f in fs {
        let h = Hyperelastic::<D>::piola_tangent(e, f);
        let p = Hyperelastic::<D>::piola_tangent_projected(e, f);
        let scale = norm(&h).max(1.0);
        assert!(
            norm(&(p - D::tangent_transpose(&p))) <= ROUND_OFF * scale,
            "{}: projected dP/dF is not symmetric at F = {f:?}",
            label::<D, E>(e)
        );
        let min = D::min_eigenvalue(&p);
        assert!(
            min >= -ROUND_OFF * scale,
            "{}: projected dP/dF has eigenvalue {min} at F = {f:?}",
            label::<D, E>(e)
        );
        if D::min_eigenvalue(&h) >= 0.0 {
            assert!(
                norm(&(p - h)) <= 1e-10 * scale,
                "{}: projection changed an already PSD dP/dF at F = {f:?}",
                label::<D, E>(e)
            );
        }
    }
    // At rest the tangent is linear elasticity: PSD, zero exactly on the D(D-1)/2
    // infinitesimal rotations.
    let at_rest = D::spectrum(&Hyperelastic::<D>::piola_tangent_projected(
        e,
        &D::identity(),
    ));
    let positive = at_rest.iter().filter(|&&l| l > 1e-9 * modulus()).count();
    assert_eq!(
        positive,
        D::D * (D::D + 1) / 2,
        "{}: rest tangent eigenvalues {at_rest:?}",
        label::<D, E>(e)
    );
    for (g, w) in at_rest.iter().zip(&linear_elasticity_spectrum::<D>()) {
        assert!(
            (g - w).abs() <= 1e-10 * modulus(),
            "{}: rest tangent eigenvalues {at_rest:?}",
            label::<D, E>(e)
        );
    }
}

/// The closed-form isotropic projection against the general one (see the module docs).
/// Returns how many samples had a negative eigenvalue (below `-1e-12 |dP/dF|`) clamped.
fn check_closed_form_projection_in<D: Battery, E: Hyperelastic<D> + Energy>(
    e: &E,
    fs: &[D::Matrix],
    inverted: bool,
) -> usize {
    let mut rng = Rng::new(11);
    let mut fs = fs.to_vec();
    for k in 0..SAMPLES {
        let s = rng.uniform(0.3, 1.8);
        let other = rng.uniform(0.3, 1.8);
        // Equal singular values, and equal up to a relative 1e-9 (the twist eigenvalue's
        // `(psi_i - psi_j) / (s_i - s_j)` is a 0/0 there); flips `s_i = -s_j` (the flip
        // eigenvalue's `(psi_i + psi_j) / (s_i + s_j)` is a 0/0 there).
        let t = if k % 2 == 0 { 1.0 } else { 1.0 + 1e-9 };
        let mut singular: Vec<Vec<Real>> = Vec::new();
        if D::D == 2 {
            singular.push(vec![s, s * t]);
            if inverted {
                singular.push(vec![s, -s * t]);
            }
        } else {
            singular.push(vec![other, s, s * t]);
            singular.push(vec![s, s * t, s / t]);
            if inverted {
                singular.push(vec![other, s, -s * t]);
                singular.push(vec![s, s * t, -s / t]);
            }
        }
        for sv in singular {
            let (q, w) = (D::random_rotation(&mut rng), D::random_rotation(&mut rng));
            fs.push(q * diagonal::<D>(&sv) * w);
        }
    }
    let mut clamped = 0;
    for f in &fs {
        let (u, sv, v) = D::svd_rotation_variant(f);
        let back = u * diagonal::<D>(&flat(&sv)) * D::transpose(&v);
        assert!(
            norm(&(back - *f)) <= 1e-14 * norm(f),
            "svd of {f:?}: {u:?} {sv:?} {v:?}"
        );
        assert!((D::det(&u) - 1.0).abs() < 1e-14 && (D::det(&v) - 1.0).abs() < 1e-14);
        let h = Hyperelastic::<D>::piola_tangent(e, f);
        if !h.all_finite() {
            continue;
        }
        let general = D::project_psd(&h);
        let closed = Hyperelastic::<D>::piola_tangent_projected(e, f);
        let err = norm(&(closed - general)) / norm(&h).max(Real::MIN_POSITIVE);
        assert!(
            err <= 1e-10,
            "{}: closed-form projection differs from the general one by {err:e} relative at F = {f:?}:\n{closed:?}\nvs\n{general:?}",
            label::<D, E>(e)
        );
        // Clearly negative: the zero eigenvalues of the rotations come out as `+-1e-13` in 3D.
        if D::min_eigenvalue(&h) < -ROUND_OFF * norm(&h) {
            clamped += 1;
        }
    }
    clamped
}

/// `Hyperelastic<D2>` against the 2D kernel [`Energy`]: the same numbers to round-off, and
/// the same `+inf`/NaN where the energy is undefined.
fn check_hyperelastic_d2_matches_energy<E: Energy + Hyperelastic<D2>>(e: &E, fs: &[Mat2]) {
    let m = modulus();
    for f in fs {
        let (psi, psi_h) = (e.psi(f), Hyperelastic::<D2>::density(e, f));
        let (p, p_h) = (e.pk1(f), Hyperelastic::<D2>::piola(e, f));
        let (h, h_h) = (e.dpk1(f), Hyperelastic::<D2>::piola_tangent(e, f));
        if !psi.is_finite() {
            assert!(psi == Real::INFINITY && psi_h == Real::INFINITY);
            assert!(p.iter().chain(p_h.iter()).all(|x| x.is_nan()));
            assert!(h.iter().chain(h_h.iter()).all(|x| x.is_nan()));
            continue;
        }
        let what = |q: &str, err: Real| {
            format!(
                "{}: {q} of Hyperelastic<D2> differs from Energy by {err:e} at F = {f:?}",
                e.name()
            )
        };
        let err = (psi - psi_h).abs();
        assert!(err <= ROUND_OFF * m.max(psi.abs()), "{}", what("psi", err));
        let err = (p - p_h).norm();
        assert!(err <= ROUND_OFF * m.max(p.norm()), "{}", what("P", err));
        let scale = m.max(h.norm());
        let err = (h - h_h).norm();
        assert!(err <= ROUND_OFF * scale, "{}", what("dP/dF", err));
        let err = (e.dpk1_projected(f) - Hyperelastic::<D2>::piola_tangent_projected(e, f)).norm();
        assert!(err <= ROUND_OFF * scale, "{}", what("projected dP/dF", err));
        let sigma = e.cauchy(f);
        let err = (sigma - Hyperelastic::<D2>::cauchy_stress(e, f)).norm();
        assert!(
            err <= ROUND_OFF * m.max(sigma.norm()),
            "{}",
            what("Cauchy stress", err)
        );
    }
}

/// The generic tests of one energy in one dimension (expanded in `<energy>::d2` and
/// `<energy>::d3`).
macro_rules! hyperelastic_battery {
    ($dim:ty, inverted: $inv:expr, frame_indifferent: $fi:expr) => {
        #[test]
        fn piola_is_gradient_of_density() {
            check_piola_is_gradient_of_density::<$dim, _>(&energy(), &samples_in::<$dim>(1, $inv));
        }

        #[test]
        fn piola_tangent_is_jacobian_of_piola() {
            check_tangent_is_jacobian_of_piola::<$dim, _>(&energy(), &samples_in::<$dim>(2, $inv));
        }

        #[test]
        fn piola_tangent_is_symmetric() {
            check_tangent_is_symmetric::<$dim, _>(&energy(), &samples_in::<$dim>(3, $inv));
        }

        #[test]
        fn rest_state_is_stress_free() {
            check_rest_state_in::<$dim, _>(&energy());
        }

        #[test]
        fn frame_indifference() {
            if $fi {
                check_frame_indifferent_in::<$dim, _>(&energy(), &samples_in::<$dim>(4, $inv));
            } else {
                let result = std::panic::catch_unwind(|| {
                    check_frame_indifferent_in::<$dim, _>(&energy(), &samples_in::<$dim>(4, $inv))
                });
                assert!(
                    result.is_err(),
                    "expected this energy to depend on rotation"
                );
            }
        }

        #[test]
        fn linearisation_is_linear_elasticity() {
            check_linearisation_in::<$dim, _>(&energy());
        }

        #[test]
        fn projected_tangent_is_psd() {
            check_projected_tangent_is_psd::<$dim, _>(&energy(), &samples_in::<$dim>(5, $inv));
        }

        #[test]
        fn closed_form_projection_equals_general() {
            let clamped = check_closed_form_projection_in::<$dim, _>(
                &energy(),
                &samples_in::<$dim>(9, $inv),
                $inv,
            );
            // Every energy but the small-strain one (a constant PSD tangent) is indefinite
            // somewhere in the samples, so the clamp is exercised.
            if energy().name() == "linear" {
                assert_eq!(clamped, 0, "the linear tangent is PSD");
            } else {
                assert!(clamped > 0, "no sample needed a clamp");
            }
        }
    };
}

macro_rules! energy_battery {
    ($module:ident, $make:expr, inverted: $inv:expr, frame_indifferent: $fi:expr) => {
        mod $module {
            use super::*;

            fn energy() -> impl Energy + Hyperelastic<D2> + Hyperelastic<D3> {
                $make
            }

            #[test]
            fn pk1_is_gradient_of_psi() {
                check_pk1_matches_fd_gradient_of_psi(&energy(), &samples(1, $inv));
            }

            #[test]
            fn dpk1_is_jacobian_of_pk1() {
                check_dpk1_matches_fd_jacobian_of_pk1(&energy(), &samples(2, $inv));
            }

            #[test]
            fn dpk1_is_symmetric() {
                check_dpk1_is_symmetric(&energy(), &samples(3, $inv));
            }

            #[test]
            fn pk1_lanes_equals_pk1() {
                // Include inverted samples for every energy: NaN must stay NaN.
                check_pk1_lanes_equals_pk1(&energy(), &samples(7, true));
            }

            #[test]
            fn corner_block_contracts_dpk1() {
                check_corner_block(&energy(), &samples(8, $inv));
            }

            #[test]
            fn rest_state_is_stress_free() {
                check_rest_state_is_stress_free(&energy());
            }

            #[test]
            fn frame_indifference() {
                if $fi {
                    check_frame_indifferent(&energy(), &samples(4, $inv));
                } else {
                    let result = std::panic::catch_unwind(|| {
                        check_frame_indifferent(&energy(), &samples(4, $inv))
                    });
                    assert!(
                        result.is_err(),
                        "expected this energy to depend on rotation"
                    );
                }
            }

            #[test]
            fn linearisation_is_linear_elasticity() {
                check_linearisation_is_linear_elasticity(&energy());
            }

            #[test]
            fn closed_form_projection_equals_general() {
                let clamped = check_closed_form_projection(&energy(), &samples(9, $inv), $inv);
                // Every energy but the small-strain one (a constant PSD tangent) is
                // indefinite somewhere in the samples, so the clamp is exercised.
                assert!(
                    clamped > 0 || energy().name() == "linear",
                    "no sample needed a clamp"
                );
            }

            #[test]
            fn projected_dpk1_is_psd() {
                check_projected_dpk1_is_psd(&energy(), &samples(5, $inv));
            }

            /// The generic definitions in 2D, and their agreement with the 2D kernel above.
            mod d2 {
                use super::*;

                hyperelastic_battery!(D2, inverted: $inv, frame_indifferent: $fi);

                #[test]
                fn agrees_with_the_2d_kernel() {
                    // Inverted samples for every energy: neo-hookean's +inf/NaN must agree too.
                    check_hyperelastic_d2_matches_energy(&energy(), &samples(6, true));
                }
            }

            /// The generic definitions in 3D.
            mod d3 {
                use super::*;

                hyperelastic_battery!(D3, inverted: $inv, frame_indifferent: $fi);
            }
        }
    };
}

energy_battery!(stvk, Stvk::new(lame()).unwrap(), inverted: true, frame_indifferent: true);
energy_battery!(corotational, Corotational::new(lame()).unwrap(), inverted: true, frame_indifferent: true);
energy_battery!(neo_hookean, NeoHookean::new(lame()).unwrap(), inverted: false, frame_indifferent: true);
energy_battery!(
    stable_neo_hookean,
    StableNeoHookean::new(lame()).unwrap(),
    inverted: true,
    frame_indifferent: true
);
energy_battery!(linear, Linear::new(lame()).unwrap(), inverted: true, frame_indifferent: false);

/// The run-time dispatch gives the same numbers as the concrete types, bit for bit.
#[test]
fn any_energy_matches_concrete_energies() {
    use fem_core::energy::EnergyKind;
    for kind in EnergyKind::ALL {
        let any = kind.build(lame()).unwrap();
        for f in samples(6, false) {
            let concrete = dispatch_energy!(&any, e => (e.psi(&f), e.pk1(&f), e.dpk1(&f)));
            assert_eq!(concrete.0.to_bits(), any.psi(&f).to_bits());
            assert_eq!(concrete.1, any.pk1(&f));
            assert_eq!(concrete.2, any.dpk1(&f));
            let (psi, p) = any.psi_pk1(&f);
            assert!((psi - concrete.0).abs() <= ROUND_OFF * modulus());
            assert!((p - concrete.1).norm() <= ROUND_OFF * modulus());
        }
    }
}

/// Neo-Hookean is undefined for J <= 0 and says so instead of returning a plausible number.
#[test]
fn neo_hookean_reports_inversion() {
    let e = NeoHookean::new(lame()).unwrap();
    let inverted = Mat2::new(-1.0, 0.0, 0.0, 1.0);
    assert_eq!(e.psi(&inverted), Real::INFINITY);
    assert!(e.pk1(&inverted).iter().all(|v| v.is_nan()));
    assert!(e.dpk1(&inverted).iter().all(|v| v.is_nan()));
}

/// StVK gives a reflection zero energy (it cannot resist inversion); stable Neo-Hookean and
/// co-rotational charge for it.
#[test]
fn inversion_resistance_differs_as_documented() {
    let reflection = Mat2::new(-1.0, 0.0, 0.0, 1.0);
    assert!(Stvk::new(lame()).unwrap().psi(&reflection).abs() < ROUND_OFF);
    assert!(StableNeoHookean::new(lame()).unwrap().psi(&reflection) > 0.1 * lame().mu());
    assert!(Corotational::new(lame()).unwrap().psi(&reflection) > 0.1 * lame().mu());
}

/// Uniaxial stretch of a plane-strain body: all energies agree to first order (the
/// linearisation test) and differ at large strain in the documented direction: StVK stiffens
/// in tension (cubic growth of P).
#[test]
fn large_stretch_orders_stvk_stiffest() {
    let f = Mat2::new(1.5, 0.0, 0.0, 1.0);
    let stvk = Stvk::new(lame()).unwrap().pk1(&f)[(0, 0)];
    let nh = NeoHookean::new(lame()).unwrap().pk1(&f)[(0, 0)];
    let corot = Corotational::new(lame()).unwrap().pk1(&f)[(0, 0)];
    assert!(
        stvk > nh && stvk > corot,
        "stvk {stvk}, nh {nh}, corot {corot}"
    );
}

/// The run-time dispatch of `Hyperelastic<D>` gives the same numbers as the concrete types,
/// bit for bit, in both dimensions.
fn check_any_energy_hyperelastic<D: Battery>() {
    use fem_core::energy::EnergyKind;
    for kind in EnergyKind::ALL {
        let any: AnyEnergy = kind.build(lame()).unwrap();
        for f in samples_in::<D>(6, true) {
            let concrete = dispatch_energy!(&any, e => (
                Hyperelastic::<D>::density(e, &f),
                Hyperelastic::<D>::piola(e, &f),
                Hyperelastic::<D>::piola_tangent(e, &f),
                Hyperelastic::<D>::piola_tangent_projected(e, &f),
                Hyperelastic::<D>::cauchy_stress(e, &f),
            ));
            let bits = |m: Vec<Real>| m.into_iter().map(Real::to_bits).collect::<Vec<_>>();
            assert_eq!(
                concrete.0.to_bits(),
                Hyperelastic::<D>::density(&any, &f).to_bits()
            );
            assert_eq!(
                bits(flat(&concrete.1)),
                bits(flat(&Hyperelastic::<D>::piola(&any, &f)))
            );
            assert_eq!(
                bits(flat(&concrete.2)),
                bits(flat(&Hyperelastic::<D>::piola_tangent(&any, &f)))
            );
            assert_eq!(
                bits(flat(&concrete.3)),
                bits(flat(&Hyperelastic::<D>::piola_tangent_projected(&any, &f)))
            );
            assert_eq!(
                bits(flat(&concrete.4)),
                bits(flat(&Hyperelastic::<D>::cauchy_stress(&any, &f)))
            );
        }
    }
}

/// The generic sampler in 2D visits the very same matrices as the 2D battery.
#[test]
fn generic_samples_in_2d_are_the_2d_samples() {
    assert_eq!(samples_in::<D2>(1, true), samples(1, true));
}

#[test]
fn any_energy_hyperelastic_matches_concrete_energies_d2() {
    check_any_energy_hyperelastic::<D2>();
}

#[test]
fn any_energy_hyperelastic_matches_concrete_energies_d3() {
    check_any_energy_hyperelastic::<D3>();
}

/// The generic Neo-Hookean is undefined for `J <= 0` in both dimensions, as the 2D kernel.
#[test]
fn neo_hookean_reports_inversion_in_both_dimensions() {
    fn check<D: Battery>() {
        let e = NeoHookean::new(lame()).unwrap();
        let mut reflection = D::identity();
        reflection.set_at(0, -1.0);
        assert_eq!(Hyperelastic::<D>::density(&e, &reflection), Real::INFINITY);
        assert!(
            flat(&Hyperelastic::<D>::piola(&e, &reflection))
                .iter()
                .all(|v| v.is_nan())
        );
        assert!(
            flat(&Hyperelastic::<D>::piola_tangent(&e, &reflection))
                .iter()
                .all(|v| v.is_nan())
        );
    }
    check::<D2>();
    check::<D3>();
}

/// Plane strain is the 3D body at `F33 = 1`: the 3D energy at `diag(F, 1)` against the 2D
/// kernel at `F` (see the module docs).
mod plane_strain {
    use super::*;

    fn embed(f: &Mat2) -> Mat3 {
        let mut m = Mat3::identity();
        m.fixed_view_mut::<2, 2>(0, 0).copy_from(f);
        m
    }

    /// `psi`, the in-plane blocks of `P` and `dP/dF`, zero out-of-plane shear and
    /// `sigma_zz`, to `1e-12` relative.
    fn check<E: Energy + Hyperelastic<D3>>(e: &E, fs: &[Mat2]) {
        let m = modulus();
        for f in fs {
            let f3 = embed(f);
            let (psi, psi3) = (e.psi(f), Hyperelastic::<D3>::density(e, &f3));
            assert!(
                (psi - psi3).abs() <= ROUND_OFF * m.max(psi.abs()),
                "{}: psi_3D(diag(F, 1)) = {psi3} but psi_2D(F) = {psi} at F = {f:?}",
                e.name()
            );
            let (p, p3) = (e.pk1(f), Hyperelastic::<D3>::piola(e, &f3));
            let scale = m.max(p.norm());
            let err = (p3.fixed_view::<2, 2>(0, 0) - p).norm();
            assert!(
                err <= ROUND_OFF * scale,
                "{}: in-plane P differs by {err:e} at F = {f:?}:\n{p3}\nvs\n{p}",
                e.name()
            );
            for (i, j) in [(0, 2), (1, 2), (2, 0), (2, 1)] {
                assert!(
                    p3[(i, j)].abs() <= ROUND_OFF * scale,
                    "{}: out-of-plane shear P_{i}{j} = {} at F = {f:?}",
                    e.name(),
                    p3[(i, j)]
                );
            }
            let (zz, zz3) = (
                e.cauchy_zz(f),
                Hyperelastic::<D3>::cauchy_stress(e, &f3)[(2, 2)],
            );
            assert!(
                (zz - zz3).abs() <= ROUND_OFF * m.max(zz.abs()),
                "{}: sigma_zz = {zz3} in 3D but cauchy_zz = {zz} at F = {f:?}",
                e.name()
            );
            let (h, h3) = (e.dpk1(f), Hyperelastic::<D3>::piola_tangent(e, &f3));
            let mut err: Real = 0.0;
            for (r, c) in (0..4).flat_map(|r| (0..4).map(move |c| (r, c))) {
                // vec index i + 2 j in 2D is i + 3 j in 3D.
                let (r3, c3) = (r % 2 + 3 * (r / 2), c % 2 + 3 * (c / 2));
                err = err.max((h3[(r3, c3)] - h[(r, c)]).abs());
            }
            assert!(
                err <= ROUND_OFF * m.max(h.norm()),
                "{}: in-plane dP/dF differs by {err:e} at F = {f:?}",
                e.name()
            );
        }
    }

    /// Random and inverted 2D samples.
    fn all() -> Vec<Mat2> {
        samples(10, true)
    }

    /// Inverted 2D samples whose smaller singular value is below (`below = true`) or above 1.
    fn inverted(below: bool) -> Vec<Mat2> {
        let mut rng = Rng::new(12);
        let fs: Vec<Mat2> = (0..4 * SAMPLES)
            .map(|_| {
                let mut f = rng.deformation_gradient(0.5, 0.2);
                f.set_column(0, &(-f.column(0)));
                f
            })
            .filter(|f| (svd_rotation_variant(f).1[1].abs() < 1.0) == below)
            .take(SAMPLES / 2)
            .collect();
        assert_eq!(fs.len(), SAMPLES / 2);
        fs
    }

    #[test]
    fn stvk() {
        check(&Stvk::new(lame()).unwrap(), &all());
    }

    #[test]
    fn neo_hookean() {
        check(&NeoHookean::new(lame()).unwrap(), &samples(10, false));
    }

    #[test]
    fn linear() {
        check(&Linear::new(lame()).unwrap(), &all());
    }

    /// Non-inverted samples, and inverted ones whose reflection the 3D polar rotation keeps in
    /// the plane: at an inverted `diag(F, 1)` the proper rotation maximising `tr(R^T F)` is
    /// `diag(R_2D, 1)` (trace `s_1 - s_2 + 1`) while `s_2 < 1`, and `diag(R', -1)` with an
    /// improper in-plane `R'` (trace `s_1 + s_2 - 1`) past it.
    #[test]
    fn corotational() {
        let e = Corotational::new(lame()).unwrap();
        check(&e, &samples(10, false));
        check(&e, &inverted(true));
    }

    /// The documented departure: past `s_2 = 1` the 3D rotation flips `z`, so the 3D body has
    /// less energy than the 2D kernel (whose rotation stays in the plane).
    #[test]
    fn corotational_inverted_past_unit_stretch_flips_z() {
        let e = Corotational::new(lame()).unwrap();
        for f in inverted(false) {
            let f3 = embed(&f);
            let r = D3::polar_rotation(&f3);
            assert!((r[(2, 2)] + 1.0).abs() < 1e-12, "R = {r} at F = {f:?}");
            let (psi, psi3) = (e.psi(&f), Hyperelastic::<D3>::density(&e, &f3));
            assert!(
                psi3 < psi - 1e-3 * modulus(),
                "psi_3D = {psi3}, psi_2D = {psi} at F = {f:?}"
            );
        }
    }

    /// Stable Neo-Hookean's constants depend on the dimension: the 2D and 3D bodies agree to
    /// second order at the identity (equal tangents, so an `O(eps^3)` energy difference) and
    /// differ at large strain.
    #[test]
    fn stable_neo_hookean_agrees_to_second_order_only() {
        let e = StableNeoHookean::new(lame()).unwrap();
        let m = modulus();
        // Tangents at I: the in-plane block of the 3D one is the 2D one.
        let (h, h3) = (
            e.dpk1(&Mat2::identity()),
            Hyperelastic::<D3>::piola_tangent(&e, &Mat3::identity()),
        );
        for (r, c) in (0..4).flat_map(|r| (0..4).map(move |c| (r, c))) {
            let (r3, c3) = (r % 2 + 3 * (r / 2), c % 2 + 3 * (c / 2));
            assert!(
                (h3[(r3, c3)] - h[(r, c)]).abs() <= ROUND_OFF * m,
                "tangents at I differ:\n{h3}\nvs\n{h}"
            );
        }
        // The energy difference along a fixed direction shrinks as eps^3.
        let dir = Mat2::new(0.7, -0.4, 0.3, -0.5);
        let diff = |eps: Real| {
            let f = Mat2::identity() + dir * eps;
            Hyperelastic::<D3>::density(&e, &embed(&f)) - e.psi(&f)
        };
        let ratio = diff(1e-2) / diff(1e-3);
        assert!(
            (ratio - 1e3).abs() < 0.1e3,
            "difference {:e} at eps = 1e-2, {:e} at 1e-3: ratio {ratio}",
            diff(1e-2),
            diff(1e-3)
        );
        // At large strain they are different materials.
        for f in [
            Mat2::new(1.5, 0.0, 0.0, 0.8),
            Mat2::new(0.7, 0.4, -0.2, 1.6),
        ] {
            let (psi, psi3) = (e.psi(&f), Hyperelastic::<D3>::density(&e, &embed(&f)));
            assert!(
                (psi - psi3).abs() > 1e-2 * psi.abs(),
                "psi_2D = {psi}, psi_3D = {psi3} at F = {f:?}"
            );
        }
    }
}
