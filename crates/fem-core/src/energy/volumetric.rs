//! The volumetric part `U(theta)` of an energy ([`Energy::volumetric`](super::Energy::volumetric)):
//! the term the first Lamé parameter scales, as a function of one scalar volume measure
//! `theta(F)`. It is what locks a linear triangle as `nu -> 1/2` (one volume constraint per
//! element), and what the averaged nodal pressure triangle ([`crate::nodal_pressure`]) moves to
//! the mesh's nodes.

use crate::math::{Lanes, Mat2, Mat4, Real, cofactor, ln, vec_index};

/// How an energy measures an element's change of volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VolumeMeasure {
    /// `theta = J = det F`; `dtheta/dF = cof F`, and `d^2 theta/dF^2` is the constant
    /// `dcof(F)/dF`.
    Determinant,
    /// `theta = 1 + tr(eps) = tr F - 1` (small strain); `dtheta/dF = I`, no curvature.
    Trace,
}

/// An energy's volumetric part `U(theta)`, J/m^2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Volumetric {
    /// `U = lambda/2 (theta - alpha)^2`.
    Quadratic {
        /// Its stiffness `U''`, Pa.
        lambda: Real,
        /// Its minimum (1, or the stable Neo-Hookean's `alpha`).
        alpha: Real,
        /// What `theta` is.
        measure: VolumeMeasure,
    },
    /// `U = lambda/2 (ln J)^2` (Neo-Hookean); `+inf` for `J <= 0`.
    LogSquared {
        /// `U''(1)`, Pa.
        lambda: Real,
    },
}

impl Volumetric {
    /// `lambda/2 (theta - alpha)^2` over `measure`.
    pub fn quadratic(lambda: Real, alpha: Real, measure: VolumeMeasure) -> Self {
        Volumetric::Quadratic {
            lambda,
            alpha,
            measure,
        }
    }

    /// What `theta` is.
    #[inline]
    pub fn measure(&self) -> VolumeMeasure {
        match self {
            Volumetric::Quadratic { measure, .. } => *measure,
            Volumetric::LogSquared { .. } => VolumeMeasure::Determinant,
        }
    }

    /// `U''` at rest, Pa: the stiffness the volume constraint carries.
    pub fn stiffness(&self) -> Real {
        match self {
            Volumetric::Quadratic { lambda, .. } | Volumetric::LogSquared { lambda } => *lambda,
        }
    }

    /// `U(theta)`.
    #[inline]
    pub fn u(&self, theta: Real) -> Real {
        match *self {
            Volumetric::Quadratic { lambda, alpha, .. } => {
                let d = theta - alpha;
                0.5 * lambda * d * d
            }
            Volumetric::LogSquared { lambda } => {
                if theta <= 0.0 {
                    return Real::INFINITY;
                }
                let l = ln(theta);
                0.5 * lambda * l * l
            }
        }
    }

    /// `U'(theta)`, the pressure-like derivative, Pa.
    #[inline]
    pub fn du(&self, theta: Real) -> Real {
        match *self {
            Volumetric::Quadratic { lambda, alpha, .. } => lambda * (theta - alpha),
            Volumetric::LogSquared { lambda } => {
                if theta <= 0.0 {
                    return Real::NAN;
                }
                lambda * ln(theta) / theta
            }
        }
    }

    /// [`Volumetric::du`] of a batch: lane `i` is bit-identical to `du(theta[i])`.
    #[inline(always)]
    pub fn du_lanes(&self, theta: Lanes) -> Lanes {
        match *self {
            Volumetric::Quadratic { lambda, alpha, .. } => (theta - alpha) * lambda,
            Volumetric::LogSquared { lambda } => {
                theta.select_positive(theta.ln() * lambda / theta, Real::NAN)
            }
        }
    }

    /// `U''(theta)`, Pa.
    #[inline]
    pub fn d2u(&self, theta: Real) -> Real {
        match *self {
            Volumetric::Quadratic { lambda, .. } => lambda,
            Volumetric::LogSquared { lambda } => {
                if theta <= 0.0 {
                    return Real::NAN;
                }
                lambda * (1.0 - ln(theta)) / (theta * theta)
            }
        }
    }

    /// `theta(F)`.
    #[inline]
    pub fn theta(&self, f: &Mat2) -> Real {
        match self.measure() {
            VolumeMeasure::Determinant => f.determinant(),
            VolumeMeasure::Trace => f[(0, 0)] + f[(1, 1)] - 1.0,
        }
    }

    /// `dtheta/dF`.
    #[inline]
    pub fn dtheta(&self, f: &Mat2) -> Mat2 {
        match self.measure() {
            VolumeMeasure::Determinant => cofactor(f),
            VolumeMeasure::Trace => Mat2::identity(),
        }
    }

    /// `d^2 theta/dF^2` on `vec(F)` (constant: `theta` is at most bilinear in `F`).
    pub fn d2theta(&self) -> Mat4 {
        let mut m = Mat4::zeros();
        if self.measure() == VolumeMeasure::Determinant {
            // J = F00 F11 - F01 F10.
            let (a, d) = (vec_index(0, 0), vec_index(1, 1));
            let (b, c) = (vec_index(0, 1), vec_index(1, 0));
            m[(a, d)] = 1.0;
            m[(d, a)] = 1.0;
            m[(b, c)] = -1.0;
            m[(c, b)] = -1.0;
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::{Energy, EnergyKind};
    use crate::material::{Material, PlaneModel};

    /// `U` of every energy: stress-free at rest when alone with the rest of `psi`, its
    /// derivatives against central differences, and `U''(1) = lambda` of the material (the
    /// small-strain volumetric stiffness the formulation moves to the nodes).
    #[test]
    fn volumetric_parts_match_their_derivatives_and_the_lame_lambda() {
        let material = Material::new(1.0e4, 0.45, 1.0).unwrap();
        let lame = material.lame(PlaneModel::PlaneStrain);
        for kind in EnergyKind::ALL {
            let e = kind.build(lame).unwrap();
            let v = e.volumetric();
            for theta in [0.7, 1.0, 1.3] {
                let h = 1e-6;
                let du = (v.u(theta + h) - v.u(theta - h)) / (2.0 * h);
                let d2u = (v.du(theta + h) - v.du(theta - h)) / (2.0 * h);
                assert!(
                    (du - v.du(theta)).abs() <= 1e-6 * (1.0 + v.du(theta).abs()),
                    "{kind:?}"
                );
                assert!(
                    (d2u - v.d2u(theta)).abs() <= 1e-5 * v.d2u(theta).abs(),
                    "{kind:?}"
                );
            }
            // The energy's own lambda term at rest: lambda for every energy but stable
            // Neo-Hookean (its lambda' = lambda + 2/3 mu).
            let expect = match kind {
                EnergyKind::StableNeoHookean => lame.lambda() + 2.0 / 3.0 * lame.mu(),
                _ => lame.lambda(),
            };
            assert!((v.d2u(1.0) - expect).abs() <= 1e-12 * expect, "{kind:?}");
            let f = Mat2::new(1.1, 0.2, -0.1, 0.95);
            let h = 1e-7;
            for k in 0..4 {
                let mut fp = f;
                let mut fm = f;
                fp[(k % 2, k / 2)] += h;
                fm[(k % 2, k / 2)] -= h;
                let fd = (v.theta(&fp) - v.theta(&fm)) / (2.0 * h);
                assert!((fd - v.dtheta(&f)[(k % 2, k / 2)]).abs() < 1e-8, "{kind:?}");
                let dfd = (v.dtheta(&fp) - v.dtheta(&fm)) / (2.0 * h);
                for l in 0..4 {
                    let exact = v.d2theta()[(vec_index(l % 2, l / 2), vec_index(k % 2, k / 2))];
                    assert!((dfd[(l % 2, l / 2)] - exact).abs() < 1e-7, "{kind:?}");
                }
            }
        }
    }
}
