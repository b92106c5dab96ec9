//! Compressible Neo-Hookean, the standard form
//! `psi = mu/2 (tr(F^T F) - 2) - mu log J + lambda/2 (log J)^2` (Bonet & Wood, *Nonlinear
//! Continuum Mechanics for FEA*, 2nd ed., Eq. 6.28, in 2D).
//!
//! **Departure from the paper**: Eq. 2 of the paper prints `-mu log det(F^T F) + lambda/2
//! log^2 det(F^T F)` with `tr(F^T F) - 3`; that expression is not stress-free at `F = I` in 2D
//! (and doubles the log terms). We implement the standard form above, which is stress-free at
//! rest and linearises to linear elasticity with the same Lamé parameters.
//!
//! It is the 3D form `mu/2 (tr(F^T F) - 3) - mu log J + lambda/2 (log J)^2` at `F33 = 1`, whose
//! out-of-plane stress is `sigma_zz = lambda log J / J` ([`Energy::cauchy_zz`]).
//!
//! `P = mu (F - F^-T) + lambda log J F^-T`;
//! `dP = mu dF + (mu - lambda log J) F^-T dF^T F^-T + lambda (F^-T : dF) F^-T`.
//!
//! **Inverted elements (`J <= 0`)**: the energy is undefined there. `psi` returns `+inf`, and `P`
//! and `dP/dF` are NaN, so a solver's finiteness check stops the run at the first inverted
//! element (and a line search rejects the step). Use `stable-neo-hookean` when elements may
//! invert.

use super::{Energy, EnergyError};
use crate::material::Lame;
use crate::math::{Mat2, Mat2Lanes, Mat4, Real, Vec2, cofactor, linear_map_matrix, ln, outer};

/// Compressible Neo-Hookean energy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeoHookean {
    pub(super) mu: Real,
    pub(super) lambda: Real,
}

impl NeoHookean {
    /// With the given Lamé parameters. Never fails (a validated [`Lame`] is in this energy's
    /// domain); it returns a `Result` because every energy is built the same way, and
    /// [`StableNeoHookean::new`](super::StableNeoHookean::new) can fail.
    pub fn new(lame: Lame) -> Result<Self, EnergyError> {
        Ok(NeoHookean {
            mu: lame.mu(),
            lambda: lame.lambda(),
        })
    }
}

impl Energy for NeoHookean {
    fn with_lame(&self, lame: Lame) -> Result<Self, EnergyError> {
        Self::new(lame)
    }

    fn name(&self) -> &'static str {
        "neo-hookean"
    }

    #[inline]
    fn psi(&self, f: &Mat2) -> Real {
        let j = f.determinant();
        if j <= 0.0 {
            return Real::INFINITY;
        }
        let lj = ln(j);
        0.5 * self.mu * (f.norm_squared() - 2.0) - self.mu * lj + 0.5 * self.lambda * lj * lj
    }

    #[inline]
    fn pk1(&self, f: &Mat2) -> Mat2 {
        let j = f.determinant();
        if j <= 0.0 {
            return Mat2::from_element(Real::NAN);
        }
        f * self.mu + cofactor(f) * ((self.lambda * ln(j) - self.mu) / j)
    }

    /// Lane-wise [`Energy::pk1`]: the same operations in the same order per lane, with
    /// `J <= 0` selected to NaN instead of branched on.
    #[inline(always)]
    fn pk1_lanes(&self, f: &Mat2Lanes) -> Mat2Lanes {
        let j = f.determinant();
        // (lambda log J - mu) / J, NaN where J <= 0 so the whole P is NaN there.
        let c = j.select_positive((j.ln() * self.lambda - self.mu) / j, Real::NAN);
        let (f00, f10, f01, f11) = (f.m00(), f.m10(), f.m01(), f.m11());
        // mu F + cof(F) c with cof(F) = [[F11, -F10], [-F01, F00]].
        Mat2Lanes([
            f00 * self.mu + f11 * c,
            f10 * self.mu + (-f01) * c,
            f01 * self.mu + (-f10) * c,
            f11 * self.mu + f00 * c,
        ])
    }

    #[inline]
    fn psi_pk1(&self, f: &Mat2) -> (Real, Mat2) {
        let j = f.determinant();
        if j <= 0.0 {
            return (Real::INFINITY, Mat2::from_element(Real::NAN));
        }
        let lj = ln(j);
        let psi =
            0.5 * self.mu * (f.norm_squared() - 2.0) - self.mu * lj + 0.5 * self.lambda * lj * lj;
        // P = mu F + (lambda log J - mu) F^-T, with F^-T = cof(F) / J: one division.
        let p = f * self.mu + cofactor(f) * ((self.lambda * lj - self.mu) / j);
        (psi, p)
    }

    /// Closed form: with `a = F^-T g`, `dP g = mu |g|^2 u + (mu + lambda (1 - log J)) a (a . u)`
    /// for `dF = u g^T` (the three terms of `dP` in the module docs), so
    /// `B = mu |g|^2 I + (mu + lambda (1 - log J)) a a^T`. NaN for `J <= 0`.
    #[inline]
    fn pk1_corner_block(&self, f: &Mat2, g: &Vec2) -> (Mat2, Mat2) {
        let j = f.determinant();
        if j <= 0.0 {
            return (Mat2::from_element(Real::NAN), Mat2::from_element(Real::NAN));
        }
        let lj = ln(j);
        let cof = cofactor(f);
        let p = f * self.mu + cof * ((self.lambda * lj - self.mu) / j);
        let a = cof * g / j;
        let c = self.mu + self.lambda * (1.0 - lj);
        let d = self.mu * g.norm_squared();
        let off = c * a.x * a.y;
        (p, Mat2::new(d + c * a.x * a.x, off, off, d + c * a.y * a.y))
    }

    /// `sigma_zz = lambda log J / J` (the 3D form with `F33 = 1`: `P33 = lambda log J`);
    /// not finite for `J <= 0`.
    #[inline]
    /// `lambda/2 (log J)^2`, the energy's own volumetric term.
    fn volumetric(&self) -> super::Volumetric {
        super::Volumetric::LogSquared {
            lambda: self.lambda,
        }
    }

    fn cauchy_zz(&self, f: &Mat2) -> Real {
        let j = f.determinant();
        if j <= 0.0 {
            return Real::NAN;
        }
        self.lambda * ln(j) / j
    }

    fn dpk1(&self, f: &Mat2) -> Mat4 {
        let j = f.determinant();
        if j <= 0.0 {
            return Mat4::from_element(Real::NAN);
        }
        let lj = ln(j);
        let f_inv_t = cofactor(f) / j;
        let c = self.mu - self.lambda * lj;
        Mat4::identity() * self.mu
            + linear_map_matrix(|df| f_inv_t * df.transpose() * f_inv_t) * c
            + outer(&f_inv_t, &f_inv_t) * self.lambda
    }

    /// Closed form ([`super::project_psd_isotropic`]): the energy is isotropic.
    fn dpk1_projected(&self, f: &Mat2) -> Mat4 {
        super::project_psd_isotropic(f, &self.dpk1(f))
    }
}
