//! Saint Venant-Kirchhoff: `psi = mu |E|^2 + lambda/2 tr(E)^2` with Green strain
//! `E = (F^T F - I) / 2` (paper Eq. 2; Kim & Eberle, *Dynamic Deformables*, 2022, sec. 3.3).
//!
//! It is the 3D form at `F33 = 1` (`E33 = 0`), whose out-of-plane stress is
//! `sigma_zz = lambda tr(E) / J` ([`Energy::cauchy_zz`]).
//!
//! `P = F S` with `S = 2 mu E + lambda tr(E) I`. `dP = dF S + F dS`, `dS = 2 mu dE + lambda
//! tr(dE) I`, `dE = sym(F^T dF)`.
//!
//! **Inverted elements (`J <= 0`)**: everything stays finite, but the energy depends on `F` only
//! through `F^T F`, so a reflected element (`F = diag(-1, 1)`) has zero energy: StVK offers no
//! resistance to inversion, and elements pushed through `J = 0` can stay inverted. Its stiffness
//! also softens under strong compression, which is why it needs smaller time steps at high E.

use super::{Energy, EnergyError};
use crate::material::Lame;
use crate::math::{Mat2, Mat4, Real, Vec2, ddot, linear_map_matrix, sym};

/// Saint Venant-Kirchhoff energy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stvk {
    pub(super) mu: Real,
    pub(super) lambda: Real,
}

impl Stvk {
    /// With the given Lamé parameters. Never fails (a validated [`Lame`] is in this energy's
    /// domain); it returns a `Result` because every energy is built the same way, and
    /// [`StableNeoHookean::new`](super::StableNeoHookean::new) can fail.
    pub fn new(lame: Lame) -> Result<Self, EnergyError> {
        Ok(Stvk {
            mu: lame.mu(),
            lambda: lame.lambda(),
        })
    }

    #[inline]
    fn green(f: &Mat2) -> Mat2 {
        (f.transpose() * f - Mat2::identity()) * 0.5
    }

    #[inline]
    fn pk2(&self, e: &Mat2) -> Mat2 {
        e * (2.0 * self.mu) + Mat2::identity() * (self.lambda * e.trace())
    }
}

impl Energy for Stvk {
    fn with_lame(&self, lame: Lame) -> Result<Self, EnergyError> {
        Self::new(lame)
    }

    fn name(&self) -> &'static str {
        "stvk"
    }

    #[inline]
    fn psi(&self, f: &Mat2) -> Real {
        let e = Self::green(f);
        let tr = e.trace();
        self.mu * ddot(&e, &e) + 0.5 * self.lambda * tr * tr
    }

    #[inline]
    fn pk1(&self, f: &Mat2) -> Mat2 {
        f * self.pk2(&Self::green(f))
    }

    #[inline]
    fn psi_pk1(&self, f: &Mat2) -> (Real, Mat2) {
        let e = Self::green(f);
        let tr = e.trace();
        let psi = self.mu * ddot(&e, &e) + 0.5 * self.lambda * tr * tr;
        (psi, f * self.pk2(&e))
    }

    /// `sigma_zz = lambda tr(E) / J` (the 3D form with `F33 = 1`: `E33 = 0`, `S33 = lambda
    /// tr(E)`, `P33 = S33`).
    #[inline]
    /// `lambda/2 (J - 1)^2`: `lambda/2 tr(E)^2` to second order in the strain.
    fn volumetric(&self) -> super::Volumetric {
        super::Volumetric::quadratic(self.lambda, 1.0, super::VolumeMeasure::Determinant)
    }

    fn cauchy_zz(&self, f: &Mat2) -> Real {
        self.lambda * Self::green(f).trace() / f.determinant()
    }

    /// Closed form: for `dF = u g^T`, `dE = (g b^T + b g^T) / 2` with `b = F^T u`, so with
    /// `c = F g`, `B = (g . S g) I + (mu + lambda) c c^T + mu |g|^2 F F^T`.
    #[inline]
    fn pk1_corner_block(&self, f: &Mat2, g: &Vec2) -> (Mat2, Mat2) {
        let s = self.pk2(&Self::green(f));
        let c = f * g;
        let b = Mat2::identity() * g.dot(&(s * g))
            + c * c.transpose() * (self.mu + self.lambda)
            + f * f.transpose() * (self.mu * g.norm_squared());
        (f * s, b)
    }

    fn dpk1(&self, f: &Mat2) -> Mat4 {
        let s = self.pk2(&Self::green(f));
        linear_map_matrix(|df| {
            let de = sym(&(f.transpose() * df));
            df * s + f * self.pk2(&de)
        })
    }

    /// Closed form ([`super::project_psd_isotropic`]): the energy is isotropic.
    fn dpk1_projected(&self, f: &Mat2) -> Mat4 {
        super::project_psd_isotropic(f, &self.dpk1(f))
    }
}
