//! The derivative battery, applied to every energy by one macro.
//!
//! For each energy, at a set of random deformation gradients:
//! - `P` equals the central-difference gradient of `psi`;
//! - `dP/dF` equals the central-difference Jacobian of `P`;
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
//! Tolerances. The FD oracle sweeps steps `1e-2..1e-8` and keeps the best: for these smooth
//! functions of O(1) arguments with O(1e3) values the best central difference is accurate to
//! about 1e-10 relative, so the threshold `FD_TOL = 1e-7` leaves three decades of margin while a
//! wrong term (a missing factor, a transposed index) gives errors of order 1e-2 to 1. Identities
//! that involve only round-off (rest stress, frame indifference) use `1e-12` relative to the
//! modulus.

mod common;

use common::Rng;
use fem_core::energy::{
    Corotational, Energy, Linear, NeoHookean, StableNeoHookean, Stvk, contract_corner, project_psd,
    svd_rotation_variant,
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

macro_rules! energy_battery {
    ($module:ident, $make:expr, inverted: $inv:expr, frame_indifferent: $fi:expr) => {
        mod $module {
            use super::*;

            fn energy() -> impl Energy {
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
