//! Every energy written **once over `F`**, for any dimension ([`Dim`]): the definitions.
//!
//! [`Hyperelastic<D>`] gives `psi`, `P = dpsi/dF`, `dP/dF` and its PSD projection for a
//! `D x D` deformation gradient. The formulas below are the module docs of each energy with
//! `2` replaced by `D`; where the mathematics differs between dimensions they call the
//! dimension's kernels (the cofactor and its derivative, the polar rotation and its derivative,
//! the analytic eigenbasis of the projection).
//!
//! In 2D the [`Energy`](super::Energy) trait is the hand-specialised kernel of the same
//! definitions (closed forms, batched lanes, corner blocks) that every 2D solver runs; a test
//! (`tests/energy_battery.rs`) checks that `Hyperelastic<D2>` and `Energy` agree to round-off
//! for every energy. 3D solvers run `Hyperelastic<D3>`.
//!
//! The constants are the same in both dimensions (the material's Lamé parameters, whose
//! `lambda` is the 3D one: plane strain is the 3D body at `F33 = 1`), with one exception:
//! Stable Neo-Hookean's re-parameterisation depends on `D`. Stress-free rest and the
//! linearisation to linear elasticity need `mu' = mu (D + 1) / D`,
//! `lambda' = lambda + mu - 2 mu / (D (D + 1))` and `alpha = 1 + mu' D / ((D + 1) lambda')`:
//! `3/2 mu`, `lambda + 2/3 mu` in 2D, and the paper's `4/3 mu`, `lambda + 5/6 mu` in 3D. So
//! the 2D and 3D Stable Neo-Hookean bodies agree at small strain but are not the same material
//! at large strain (the other four energies are; co-rotational only while an inverted
//! element's smaller in-plane stretch is below 1: past it the 3D polar rotation of
//! `diag(F, 1)` flips the out-of-plane axis, where the 2D one stays in the plane).

use super::{Corotational, Linear, NeoHookean, StableNeoHookean, Stvk};
use crate::dim::{Dense, Dim};
use crate::math::{Real, ln};

/// A hyperelastic energy density for a `D`-dimensional body.
pub trait Hyperelastic<D: Dim>: Send + Sync + Clone + std::fmt::Debug {
    /// `psi(F)`, J/m^D (per unit thickness in 2D). `+inf` where the energy is undefined.
    fn density(&self, f: &D::Matrix) -> Real;

    /// The first Piola-Kirchhoff stress `P = dpsi/dF`, Pa.
    fn piola(&self, f: &D::Matrix) -> D::Matrix;

    /// `dP/dF` on `vec(F)` (column-major, see [`crate::math`]).
    fn piola_tangent(&self, f: &D::Matrix) -> D::Tangent;

    /// `dP/dF` projected onto the positive semi-definite cone. The default is the closed form
    /// of an isotropic energy ([`Dim::project_psd_isotropic`]).
    fn piola_tangent_projected(&self, f: &D::Matrix) -> D::Tangent {
        D::project_psd_isotropic(f, &self.piola_tangent(f))
    }

    /// The Cauchy stress `P F^T / J`, Pa (the small-strain energy overrides it with `P`).
    fn cauchy_stress(&self, f: &D::Matrix) -> D::Matrix {
        self.piola(f) * D::transpose(f) / D::det(f)
    }
}

#[inline]
fn dim_real<D: Dim>() -> Real {
    D::D as Real
}

#[inline]
fn sym<D: Dim>(m: &D::Matrix) -> D::Matrix {
    (*m + D::transpose(m)) * 0.5
}

/// `psi = mu/2 (|F|^2 - D) - mu log J + lambda/2 (log J)^2`.
impl<D: Dim> Hyperelastic<D> for NeoHookean {
    fn density(&self, f: &D::Matrix) -> Real {
        let j = D::det(f);
        if j <= 0.0 {
            return Real::INFINITY;
        }
        let lj = ln(j);
        0.5 * self.mu * (f.norm2() - dim_real::<D>()) - self.mu * lj + 0.5 * self.lambda * lj * lj
    }

    /// `P = mu F + (lambda log J - mu) / J cof(F)`.
    fn piola(&self, f: &D::Matrix) -> D::Matrix {
        let j = D::det(f);
        if j <= 0.0 {
            return nan_matrix::<D>();
        }
        *f * self.mu + D::cofactor(f) * ((self.lambda * ln(j) - self.mu) / j)
    }

    /// With `c(J) = (lambda log J - mu) / J`:
    /// `dP = mu dF + c'(J) (cof F : dF) cof F + c(J) dcof(F)[dF]`,
    /// `c'(J) = (lambda (1 - log J) + mu) / J^2`.
    fn piola_tangent(&self, f: &D::Matrix) -> D::Tangent {
        let j = D::det(f);
        if j <= 0.0 {
            return nan_tangent::<D>();
        }
        let lj = ln(j);
        let cof = D::cofactor(f);
        let c = (self.lambda * lj - self.mu) / j;
        let dc = (self.lambda * (1.0 - lj) + self.mu) / (j * j);
        D::tangent_identity() * self.mu
            + D::tangent_outer(&cof, &cof) * dc
            + D::linear_map(|df| D::dcofactor(f, df)) * c
    }
}

/// `psi = mu |E|^2 + lambda/2 tr(E)^2`, `E = (F^T F - I) / 2`.
impl<D: Dim> Hyperelastic<D> for Stvk {
    fn density(&self, f: &D::Matrix) -> Real {
        let e = (D::transpose(f) * *f - D::identity()) * 0.5;
        let t = D::trace(&e);
        self.mu * e.norm2() + 0.5 * self.lambda * t * t
    }

    /// `P = F S`, `S = 2 mu E + lambda tr(E) I`.
    fn piola(&self, f: &D::Matrix) -> D::Matrix {
        let e = (D::transpose(f) * *f - D::identity()) * 0.5;
        *f * (e * (2.0 * self.mu) + D::identity() * (self.lambda * D::trace(&e)))
    }

    /// `dP = dF S + F (2 mu dE + lambda tr(dE) I)`, `dE = sym(F^T dF)`.
    fn piola_tangent(&self, f: &D::Matrix) -> D::Tangent {
        let e = (D::transpose(f) * *f - D::identity()) * 0.5;
        let s = e * (2.0 * self.mu) + D::identity() * (self.lambda * D::trace(&e));
        D::linear_map(|df| {
            let de = sym::<D>(&(D::transpose(f) * *df));
            *df * s + *f * (de * (2.0 * self.mu) + D::identity() * (self.lambda * D::trace(&de)))
        })
    }
}

/// `psi = mu |F - R|^2 + lambda/2 tr(R^T F - I)^2`, `R` the polar rotation.
impl<D: Dim> Hyperelastic<D> for Corotational {
    fn density(&self, f: &D::Matrix) -> Real {
        let r = D::polar_rotation(f);
        let t = D::trace(&(D::transpose(&r) * *f)) - dim_real::<D>();
        self.mu * (*f - r).norm2() + 0.5 * self.lambda * t * t
    }

    /// `P = 2 mu (F - R) + lambda tr(R^T F - I) R` (the `dR` terms vanish: `R` maximises
    /// `tr(R^T F)`).
    fn piola(&self, f: &D::Matrix) -> D::Matrix {
        let r = D::polar_rotation(f);
        let t = D::trace(&(D::transpose(&r) * *f)) - dim_real::<D>();
        (*f - r) * (2.0 * self.mu) + r * (self.lambda * t)
    }

    /// `dP = 2 mu (dF - dR) + lambda tr(R^T dF) R + lambda tr(R^T F - I) dR`.
    fn piola_tangent(&self, f: &D::Matrix) -> D::Tangent {
        let r = D::polar_rotation(f);
        let rt = D::transpose(&r);
        let t = D::trace(&(rt * *f)) - dim_real::<D>();
        // dR/dF once (one SVD in 3D), then applied to each direction.
        let dr_df = D::drotation_tangent(f);
        D::linear_map(|df| {
            let dr = D::apply(&dr_df, df);
            (*df - dr) * (2.0 * self.mu)
                + r * (self.lambda * D::trace(&(rt * *df)))
                + dr * (self.lambda * t)
        })
    }
}

/// The dimension's constants `(mu', lambda', alpha, rest offset)` of Stable Neo-Hookean (see
/// the module docs).
fn stable_constants<D: Dim>(mu: Real, lambda: Real) -> (Real, Real, Real, Real) {
    let d = dim_real::<D>();
    let a = mu * (d + 1.0) / d;
    let b = lambda + mu - 2.0 * mu / (d * (d + 1.0));
    let alpha = 1.0 + a * d / ((d + 1.0) * b);
    let rest = 0.5 * b * (1.0 - alpha) * (1.0 - alpha) - 0.5 * a * ln(d + 1.0);
    (a, b, alpha, rest)
}

/// `psi = mu'/2 (I_C - D) + lambda'/2 (J - alpha)^2 - mu'/2 log(I_C + 1)` minus its rest value.
impl<D: Dim> Hyperelastic<D> for StableNeoHookean {
    fn density(&self, f: &D::Matrix) -> Real {
        let (a, b, alpha, rest) = stable_constants::<D>(self.lame.0, self.lame.1);
        let ic = f.norm2();
        let j = D::det(f);
        0.5 * a * (ic - dim_real::<D>()) + 0.5 * b * (j - alpha) * (j - alpha)
            - 0.5 * a * ln(ic + 1.0)
            - rest
    }

    /// `P = mu' (1 - 1/(I_C + 1)) F + lambda' (J - alpha) cof(F)`.
    fn piola(&self, f: &D::Matrix) -> D::Matrix {
        let (a, b, alpha, _) = stable_constants::<D>(self.lame.0, self.lame.1);
        let ic = f.norm2();
        *f * (a * (1.0 - 1.0 / (ic + 1.0))) + D::cofactor(f) * (b * (D::det(f) - alpha))
    }

    /// `dP = mu' (1 - 1/(I_C+1)) dF + 2 mu' (F : dF) / (I_C+1)^2 F`
    /// `+ lambda' (cof F : dF) cof F + lambda' (J - alpha) dcof(F)[dF]`.
    fn piola_tangent(&self, f: &D::Matrix) -> D::Tangent {
        let (a, b, alpha, _) = stable_constants::<D>(self.lame.0, self.lame.1);
        let ic = f.norm2();
        let cof = D::cofactor(f);
        let j = D::det(f);
        D::tangent_identity() * (a * (1.0 - 1.0 / (ic + 1.0)))
            + D::tangent_outer(f, f) * (2.0 * a / ((ic + 1.0) * (ic + 1.0)))
            + D::tangent_outer(&cof, &cof) * b
            + D::linear_map(|df| D::dcofactor(f, df)) * (b * (j - alpha))
    }
}

/// `psi = mu |eps|^2 + lambda/2 tr(eps)^2`, `eps = sym(F) - I`.
impl<D: Dim> Hyperelastic<D> for Linear {
    fn density(&self, f: &D::Matrix) -> Real {
        let eps = sym::<D>(f) - D::identity();
        let t = D::trace(&eps);
        self.mu * eps.norm2() + 0.5 * self.lambda * t * t
    }

    /// `P = 2 mu eps + lambda tr(eps) I`.
    fn piola(&self, f: &D::Matrix) -> D::Matrix {
        let eps = sym::<D>(f) - D::identity();
        eps * (2.0 * self.mu) + D::identity() * (self.lambda * D::trace(&eps))
    }

    /// Constant: `dP = 2 mu sym(dF) + lambda tr(dF) I`.
    fn piola_tangent(&self, _f: &D::Matrix) -> D::Tangent {
        D::linear_map(|df| {
            sym::<D>(df) * (2.0 * self.mu) + D::identity() * (self.lambda * D::trace(df))
        })
    }

    /// The constant tangent is already positive semi-definite (`mu > 0`, `lambda + 2 mu / D > 0`).
    fn piola_tangent_projected(&self, f: &D::Matrix) -> D::Tangent {
        Hyperelastic::<D>::piola_tangent(self, f)
    }

    /// The small-strain stress is `P` itself.
    fn cauchy_stress(&self, f: &D::Matrix) -> D::Matrix {
        Hyperelastic::<D>::piola(self, f)
    }
}

/// Run-time dispatch, one `match` per call.
impl<D: Dim> Hyperelastic<D> for super::AnyEnergy {
    fn density(&self, f: &D::Matrix) -> Real {
        crate::dispatch_energy!(self, e => Hyperelastic::<D>::density(e, f))
    }
    fn piola(&self, f: &D::Matrix) -> D::Matrix {
        crate::dispatch_energy!(self, e => Hyperelastic::<D>::piola(e, f))
    }
    fn piola_tangent(&self, f: &D::Matrix) -> D::Tangent {
        crate::dispatch_energy!(self, e => Hyperelastic::<D>::piola_tangent(e, f))
    }
    fn piola_tangent_projected(&self, f: &D::Matrix) -> D::Tangent {
        crate::dispatch_energy!(self, e => Hyperelastic::<D>::piola_tangent_projected(e, f))
    }
    fn cauchy_stress(&self, f: &D::Matrix) -> D::Matrix {
        crate::dispatch_energy!(self, e => Hyperelastic::<D>::cauchy_stress(e, f))
    }
}

fn nan_matrix<D: Dim>() -> D::Matrix {
    let mut m = D::Matrix::zeros();
    (0..<D::Matrix as Dense>::LEN).for_each(|k| m.set_at(k, Real::NAN));
    m
}

fn nan_tangent<D: Dim>() -> D::Tangent {
    let mut m = D::Tangent::zeros();
    (0..<D::Tangent as Dense>::LEN).for_each(|k| m.set_at(k, Real::NAN));
    m
}
