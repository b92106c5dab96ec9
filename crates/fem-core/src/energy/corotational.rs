//! Co-rotational: `psi = mu |F - R|^2 + lambda/2 tr(R^T F - I)^2` with `R` the rotation of the
//! polar decomposition `F = R S` (paper Eq. 2; Kim & Eberle, *Dynamic Deformables*, sec. 3.4).
//!
//! It is the 3D form at `F33 = 1` (rotation `diag(R, 1)`), whose out-of-plane stress is
//! `sigma_zz = lambda tr(R^T F - I) / J` ([`Energy::cauchy_zz`]).
//!
//! `R` comes from the closed-form 2D polar decomposition in [`crate::polar`], always a proper
//! rotation. Because `R` maximises `tr(R^T F)`, the terms with `dR` vanish from `P`:
//! `P = 2 mu (F - R) + lambda (tr(R^T F) - 2) R`. In `dP/dF` they do not:
//! `dP = 2 mu (dF - dR) + lambda tr(R^T dF) R + lambda (tr(R^T F) - 2) dR`, with
//! `dR = R' dtheta` ([`crate::polar::Polar2::dtheta`]).
//!
//! **Inverted elements (`J <= 0`)**: finite. With a proper rotation, `S = R^T F` has a negative
//! eigenvalue and the `|F - R|^2` term grows as the element inverts further, so the energy
//! resists inversion (weakly: it stays bounded at `J = 0`). At a scaled reflection
//! `F = [[a, b], [b, -a]]` the rotation is not unique and the identity is used.

use super::{Energy, EnergyError};
use crate::material::Lame;
use crate::math::{Mat2, Mat4, Real, Vec2, linear_map_matrix};
use crate::polar::Polar2;

/// Co-rotational linear elasticity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corotational {
    pub(super) mu: Real,
    pub(super) lambda: Real,
}

impl Corotational {
    /// With the given Lamé parameters. Never fails (a validated [`Lame`] is in this energy's
    /// domain); it returns a `Result` because every energy is built the same way, and
    /// [`StableNeoHookean::new`](super::StableNeoHookean::new) can fail.
    pub fn new(lame: Lame) -> Result<Self, EnergyError> {
        Ok(Corotational {
            mu: lame.mu(),
            lambda: lame.lambda(),
        })
    }
}

impl Energy for Corotational {
    fn with_lame(&self, lame: Lame) -> Result<Self, EnergyError> {
        Self::new(lame)
    }

    fn name(&self) -> &'static str {
        "corotational"
    }

    #[inline]
    fn psi(&self, f: &Mat2) -> Real {
        self.psi_pk1(f).0
    }

    #[inline]
    fn pk1(&self, f: &Mat2) -> Mat2 {
        let r = Polar2::new(f).rotation();
        // tr(R^T F) - 2 = c (F00 + F11) + s (F10 - F01) - 2, written out to skip the product.
        let t = r[(0, 0)] * (f[(0, 0)] + f[(1, 1)]) + r[(1, 0)] * (f[(1, 0)] - f[(0, 1)]) - 2.0;
        (f - r) * (2.0 * self.mu) + r * (self.lambda * t)
    }

    #[inline]
    fn psi_pk1(&self, f: &Mat2) -> (Real, Mat2) {
        let r = Polar2::new(f).rotation();
        let d = f - r;
        let t = (r.transpose() * f).trace() - 2.0;
        let psi = self.mu * d.norm_squared() + 0.5 * self.lambda * t * t;
        (psi, d * (2.0 * self.mu) + r * (self.lambda * t))
    }

    /// `sigma_zz = lambda tr(R^T F - I) / J` (the 3D form with `F33 = 1` and the rotation
    /// `diag(R, 1)`: `P33 = 2 mu (1 - 1) + lambda tr(R^T F - I)`).
    #[inline]
    /// `lambda/2 (J - 1)^2`: `lambda/2 tr(S - I)^2` to second order in the strain.
    fn volumetric(&self) -> super::Volumetric {
        super::Volumetric::quadratic(self.lambda, 1.0, super::VolumeMeasure::Determinant)
    }

    fn cauchy_zz(&self, f: &Mat2) -> Real {
        let r = Polar2::new(f).rotation();
        let t = r[(0, 0)] * (f[(0, 0)] + f[(1, 1)]) + r[(1, 0)] * (f[(1, 0)] - f[(0, 1)]) - 2.0;
        self.lambda * t / f.determinant()
    }

    /// Closed form: for `dF = u g^T`, `tr(R^T dF) = r . u` with `r = R g`, and
    /// `dR g = R' g dtheta = (J r) (J r . u) / |(A, B)|` with `J r = (-r_y, r_x)` (see
    /// [`Polar2::dtheta`]), so `B = 2 mu |g|^2 I + lambda r r^T + (lambda t - 2 mu) / |(A, B)|
    /// (J r)(J r)^T`, `t = tr(R^T F) - 2`. One polar decomposition serves `P` and `B`.
    #[inline]
    fn pk1_corner_block(&self, f: &Mat2, g: &Vec2) -> (Mat2, Mat2) {
        let polar = Polar2::new(f);
        let r = polar.rotation();
        let t = r[(0, 0)] * (f[(0, 0)] + f[(1, 1)]) + r[(1, 0)] * (f[(1, 0)] - f[(0, 1)]) - 2.0;
        let p = (f - r) * (2.0 * self.mu) + r * (self.lambda * t);
        let rg = r * g;
        let jr = Vec2::new(-rg.y, rg.x);
        let k = (self.lambda * t - 2.0 * self.mu) * polar.inv_norm;
        let b = Mat2::identity() * (2.0 * self.mu * g.norm_squared())
            + rg * rg.transpose() * self.lambda
            + jr * jr.transpose() * k;
        (p, b)
    }

    fn dpk1(&self, f: &Mat2) -> Mat4 {
        let polar = Polar2::new(f);
        let r = polar.rotation();
        let rp = polar.drotation();
        let t = (r.transpose() * f).trace() - 2.0;
        linear_map_matrix(|df| {
            let dr = rp * polar.dtheta(df);
            (df - dr) * (2.0 * self.mu)
                + r * (self.lambda * (r.transpose() * df).trace())
                + dr * (self.lambda * t)
        })
    }

    /// Closed form ([`super::project_psd_isotropic`]): the energy is isotropic.
    fn dpk1_projected(&self, f: &Mat2) -> Mat4 {
        super::project_psd_isotropic(f, &self.dpk1(f))
    }
}
