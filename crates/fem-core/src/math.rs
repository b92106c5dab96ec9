//! Type aliases and small dense helpers shared by every module.
//!
//! Notation: `F` is the deformation gradient, `P` the first Piola-Kirchhoff stress, `J = det F`.
//! Fourth-order tensors such as dP/dF are stored as 4x4 matrices acting on `vec(F)`, the
//! **column-major** flattening `[F00, F10, F01, F11]`; this is nalgebra's own storage order, so
//! `vec(F)` is `F.as_slice()`. Entry `(r, c)` of `dP/dF` is `dP_r / dF_c` in that numbering.

use nalgebra::{Matrix2, Matrix4, Matrix6, Vector2, Vector4};

/// Scalar type of every kernel.
pub type Real = f64;
/// A point or a vector in the plane.
pub type Vec2 = Vector2<Real>;
/// A 2x2 matrix (deformation gradient, stress).
pub type Mat2 = Matrix2<Real>;
/// A 4x4 matrix acting on `vec(F)` (see the module docs for the flattening).
pub type Mat4 = Matrix4<Real>;
/// A 4-vector, `vec` of a 2x2 matrix.
pub type Vec4 = Vector4<Real>;
/// The 6x6 stiffness block of one triangle (3 vertices x 2 components).
pub type Mat6 = Matrix6<Real>;

/// `vec(A)`: the column-major flattening `[A00, A10, A01, A11]`.
#[inline]
pub fn vec(a: &Mat2) -> Vec4 {
    Vec4::new(a[(0, 0)], a[(1, 0)], a[(0, 1)], a[(1, 1)])
}

/// Inverse of [`vec`].
#[inline]
pub fn unvec(v: &Vec4) -> Mat2 {
    Mat2::new(v[0], v[2], v[1], v[3])
}

/// Index of entry `(i, j)` of a 2x2 matrix in `vec` order.
#[inline]
pub const fn vec_index(i: usize, j: usize) -> usize {
    i + 2 * j
}

/// The cofactor matrix `cof(F) = J F^-T = dJ/dF` (defined for every `F`, singular or not).
#[inline]
pub fn cofactor(f: &Mat2) -> Mat2 {
    Mat2::new(f[(1, 1)], -f[(1, 0)], -f[(0, 1)], f[(0, 0)])
}

/// Rotation matrix by angle `theta` (counter-clockwise).
#[inline]
pub fn rotation(theta: Real) -> Mat2 {
    let (s, c) = theta.sin_cos();
    Mat2::new(c, -s, s, c)
}

/// Symmetric part `(A + A^T) / 2`.
#[inline]
pub fn sym(a: &Mat2) -> Mat2 {
    (a + a.transpose()) * 0.5
}

/// Frobenius inner product `A : B = tr(A^T B)`.
#[inline]
pub fn ddot(a: &Mat2, b: &Mat2) -> Real {
    a.component_mul(b).sum()
}

/// Rank-one fourth-order tensor `vec(A) vec(B)^T`.
#[inline]
pub fn outer(a: &Mat2, b: &Mat2) -> Mat4 {
    vec(a) * vec(b).transpose()
}

/// The 4x4 matrix of the linear map `dF -> L(dF)`, built column by column from its action on
/// the four unit matrices. Used to turn a directional derivative into dP/dF without index
/// bookkeeping; the compiler unrolls it.
#[inline]
pub fn linear_map_matrix(map: impl Fn(&Mat2) -> Mat2) -> Mat4 {
    let mut m = Mat4::zeros();
    for c in 0..4 {
        let mut e = Vec4::zeros();
        e[c] = 1.0;
        let col = vec(&map(&unvec(&e)));
        m.set_column(c, &col);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vec_matches_nalgebra_storage_and_unvec_inverts_it() {
        let a = Mat2::new(1.0, 2.0, 3.0, 4.0);
        assert_eq!(vec(&a).as_slice(), a.as_slice());
        assert_eq!(unvec(&vec(&a)), a);
        assert_eq!(vec(&a)[vec_index(0, 1)], a[(0, 1)]);
    }

    #[test]
    fn cofactor_is_det_times_inverse_transpose() {
        let f = Mat2::new(1.3, 0.2, -0.4, 0.9);
        let expected = f.try_inverse().unwrap().transpose() * f.determinant();
        assert!((cofactor(&f) - expected).norm() < 1e-14);
    }
}
