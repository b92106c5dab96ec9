//! Stable Neo-Hookean (Smith, de Goes & Kim, "Stable Neo-Hookean Flesh Simulation", ACM TOG
//! 2018), in 2D: `psi = mu'/2 (I_C - 2) + lambda'/2 (J - alpha)^2 - mu'/2 log(I_C + 1)` with
//! `I_C = tr(F^T F)`, minus its value at `F = I` (`lambda'/2 (1 - alpha)^2 - mu'/2 log 3`) so
//! that the rest state has zero energy like every other energy here (a constant changes no
//! force).
//!
//! It is the 3D energy `mu'/2 (I_C3 - 3) + lambda'/2 (J - alpha)^2 - mu'/2 log(I_C3)` at
//! `F33 = 1` (`I_C3 = I_C + 1`; the paper's 3D form has `log(I_C3 + 1)` and so a different 2D
//! restriction), which gives the out-of-plane stress of plane strain
//! ([`Energy::cauchy_zz`]); it linearises to `lambda tr(eps)`, as it must.
//!
//! The 3D paper's constants are re-derived for 2D. Stress-free rest (`P(I) = 0`) needs
//! `alpha = 1 + 2 mu' / (3 lambda')`. Matching the linearisation at `F = I` to linear elasticity
//! with the material's `(mu, lambda)` needs `mu' = 3/2 mu` and `lambda' = lambda + 2/3 mu`
//! (the 3D paper's `4/3 mu` and `lambda + 5/6 mu` come from the same two conditions with
//! `I_C = 3`). The battery in `tests/energy_battery.rs` checks both conditions.
//!
//! `P = mu' (1 - 1/(I_C + 1)) F + lambda' (J - alpha) cof(F)`, with `cof(F) = dJ/dF`;
//! `dP = mu' (1 - 1/(I_C+1)) dF + 2 mu' (F : dF)/(I_C+1)^2 F + lambda' (cof F : dF) cof F
//! + lambda' (J - alpha) cof(dF)`.
//!
//! **Inverted elements (`J <= 0`)**: finite and smooth everywhere, with no log of `J`; the
//! volume term keeps pushing the element back towards `J = alpha`. This is the inversion-safe
//! choice.

use super::{Energy, EnergyError};
use crate::material::Lame;
use crate::math::{Mat2, Mat4, Real, cofactor, ln, outer};

/// Stable Neo-Hookean energy (2D constants).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StableNeoHookean {
    mu: Real,
    lambda: Real,
    alpha: Real,
    /// `psi` of the formula at `F = I`, subtracted so the rest state has zero energy.
    rest_offset: Real,
    /// The material's own Lamé parameters `(mu, lambda)`, from which each dimension derives
    /// its constants ([`super::Hyperelastic`]).
    pub(crate) lame: (Real, Real),
}

impl StableNeoHookean {
    /// With the material's Lamé parameters, re-parameterised as in the module docs. Fails when
    /// `lambda + 2/3 mu <= 0` (possible only for plane stress with `nu <= -1/2`).
    pub fn new(lame: Lame) -> Result<Self, EnergyError> {
        let mu = 1.5 * lame.mu();
        let lambda = lame.lambda() + 2.0 / 3.0 * lame.mu();
        if !(lambda > 0.0 && mu > 0.0) {
            return Err(EnergyError::Parameters {
                energy: "stable-neo-hookean",
                message: format!(
                    "needs lambda + 2/3 mu > 0, got lambda = {}, mu = {}",
                    lame.lambda(),
                    lame.mu()
                ),
            });
        }
        let alpha = 1.0 + 2.0 * mu / (3.0 * lambda);
        let rest_offset = 0.5 * lambda * (1.0 - alpha).powi(2) - 0.5 * mu * ln(3.0);
        Ok(StableNeoHookean {
            mu,
            lambda,
            alpha,
            rest_offset,
            lame: (lame.mu(), lame.lambda()),
        })
    }
}

impl Energy for StableNeoHookean {
    fn with_lame(&self, lame: Lame) -> Result<Self, EnergyError> {
        Self::new(lame)
    }

    fn name(&self) -> &'static str {
        "stable-neo-hookean"
    }

    #[inline]
    fn psi(&self, f: &Mat2) -> Real {
        let ic = f.norm_squared();
        let d = f.determinant() - self.alpha;
        0.5 * self.mu * (ic - 2.0) + 0.5 * self.lambda * d * d
            - 0.5 * self.mu * ln(ic + 1.0)
            - self.rest_offset
    }

    #[inline]
    fn pk1(&self, f: &Mat2) -> Mat2 {
        let ic = f.norm_squared();
        let d = f.determinant() - self.alpha;
        f * (self.mu * (1.0 - 1.0 / (ic + 1.0))) + cofactor(f) * (self.lambda * d)
    }

    /// `sigma_zz = (mu' (1 - 1/(I_C + 1)) + lambda' (J - alpha) J) / J`: `P33` of the 3D form
    /// of the module docs at `F33 = 1`.
    #[inline]
    /// `lambda'/2 (J - alpha)^2`, the energy's own volumetric term.
    fn volumetric(&self) -> super::Volumetric {
        super::Volumetric::quadratic(self.lambda, self.alpha, super::VolumeMeasure::Determinant)
    }

    fn cauchy_zz(&self, f: &Mat2) -> Real {
        let ic = f.norm_squared();
        let j = f.determinant();
        (self.mu * (1.0 - 1.0 / (ic + 1.0)) + self.lambda * (j - self.alpha) * j) / j
    }

    fn dpk1(&self, f: &Mat2) -> Mat4 {
        let ic = f.norm_squared();
        let d = f.determinant() - self.alpha;
        let cof = cofactor(f);
        // cof(dF) is linear in dF: vec(cof(dF)) = C vec(dF) with C mapping
        // [a, b, c, d] (column-major a=00, b=10, c=01, d=11) to [d, -c, -b, a].
        let cof_map = Mat4::new(
            0.0, 0.0, 0.0, 1.0, //
            0.0, 0.0, -1.0, 0.0, //
            0.0, -1.0, 0.0, 0.0, //
            1.0, 0.0, 0.0, 0.0,
        );
        let ic1 = ic + 1.0;
        Mat4::identity() * (self.mu * (1.0 - 1.0 / ic1))
            + outer(f, f) * (2.0 * self.mu / (ic1 * ic1))
            + outer(&cof, &cof) * self.lambda
            + cof_map * (self.lambda * d)
    }

    /// Closed form ([`super::project_psd_isotropic`]): the energy is isotropic.
    fn dpk1_projected(&self, f: &Mat2) -> Mat4 {
        super::project_psd_isotropic(f, &self.dpk1(f))
    }
}
