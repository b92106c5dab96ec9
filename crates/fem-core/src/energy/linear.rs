//! Linear (small-strain) elasticity: `psi = mu |eps|^2 + lambda/2 tr(eps)^2` with
//! `eps = sym(F) - I`; `P = 2 mu eps + lambda tr(eps) I`; `dP/dF` is constant.
//!
//! Its stress is the small-strain stress `P` itself ([`Energy::cauchy`]), with `sigma_zz =
//! lambda tr(eps)` in plane strain.
//!
//! It is the reference every other energy must reduce to at `F = I` (the battery checks it),
//! and the cheapest. It is **not rotation invariant**: a rigid rotation of the element
//! produces stress, growing with the angle, so it is wrong for large rotations (a cantilever
//! under gravity with E = 1000 Pa). **Inverted elements (`J <= 0`)**: finite, no special
//! treatment; the energy does not know about orientation.

use super::{Energy, EnergyError};
use crate::material::Lame;
use crate::math::{Mat2, Mat4, Real, Vec2, linear_map_matrix, sym};

/// Linear elasticity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Linear {
    pub(super) mu: Real,
    pub(super) lambda: Real,
    tangent: Mat4,
}

impl Linear {
    /// With the given Lamé parameters. Never fails (a validated [`Lame`] is in this energy's
    /// domain); it returns a `Result` because every energy is built the same way, and
    /// [`StableNeoHookean::new`](super::StableNeoHookean::new) can fail.
    pub fn new(lame: Lame) -> Result<Self, EnergyError> {
        let (mu, lambda) = (lame.mu(), lame.lambda());
        let tangent =
            linear_map_matrix(|df| sym(df) * (2.0 * mu) + Mat2::identity() * (lambda * df.trace()));
        Ok(Linear {
            mu,
            lambda,
            tangent,
        })
    }
}

impl Energy for Linear {
    fn with_lame(&self, lame: Lame) -> Result<Self, EnergyError> {
        Self::new(lame)
    }

    fn name(&self) -> &'static str {
        "linear"
    }

    #[inline]
    fn psi(&self, f: &Mat2) -> Real {
        let eps = sym(f) - Mat2::identity();
        let tr = eps.trace();
        self.mu * eps.norm_squared() + 0.5 * self.lambda * tr * tr
    }

    #[inline]
    fn pk1(&self, f: &Mat2) -> Mat2 {
        let eps = sym(f) - Mat2::identity();
        eps * (2.0 * self.mu) + Mat2::identity() * (self.lambda * eps.trace())
    }

    /// Closed form (constant in `F`): `B = mu |g|^2 I + (mu + lambda) g g^T`.
    #[inline]
    fn pk1_corner_block(&self, f: &Mat2, g: &Vec2) -> (Mat2, Mat2) {
        let b = Mat2::identity() * (self.mu * g.norm_squared())
            + g * g.transpose() * (self.mu + self.lambda);
        (self.pk1(f), b)
    }

    /// The small-strain `sigma_zz = lambda tr(eps)` (`eps_zz = 0`): no push-forward.
    #[inline]
    /// `lambda/2 tr(eps)^2` with `theta = 1 + tr(eps)`, the energy's own volumetric term.
    fn volumetric(&self) -> super::Volumetric {
        super::Volumetric::quadratic(self.lambda, 1.0, super::VolumeMeasure::Trace)
    }

    fn cauchy_zz(&self, f: &Mat2) -> Real {
        self.lambda * (sym(f) - Mat2::identity()).trace()
    }

    /// The small-strain stress is `P` itself (symmetric); `P F^T / J` would mix in the
    /// rotation and the volume change that small-strain elasticity leaves out.
    #[inline]
    fn cauchy(&self, f: &Mat2) -> Mat2 {
        self.pk1(f)
    }

    fn dpk1(&self, _f: &Mat2) -> Mat4 {
        self.tangent
    }

    fn dpk1_projected(&self, _f: &Mat2) -> Mat4 {
        // The tangent is constant and PSD for mu > 0, lambda + mu > 0.
        self.tangent
    }
}
