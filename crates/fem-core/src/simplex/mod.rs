//! The linear simplex of any dimension behind one interface: the triangle in 2D and the
//! tetrahedron in 3D ([`Simplex<D>`]), a validated mesh of them ([`SimplexMesh<D>`]) and
//! assembly of energy, forces and the sparse stiffness over it ([`assembly`]).
//!
//! With rest vertices `X0..XD` and current vertices `x0..xD`, `Dm = [X1 - X0, ..., XD - X0]`,
//! `Ds` likewise and `F = Ds Dm^-1`. Writing `g1..gD` for the rows of `Dm^-1` and
//! `g0 = -(g1 + ... + gD)`, the gradients of the barycentric shape functions, an element of rest
//! measure `V` (area in 2D, volume in 3D) has
//! - nodal forces `f_a = -V P g_a`;
//! - stiffness blocks `K_ab[i][k] = V sum_jl g_a[j] dP_ij/dF_kl g_b[l]`.
//!
//! These are the formulas of the 2D triangle [`crate::element::Tri3`], which the 2D solvers
//! keep as their hand-specialised kernel (a test checks the two agree); the 3D solvers use this
//! module.

pub mod assembly;
mod mesh;

pub use mesh::{SimplexMesh, SimplexMeshError};

use crate::dim::{Dense, Dim};
use crate::element::{ElementError, ElementTolerance};
use crate::math::Real;

/// Rest-state data of one linear simplex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Simplex<D: Dim> {
    /// `Dm^-1`.
    pub dm_inv: D::Matrix,
    /// Rest measure (area in 2D, volume in 3D), positive.
    pub measure: Real,
}

/// `D!`: a simplex's measure is `det(Dm) / D!`.
fn factorial(d: usize) -> Real {
    (1..=d).map(|k| k as Real).product()
}

impl<D: Dim> Simplex<D> {
    /// From the `D + 1` rest vertices, positively oriented (counter-clockwise triangles,
    /// tetrahedra with `(X1 - X0) . ((X2 - X0) x (X3 - X0)) > 0`).
    ///
    /// Degenerate when `|measure| <= relative_area * (longest edge)^D` (the same relative
    /// tolerance as the triangle's).
    pub fn new(rest: &[D::Vector], tol: ElementTolerance) -> Result<Self, ElementError> {
        assert_eq!(
            rest.len(),
            D::NODES,
            "a {} has {} vertices",
            D::SIMPLEX,
            D::NODES
        );
        if rest.iter().any(|p| !p.all_finite()) {
            return Err(ElementError::NonFinite);
        }
        let edges: Vec<D::Vector> = rest[1..].iter().map(|p| *p - rest[0]).collect();
        let dm = D::from_columns(&edges);
        let measure = D::det(&dm) / factorial(D::D);
        let mut longest2: Real = 0.0;
        for a in 0..D::NODES {
            for b in a + 1..D::NODES {
                longest2 = longest2.max((rest[b] - rest[a]).norm2());
            }
        }
        let threshold = tol.relative_area * longest2.powf(0.5 * D::D as Real);
        if measure.abs() <= threshold || !measure.is_finite() {
            return Err(ElementError::Degenerate {
                area: measure,
                threshold,
            });
        }
        if measure < 0.0 {
            return Err(ElementError::Inverted { area: measure });
        }
        let dm_inv = D::inverse(&dm).ok_or(ElementError::Degenerate {
            area: measure,
            threshold,
        })?;
        Ok(Simplex { dm_inv, measure })
    }

    /// The deformation gradient for the current vertices `x` (`D + 1` of them).
    #[inline]
    pub fn deformation_gradient(&self, x: &[D::Vector]) -> D::Matrix {
        let mut ds = D::Matrix::zeros();
        for c in 0..D::D {
            let e = x[c + 1] - x[0];
            for r in 0..D::D {
                ds.set_at(r + D::D * c, e.at(r));
            }
        }
        ds * self.dm_inv
    }

    /// The shape-function gradient `g_a` of corner `a`.
    #[inline]
    pub fn gradient(&self, a: usize) -> D::Vector {
        if a == 0 {
            let mut g = D::Vector::zeros();
            for r in 0..D::D {
                g = g - D::row(&self.dm_inv, r);
            }
            g
        } else {
            D::row(&self.dm_inv, a - 1)
        }
    }

    /// The elastic nodal force `f_a = -V P g_a` on corner `a` for the stress `p`.
    #[inline]
    pub fn force(&self, p: &D::Matrix, a: usize) -> D::Vector {
        *p * self.gradient(a) * (-self.measure)
    }

    /// The `D x D` stiffness block `K_ab` for the tangent `dpdf`.
    #[inline]
    pub fn stiffness_block(&self, dpdf: &D::Tangent, a: usize, b: usize) -> D::Matrix {
        D::contract(dpdf, &self.gradient(a), &self.gradient(b)) * self.measure
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dim::{D2, D3, Mat3, Vec3};
    use crate::element::Tri3;
    use crate::math::{Mat2, Vec2};

    fn tet() -> [Vec3; 4] {
        [
            Vec3::new(0.1, 0.2, -0.1),
            Vec3::new(1.3, 0.1, 0.2),
            Vec3::new(0.2, 1.1, 0.1),
            Vec3::new(0.3, 0.4, 0.9),
        ]
    }

    #[test]
    fn affine_map_is_recovered_and_volume_is_right() {
        let rest = tet();
        let s = Simplex::<D3>::new(&rest, ElementTolerance::default()).unwrap();
        let (e1, e2, e3) = (rest[1] - rest[0], rest[2] - rest[0], rest[3] - rest[0]);
        assert!((s.measure - e1.dot(&e2.cross(&e3)) / 6.0).abs() < 1e-15);
        let a = Mat3::new(1.2, 0.3, -0.2, 0.1, 0.8, 0.3, -0.1, 0.2, 1.1);
        let x = rest.map(|p| a * p + Vec3::new(4.0, -1.0, 2.0));
        assert!((s.deformation_gradient(&x) - a).norm() < 1e-14);
        // The shape-function gradients sum to zero and reproduce the identity.
        let sum: Vec3 = (0..4).map(|k| s.gradient(k)).sum();
        assert!(sum.norm() < 1e-14);
        let id: Mat3 = (0..4).map(|k| rest[k] * s.gradient(k).transpose()).sum();
        assert!((id - Mat3::identity()).norm() < 1e-14);
    }

    #[test]
    fn inverted_degenerate_and_non_finite_tetrahedra_are_refused() {
        let mut inv = tet();
        inv.swap(1, 2);
        assert!(matches!(
            Simplex::<D3>::new(&inv, ElementTolerance::default()),
            Err(ElementError::Inverted { .. })
        ));
        let mut flat = tet();
        flat[3] = (flat[1] + flat[2]) * 0.5;
        assert!(matches!(
            Simplex::<D3>::new(&flat, ElementTolerance::default()),
            Err(ElementError::Degenerate { .. })
        ));
        let mut nan = tet();
        nan[2].y = Real::NAN;
        assert_eq!(
            Simplex::<D3>::new(&nan, ElementTolerance::default()),
            Err(ElementError::NonFinite)
        );
    }

    /// In 2D the generic simplex is the triangle: the same `Dm^-1`, area, `F`, forces and
    /// stiffness, to round-off.
    #[test]
    fn the_2d_simplex_is_the_triangle() {
        let rest = [
            Vec2::new(0.3, 0.1),
            Vec2::new(1.7, 0.4),
            Vec2::new(0.9, 1.6),
        ];
        let t = Tri3::new(rest, ElementTolerance::default()).unwrap();
        let s = Simplex::<D2>::new(&rest, ElementTolerance::default()).unwrap();
        assert!((t.dm_inv - s.dm_inv).norm() < 1e-15);
        assert!((t.area - s.measure).abs() < 1e-15);
        let x = [
            Vec2::new(0.2, 0.0),
            Vec2::new(1.9, 0.5),
            Vec2::new(0.7, 1.8),
        ];
        assert!((t.deformation_gradient(x) - s.deformation_gradient(&x)).norm() < 1e-14);
        let p = Mat2::new(3.0, -1.0, 0.5, 2.0);
        let f = t.forces(&p);
        for (a, fa) in f.iter().enumerate() {
            assert!((fa - s.force(&p, a)).norm() < 1e-13);
        }
        let d = crate::math::Mat4::from_fn(|r, c| ((r * 4 + c) as Real).sin());
        let k = t.stiffness(&d);
        for a in 0..3 {
            for b in 0..3 {
                let block = s.stiffness_block(&d, a, b);
                let want = k.fixed_view::<2, 2>(2 * a, 2 * b);
                assert!((block - want).norm() < 1e-13);
            }
        }
    }
}
