//! The linear triangle (Tri3): rest-state kinematics and the chain rule from `F` to nodes.
//!
//! With rest vertices `X0, X1, X2` and current vertices `x0, x1, x2`, `Dm = [X1 - X0, X2 - X0]`,
//! `Ds = [x1 - x0, x2 - x0]` and `F = Ds Dm^-1` (constant over the element). Writing
//! `g1, g2` for the rows of `Dm^-1` and `g0 = -(g1 + g2)`, `dF_ij / dx_{a,i} = g_a[j]`: the
//! gradients of the barycentric shape functions. Hence, for an element of rest area `a`:
//! - nodal force (paper Eq. 3): `f_a = -a P g_a`, i.e. `[f1 f2] = -a P Dm^-T`, `f0 = -f1 - f2`;
//! - stiffness block: `K_ab[i][k] = a sum_jl g_a[j] dP_ij/dF_kl g_b[l]`.

use crate::math::{Mat2, Mat4, Mat6, Real, Vec2, vec_index};

/// Why a rest triangle cannot be used.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ElementError {
    /// Zero (or numerically zero) area.
    #[error("degenerate rest triangle (area {area:e}, below {threshold:e})")]
    Degenerate {
        /// Signed rest area.
        area: Real,
        /// The smallest area accepted for its edge lengths.
        threshold: Real,
    },
    /// Clockwise vertex order.
    #[error("inverted rest triangle (clockwise, signed area {area:e})")]
    Inverted {
        /// Signed rest area (negative).
        area: Real,
    },
    /// A coordinate is NaN or infinite.
    #[error("non-finite rest vertex coordinate")]
    NonFinite,
}

/// Tolerances for accepting a rest triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementTolerance {
    /// A triangle is degenerate when `|area| <= relative_area * (longest edge)^2`.
    /// Default `1e-10`: an equilateral triangle has ratio 0.43, and a sliver with a 1e-10
    /// ratio has a condition number that makes `Dm^-1` meaningless in f64.
    pub relative_area: Real,
}

impl Default for ElementTolerance {
    fn default() -> Self {
        ElementTolerance {
            relative_area: 1e-10,
        }
    }
}

/// Rest-state data of one linear triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tri3 {
    /// `Dm^-1`.
    pub dm_inv: Mat2,
    /// Rest area (positive), m^2.
    pub area: Real,
}

impl Tri3 {
    /// From the three rest vertices, counter-clockwise.
    pub fn new(rest: [Vec2; 3], tol: ElementTolerance) -> Result<Self, ElementError> {
        if rest.iter().any(|p| !p.x.is_finite() || !p.y.is_finite()) {
            return Err(ElementError::NonFinite);
        }
        let e1 = rest[1] - rest[0];
        let e2 = rest[2] - rest[0];
        let e3 = rest[2] - rest[1];
        let dm = Mat2::from_columns(&[e1, e2]);
        let area = 0.5 * dm.determinant();
        let longest2 = e1
            .norm_squared()
            .max(e2.norm_squared())
            .max(e3.norm_squared());
        let threshold = tol.relative_area * longest2;
        if area.abs() <= threshold || !area.is_finite() {
            return Err(ElementError::Degenerate { area, threshold });
        }
        if area < 0.0 {
            return Err(ElementError::Inverted { area });
        }
        // Non-degenerate by the check above, so the inverse exists.
        let dm_inv = dm
            .try_inverse()
            .ok_or(ElementError::Degenerate { area, threshold })?;
        Ok(Tri3 { dm_inv, area })
    }

    /// The deformation gradient for current vertices `x`.
    #[inline]
    pub fn deformation_gradient(&self, x: [Vec2; 3]) -> Mat2 {
        Mat2::from_columns(&[x[1] - x[0], x[2] - x[0]]) * self.dm_inv
    }

    /// Shape-function gradients `[g0, g1, g2]` (see the module docs).
    #[inline]
    pub fn gradients(&self) -> [Vec2; 3] {
        let g1 = self.dm_inv.row(0).transpose();
        let g2 = self.dm_inv.row(1).transpose();
        [-(g1 + g2), g1, g2]
    }

    /// Elastic nodal forces `f_a = -a P g_a` for a first Piola-Kirchhoff stress `p`.
    #[inline]
    pub fn forces(&self, p: &Mat2) -> [Vec2; 3] {
        let h = p * self.dm_inv.transpose() * (-self.area);
        let f1 = h.column(0).into_owned();
        let f2 = h.column(1).into_owned();
        [-(f1 + f2), f1, f2]
    }

    /// The 6x6 stiffness `K = d^2 (a psi) / dx^2` for `dP/dF` = `dpdf`; rows and columns are
    /// ordered `[x0, y0, x1, y1, x2, y2]`.
    pub fn stiffness(&self, dpdf: &Mat4) -> Mat6 {
        let g = self.gradients();
        let mut k = Mat6::zeros();
        for a in 0..3 {
            for b in 0..3 {
                for i in 0..2 {
                    for kk in 0..2 {
                        let mut s = 0.0;
                        for j in 0..2 {
                            for l in 0..2 {
                                s += g[a][j] * dpdf[(vec_index(i, j), vec_index(kk, l))] * g[b][l];
                            }
                        }
                        k[(2 * a + i, 2 * b + kk)] = self.area * s;
                    }
                }
            }
        }
        k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> [Vec2; 3] {
        [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
        ]
    }

    #[test]
    fn rest_configuration_has_identity_gradient() {
        let t = Tri3::new(unit(), ElementTolerance::default()).unwrap();
        assert_eq!(t.area, 0.5);
        assert_eq!(t.deformation_gradient(unit()), Mat2::identity());
    }

    #[test]
    fn affine_map_is_recovered_exactly() {
        let rest = [
            Vec2::new(0.3, 0.1),
            Vec2::new(1.7, 0.4),
            Vec2::new(0.9, 1.6),
        ];
        let a = Mat2::new(1.2, 0.3, -0.2, 0.8);
        let t = Tri3::new(rest, ElementTolerance::default()).unwrap();
        let x = rest.map(|p| a * p + Vec2::new(4.0, -1.0));
        assert!((t.deformation_gradient(x) - a).norm() < 1e-14);
    }

    #[test]
    fn clockwise_and_degenerate_triangles_are_rejected() {
        let mut cw = unit();
        cw.swap(1, 2);
        assert!(matches!(
            Tri3::new(cw, ElementTolerance::default()),
            Err(ElementError::Inverted { .. })
        ));
        let flat = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(2.0, 0.0),
        ];
        assert!(matches!(
            Tri3::new(flat, ElementTolerance::default()),
            Err(ElementError::Degenerate { .. })
        ));
        let nan = [
            Vec2::new(Real::NAN, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
        ];
        assert_eq!(
            Tri3::new(nan, ElementTolerance::default()),
            Err(ElementError::NonFinite)
        );
    }
}
