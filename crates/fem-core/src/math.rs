//! Type aliases and small dense helpers shared by every module.
//!
//! Notation: `F` is the deformation gradient, `P` the first Piola-Kirchhoff stress, `J = det F`.
//! Fourth-order tensors such as dP/dF are stored as 4x4 matrices acting on `vec(F)`, the
//! **column-major** flattening `[F00, F10, F01, F11]`; this is nalgebra's own storage order, so
//! `vec(F)` is `F.as_slice()`. Entry `(r, c)` of `dP/dF` is `dP_r / dF_c` in that numbering.
//!
//! Batched kernels evaluate [`LANES`] elements at once in structure-of-arrays form: [`Lanes`]
//! holds one real per element and [`Mat2Lanes`] one 2x2 matrix per element (component-wise, in
//! `vec` order). Their arithmetic is lane by lane, with the same operations in the same order as
//! the scalar code it mirrors, so lane `i` of a batched result is bit-identical to the scalar
//! result for element `i`; written this way the compiler vectorises it for the default target.

use std::ops::{Add, Div, Mul, Neg, Sub};

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

/// Inverse of [`vec()`].
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

/// Number of elements a batched kernel evaluates together (see [`Lanes`]).
pub const LANES: usize = 4;

/// One real per element of a batch of [`LANES`] elements. Arithmetic is lane by lane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Lanes(pub [Real; LANES]);

impl Lanes {
    /// Every lane set to `v`.
    #[inline(always)]
    pub fn splat(v: Real) -> Self {
        Lanes([v; LANES])
    }

    /// Apply `op` to every lane.
    #[inline(always)]
    pub fn map(self, op: impl Fn(Real) -> Real) -> Self {
        // A counted loop rather than `array::map`: it inlines and vectorises reliably.
        let mut out = self.0;
        for v in &mut out {
            *v = op(*v);
        }
        Lanes(out)
    }

    /// Combine two batches lane by lane with `op`.
    #[inline(always)]
    pub fn zip_with(self, other: Self, op: impl Fn(Real, Real) -> Real) -> Self {
        let mut out = self.0;
        for (v, &b) in out.iter_mut().zip(&other.0) {
            *v = op(*v, b);
        }
        Lanes(out)
    }

    /// Lane-wise `if self[i] > 0 { self_if[i] } else { otherwise }`, written as a select so it
    /// stays branch-free.
    #[inline(always)]
    pub fn select_positive(self, if_positive: Self, otherwise: Real) -> Self {
        self.zip_with(if_positive, |c, v| if c > 0.0 { v } else { otherwise })
    }

    /// Lane-wise natural logarithm (`f64::ln`, the C library's `log`, per lane).
    ///
    /// A branch-free polynomial logarithm that the compiler vectorises was tried here and
    /// measured slower: on the default x86-64 target (SSE2, no fused multiply-add) it needs
    /// about 40 instructions per lane, while the C library's table-driven `log` selects an FMA
    /// version at run time and costs about 15. Calling the library per lane also keeps every
    /// lane bit-identical to the scalar `ln` on any given machine.
    #[inline(always)]
    pub fn ln(self) -> Self {
        self.map(Real::ln)
    }

    /// Lane-wise `sqrt`.
    #[inline(always)]
    pub fn sqrt(self) -> Self {
        self.map(Real::sqrt)
    }
}

macro_rules! lanes_binary_op {
    ($trait:ident, $method:ident, $op:tt) => {
        impl $trait for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, rhs: Lanes) -> Lanes {
                self.zip_with(rhs, |a, b| a $op b)
            }
        }
        impl $trait<Real> for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, rhs: Real) -> Lanes {
                self.map(|a| a $op rhs)
            }
        }
    };
}

lanes_binary_op!(Add, add, +);
lanes_binary_op!(Sub, sub, -);
lanes_binary_op!(Mul, mul, *);
lanes_binary_op!(Div, div, /);

impl Neg for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn neg(self) -> Lanes {
        self.map(|a| -a)
    }
}

/// A batch of [`LANES`] 2x2 matrices in structure-of-arrays form: component `k` (in `vec`
/// order `[A00, A10, A01, A11]`) of every matrix.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Mat2Lanes(pub [Lanes; 4]);

impl Mat2Lanes {
    /// Pack `LANES` matrices.
    #[inline(always)]
    pub fn from_mats(m: &[Mat2; LANES]) -> Self {
        let mut out = Mat2Lanes::default();
        for (i, mi) in m.iter().enumerate() {
            out.set_lane(i, mi);
        }
        out
    }

    /// Overwrite matrix `i` of the batch.
    #[inline(always)]
    pub fn set_lane(&mut self, i: usize, m: &Mat2) {
        for (c, &v) in self.0.iter_mut().zip(m.as_slice()) {
            c.0[i] = v;
        }
    }

    /// Matrix `i` of the batch.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Mat2 {
        let c = &self.0;
        Mat2::new(c[0].0[i], c[2].0[i], c[1].0[i], c[3].0[i])
    }

    /// Component `(0, 0)` of every matrix.
    #[inline(always)]
    pub fn m00(&self) -> Lanes {
        self.0[0]
    }

    /// Component `(1, 0)` of every matrix.
    #[inline(always)]
    pub fn m10(&self) -> Lanes {
        self.0[1]
    }

    /// Component `(0, 1)` of every matrix.
    #[inline(always)]
    pub fn m01(&self) -> Lanes {
        self.0[2]
    }

    /// Component `(1, 1)` of every matrix.
    #[inline(always)]
    pub fn m11(&self) -> Lanes {
        self.0[3]
    }

    /// `det A = A00 A11 - A10 A01` per lane (the same operations as nalgebra's 2x2
    /// `determinant`, so each lane equals it bit for bit).
    #[inline(always)]
    pub fn determinant(&self) -> Lanes {
        self.m00() * self.m11() - self.m10() * self.m01()
    }
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
