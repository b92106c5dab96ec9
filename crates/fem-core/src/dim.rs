//! The spatial dimension as a type: [`D2`] (triangles, plane strain) and [`D3`] (tetrahedra).
//!
//! Code that is the same in 2D and 3D (an energy written over `F`, the linear simplex, a mesh
//! of simplices, assembly) is generic over `D: Dim`; where the mathematics differs the trait
//! holds a **per-dimension kernel**:
//!
//! | kernel                   | [`D2`]                                 | [`D3`]                                 |
//! |--------------------------|----------------------------------------|----------------------------------------|
//! | determinant, cofactor    | closed form                            | closed form                            |
//! | `d cof(F)[dF]`           | `cof(dF)` (linear in `F`)              | bilinear: `cof(F + dF) - cof(F) - cof(dF)` |
//! | polar rotation `R`       | closed form ([`crate::polar::Polar2`]) | from the rotation-variant SVD          |
//! | rotation-variant SVD     | closed form ([`crate::energy::svd_rotation_variant`]) | nalgebra's SVD, signs fixed |
//! | isotropic PSD projection | closed form 2x2 blocks ([`crate::energy::project_psd_isotropic`]) | the same eigenbasis, a 3x3 scaling block |
//! | von Mises                | plane strain, with `sigma_zz`          | the full 3D formula                    |
//!
//! Fourth-order tensors act on the column-major `vec(F)` in both dimensions ([`crate::math`]):
//! a [`Dim::Tangent`] is `D^2 x D^2` and entry `(i + D j, k + D l)` is `dP_ij / dF_kl`.
//!
//! The trait is **sealed**: the two markers are the only dimensions, and every generic function
//! is checked by the compiler for both (the crate's tests instantiate each one with both).

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

use nalgebra::{Matrix3, SMatrix, SymmetricEigen, Vector3};

use crate::math::{Mat2, Mat4, Real, Vec2};

/// A point or a vector in space.
pub type Vec3 = Vector3<Real>;
/// A 3x3 matrix (deformation gradient, stress in 3D).
pub type Mat3 = Matrix3<Real>;
/// A 9x9 matrix acting on `vec(F)` of a 3x3 `F` (`dP/dF` in 3D).
pub type Mat9 = SMatrix<Real, 9, 9>;

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::D2 {}
    impl Sealed for super::D3 {}
}

/// The arithmetic generic kernels need from a small dense vector or matrix (nalgebra's
/// fixed-size types; the trait only names what they already do).
pub trait Dense:
    Copy
    + Debug
    + PartialEq
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Neg<Output = Self>
    + Mul<Real, Output = Self>
    + Div<Real, Output = Self>
    + AddAssign
{
    /// Number of entries.
    const LEN: usize;
    /// All zeros.
    fn zeros() -> Self;
    /// Entry `k` in column-major order.
    fn at(&self, k: usize) -> Real;
    /// Set entry `k` in column-major order.
    fn set_at(&mut self, k: usize, value: Real);
    /// The Frobenius (Euclidean) inner product.
    fn inner(&self, other: &Self) -> Real {
        (0..Self::LEN).map(|k| self.at(k) * other.at(k)).sum()
    }
    /// The squared Frobenius (Euclidean) norm.
    fn norm2(&self) -> Real {
        self.inner(self)
    }
    /// Every entry finite.
    fn all_finite(&self) -> bool {
        (0..Self::LEN).all(|k| self.at(k).is_finite())
    }
}

macro_rules! impl_dense {
    ($($ty:ty),*) => {$(
        impl Dense for $ty {
            const LEN: usize = <$ty as FixedLen>::LEN;
            #[inline]
            fn zeros() -> Self {
                <$ty>::zeros()
            }
            #[inline]
            fn at(&self, k: usize) -> Real {
                self[k]
            }
            #[inline]
            fn set_at(&mut self, k: usize, value: Real) {
                self[k] = value;
            }
        }
    )*};
}

// nalgebra's fixed-size types have no associated `LEN`; name it here.
trait FixedLen {
    const LEN: usize;
}
impl<const R: usize, const C: usize> FixedLen for SMatrix<Real, R, C> {
    const LEN: usize = R * C;
}

impl_dense!(Vec2, Vec3, Mat2, Mat3, Mat4, Mat9);

/// A spatial dimension: [`D2`] or [`D3`] (sealed).
pub trait Dim: sealed::Sealed + Copy + Clone + Debug + Default + Send + Sync + 'static {
    /// The number of spatial dimensions.
    const D: usize;
    /// Nodes of the linear simplex (triangle, tetrahedron): `D + 1`.
    const NODES: usize;
    /// `"2d"` or `"3d"`, as files and the command line spell it.
    const NAME: &'static str;
    /// The simplex's name in messages (`triangle`, `tetrahedron`).
    const SIMPLEX: &'static str;

    /// A point or a vector.
    type Vector: Dense;
    /// A `D x D` matrix (`F`, `P`, stress).
    type Matrix: Dense
        + Mul<Self::Matrix, Output = Self::Matrix>
        + Mul<Self::Vector, Output = Self::Vector>;
    /// A `D^2 x D^2` matrix on `vec(F)` (`dP/dF`).
    type Tangent: Dense + Mul<Self::Tangent, Output = Self::Tangent>;
    /// The vertex indices of one simplex, `[u32; D + 1]`.
    type Cell: Copy + Debug + PartialEq + Eq + Send + Sync + Default + AsRef<[u32]> + AsMut<[u32]>;

    /// The identity matrix.
    fn identity() -> Self::Matrix;
    /// Entry `(i, j)`.
    #[inline]
    fn entry(m: &Self::Matrix, i: usize, j: usize) -> Real {
        m.at(i + Self::D * j)
    }
    /// `m^T`.
    fn transpose(m: &Self::Matrix) -> Self::Matrix;
    /// `tr(m)`.
    fn trace(m: &Self::Matrix) -> Real {
        (0..Self::D).map(|i| Self::entry(m, i, i)).sum()
    }
    /// `det(m)`.
    fn det(m: &Self::Matrix) -> Real;
    /// The cofactor matrix `cof(F) = dJ/dF = J F^-T` (defined for singular `F` too).
    fn cofactor(f: &Self::Matrix) -> Self::Matrix;
    /// The derivative of [`Dim::cofactor`] at `f` along `df`.
    fn dcofactor(f: &Self::Matrix, df: &Self::Matrix) -> Self::Matrix;
    /// `m^-1`, or `None` when `m` is singular.
    fn inverse(m: &Self::Matrix) -> Option<Self::Matrix>;
    /// The matrix whose columns are `cols` (`D` of them).
    fn from_columns(cols: &[Self::Vector]) -> Self::Matrix;
    /// Row `i` of `m` as a vector.
    fn row(m: &Self::Matrix, i: usize) -> Self::Vector;
    /// The outer product `a b^T`.
    fn outer(a: &Self::Vector, b: &Self::Vector) -> Self::Matrix;

    /// The identity on `vec(F)`.
    fn tangent_identity() -> Self::Tangent;
    /// `vec(a) vec(b)^T`.
    fn tangent_outer(a: &Self::Matrix, b: &Self::Matrix) -> Self::Tangent;
    /// `T^T`.
    fn tangent_transpose(t: &Self::Tangent) -> Self::Tangent;
    /// The tangent applied to a perturbation: `vec(dP) = T vec(dF)`.
    fn apply(t: &Self::Tangent, df: &Self::Matrix) -> Self::Matrix {
        let n = Self::D * Self::D;
        let mut out = Self::Matrix::zeros();
        for r in 0..n {
            out.set_at(r, (0..n).map(|c| t.at(r + n * c) * df.at(c)).sum());
        }
        out
    }
    /// The matrix of the linear map `dF -> map(dF)`, column by column from the unit matrices.
    fn linear_map(map: impl Fn(&Self::Matrix) -> Self::Matrix) -> Self::Tangent {
        let n = Self::D * Self::D;
        let mut t = Self::Tangent::zeros();
        for c in 0..n {
            let mut e = Self::Matrix::zeros();
            e.set_at(c, 1.0);
            let col = map(&e);
            for r in 0..n {
                t.set_at(r + n * c, col.at(r));
            }
        }
        t
    }
    /// The corner block `B_ik = sum_jl g_j T_(ij),(kl) h_l` of a tangent between two corners
    /// with shape-function gradients `g` and `h` (the stiffness block per unit measure).
    fn contract(t: &Self::Tangent, g: &Self::Vector, h: &Self::Vector) -> Self::Matrix {
        let (d, n) = (Self::D, Self::D * Self::D);
        let mut b = Self::Matrix::zeros();
        for i in 0..d {
            for k in 0..d {
                let mut s = 0.0;
                for j in 0..d {
                    for l in 0..d {
                        s += g.at(j) * t.at(i + d * j + n * (k + d * l)) * h.at(l);
                    }
                }
                b.set_at(i + d * k, s);
            }
        }
        b
    }

    /// The rotation-variant SVD `F = U diag(s) V^T`: `U` and `V` proper rotations, `s` sorted
    /// by decreasing magnitude with the last one negative when `det F < 0`.
    fn svd_rotation_variant(f: &Self::Matrix) -> (Self::Matrix, Self::Vector, Self::Matrix);
    /// The proper rotation `R` that maximises `tr(R^T F)` (the polar rotation of `F` when
    /// `det F > 0`).
    fn polar_rotation(f: &Self::Matrix) -> Self::Matrix;
    /// The derivative of [`Dim::polar_rotation`] at `f` along `df` (zero in a degenerate
    /// direction, where the rotation is not unique).
    fn drotation(f: &Self::Matrix, df: &Self::Matrix) -> Self::Matrix;
    /// [`Dim::drotation`] at `f` for every direction at once, as a tangent on `vec(dF)` (in 3D
    /// one SVD for all nine directions).
    fn drotation_tangent(f: &Self::Matrix) -> Self::Tangent {
        Self::linear_map(|df| Self::drotation(f, df))
    }
    /// The PSD projection of the tangent `d` of an **isotropic** energy at `f`, through the
    /// analytic eigenbasis `U e_a e_b^T V^T` of the rotation-variant SVD (Smith, de Goes and
    /// Kim 2019): scaling directions in one `D x D` block, each twist/flip pair in a 2x2 block.
    fn project_psd_isotropic(f: &Self::Matrix, d: &Self::Tangent) -> Self::Tangent;
    /// The PSD projection of any symmetric tangent by an iterative symmetric eigendecomposition
    /// (the oracle of [`Dim::project_psd_isotropic`]).
    fn project_psd(d: &Self::Tangent) -> Self::Tangent;
    /// The smallest eigenvalue of the tangent's symmetric part.
    fn min_eigenvalue(d: &Self::Tangent) -> Real;

    /// Von Mises stress of the Cauchy stress `sigma` (with the out-of-plane `sigma_zz` of
    /// plane strain in 2D; ignored in 3D).
    fn von_mises(sigma: &Self::Matrix, sigma_zz: Real) -> Real;
}

/// Two dimensions: triangles in plane strain.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct D2;

/// Three dimensions: tetrahedra.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct D3;

impl Dim for D2 {
    const D: usize = 2;
    const NODES: usize = 3;
    const NAME: &'static str = "2d";
    const SIMPLEX: &'static str = "triangle";
    type Vector = Vec2;
    type Matrix = Mat2;
    type Tangent = Mat4;
    type Cell = [u32; 3];

    #[inline]
    fn identity() -> Mat2 {
        Mat2::identity()
    }
    #[inline]
    fn transpose(m: &Mat2) -> Mat2 {
        m.transpose()
    }
    #[inline]
    fn det(m: &Mat2) -> Real {
        m.determinant()
    }
    #[inline]
    fn cofactor(f: &Mat2) -> Mat2 {
        crate::math::cofactor(f)
    }
    #[inline]
    fn dcofactor(_f: &Mat2, df: &Mat2) -> Mat2 {
        crate::math::cofactor(df)
    }
    #[inline]
    fn inverse(m: &Mat2) -> Option<Mat2> {
        m.try_inverse()
    }
    #[inline]
    fn from_columns(cols: &[Vec2]) -> Mat2 {
        Mat2::from_columns(&cols[..2])
    }
    #[inline]
    fn row(m: &Mat2, i: usize) -> Vec2 {
        m.row(i).transpose()
    }
    #[inline]
    fn outer(a: &Vec2, b: &Vec2) -> Mat2 {
        a * b.transpose()
    }
    #[inline]
    fn tangent_identity() -> Mat4 {
        Mat4::identity()
    }
    #[inline]
    fn tangent_outer(a: &Mat2, b: &Mat2) -> Mat4 {
        crate::math::outer(a, b)
    }
    #[inline]
    fn tangent_transpose(t: &Mat4) -> Mat4 {
        t.transpose()
    }
    fn svd_rotation_variant(f: &Mat2) -> (Mat2, Vec2, Mat2) {
        crate::energy::svd_rotation_variant(f)
    }
    fn polar_rotation(f: &Mat2) -> Mat2 {
        crate::polar::Polar2::new(f).rotation()
    }
    fn drotation(f: &Mat2, df: &Mat2) -> Mat2 {
        let polar = crate::polar::Polar2::new(f);
        polar.drotation() * polar.dtheta(df)
    }
    fn project_psd_isotropic(f: &Mat2, d: &Mat4) -> Mat4 {
        crate::energy::project_psd_isotropic(f, d)
    }
    fn project_psd(d: &Mat4) -> Mat4 {
        crate::energy::project_psd(d)
    }
    fn min_eigenvalue(d: &Mat4) -> Real {
        SymmetricEigen::new((d + d.transpose()) * 0.5)
            .eigenvalues
            .min()
    }
    fn von_mises(sigma: &Mat2, sigma_zz: Real) -> Real {
        crate::stress::von_mises(sigma, sigma_zz)
    }
}

impl Dim for D3 {
    const D: usize = 3;
    const NODES: usize = 4;
    const NAME: &'static str = "3d";
    const SIMPLEX: &'static str = "tetrahedron";
    type Vector = Vec3;
    type Matrix = Mat3;
    type Tangent = Mat9;
    type Cell = [u32; 4];

    #[inline]
    fn identity() -> Mat3 {
        Mat3::identity()
    }
    #[inline]
    fn transpose(m: &Mat3) -> Mat3 {
        m.transpose()
    }
    #[inline]
    fn det(m: &Mat3) -> Real {
        m.determinant()
    }
    /// Columns: `cof(F) = [f1 x f2, f2 x f0, f0 x f1]` row-wise, i.e. row `i` of `cof F` is
    /// the cross product of the other two columns of `F` (so `F^T cof(F) = J I`).
    #[inline]
    fn cofactor(f: &Mat3) -> Mat3 {
        let (c0, c1, c2) = (f.column(0), f.column(1), f.column(2));
        Mat3::from_columns(&[c1.cross(&c2), c2.cross(&c0), c0.cross(&c1)])
    }
    /// `d cof(F)[dF]`: column `k` of `cof F` is `f_(k+1) x f_(k+2)`, so its derivative is
    /// `df_(k+1) x f_(k+2) + f_(k+1) x df_(k+2)`.
    #[inline]
    fn dcofactor(f: &Mat3, df: &Mat3) -> Mat3 {
        let col = |k: usize| {
            let (a, b) = ((k + 1) % 3, (k + 2) % 3);
            df.column(a).cross(&f.column(b)) + f.column(a).cross(&df.column(b))
        };
        Mat3::from_columns(&[col(0), col(1), col(2)])
    }
    #[inline]
    fn inverse(m: &Mat3) -> Option<Mat3> {
        m.try_inverse()
    }
    #[inline]
    fn from_columns(cols: &[Vec3]) -> Mat3 {
        Mat3::from_columns(&cols[..3])
    }
    #[inline]
    fn row(m: &Mat3, i: usize) -> Vec3 {
        m.row(i).transpose()
    }
    #[inline]
    fn outer(a: &Vec3, b: &Vec3) -> Mat3 {
        a * b.transpose()
    }
    #[inline]
    fn tangent_identity() -> Mat9 {
        Mat9::identity()
    }
    #[inline]
    fn tangent_outer(a: &Mat3, b: &Mat3) -> Mat9 {
        let (va, vb) = (
            SMatrix::<Real, 9, 1>::from_column_slice(a.as_slice()),
            SMatrix::<Real, 9, 1>::from_column_slice(b.as_slice()),
        );
        va * vb.transpose()
    }
    #[inline]
    fn tangent_transpose(t: &Mat9) -> Mat9 {
        t.transpose()
    }

    /// nalgebra's SVD (singular values non-negative and sorted decreasing), then the
    /// reflections of `U` and `V` moved into the smallest singular value, as inversion-aware
    /// elasticity wants (Irving, Teran and Fedkiw 2004; Kim and Eberle 2022, sec. 5).
    fn svd_rotation_variant(f: &Mat3) -> (Mat3, Vec3, Mat3) {
        let svd = f.svd(true, true);
        let (mut u, mut s, mut v) = match (svd.u, svd.v_t) {
            (Some(u), Some(v_t)) => (u, svd.singular_values, v_t.transpose()),
            // nalgebra computes both factors when asked; a non-finite `F` is the only way
            // here, and it gives a non-finite answer.
            _ => {
                return (
                    Mat3::from_element(Real::NAN),
                    Vec3::from_element(Real::NAN),
                    Mat3::from_element(Real::NAN),
                );
            }
        };
        // Sort by decreasing singular value (nalgebra sorts, but say so in code).
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| s[b].total_cmp(&s[a]));
        if order != [0, 1, 2] {
            let (u0, s0, v0) = (u, s, v);
            for (k, &o) in order.iter().enumerate() {
                u.set_column(k, &u0.column(o));
                v.set_column(k, &v0.column(o));
                s[k] = s0[o];
            }
        }
        if u.determinant() < 0.0 {
            u.column_mut(2).neg_mut();
            s[2] = -s[2];
        }
        if v.determinant() < 0.0 {
            v.column_mut(2).neg_mut();
            s[2] = -s[2];
        }
        (u, s, v)
    }

    fn polar_rotation(f: &Mat3) -> Mat3 {
        let (u, _, v) = Self::svd_rotation_variant(f);
        u * v.transpose()
    }

    /// With `F = U diag(s) V^T` and `M = U^T dF V`, `dR = U W V^T` where `W` is skew with
    /// `W_ij = (M_ij - M_ji) / (s_i + s_j)` (Kim and Eberle 2022, sec. 5.3; Papadopoulo and
    /// Lourakis 2000). A pair with `s_i + s_j = 0` is a direction in which the rotation is not
    /// unique; it contributes zero.
    fn drotation(f: &Mat3, df: &Mat3) -> Mat3 {
        let (u, s, v) = Self::svd_rotation_variant(f);
        drotation_from_svd(&u, &s, &v, df)
    }

    fn drotation_tangent(f: &Mat3) -> Mat9 {
        let (u, s, v) = Self::svd_rotation_variant(f);
        Self::linear_map(|df| drotation_from_svd(&u, &s, &v, df))
    }

    fn project_psd_isotropic(f: &Mat3, d: &Mat9) -> Mat9 {
        let sym = (d + d.transpose()) * 0.5;
        if nalgebra::Cholesky::new(sym).is_some() {
            return sym;
        }
        let (u, _, v) = Self::svd_rotation_variant(f);
        // Columns of the eigenbasis: vec(u_a v_b^T) for the scaling directions (a, a), then
        // each twist/flip pair (a, b), (b, a) with a < b.
        const PAIRS: [(usize, usize); 9] = [
            (0, 0),
            (1, 1),
            (2, 2),
            (0, 1),
            (1, 0),
            (0, 2),
            (2, 0),
            (1, 2),
            (2, 1),
        ];
        let mut q = Mat9::zeros();
        for (k, (a, b)) in PAIRS.into_iter().enumerate() {
            for j in 0..3 {
                for i in 0..3 {
                    q[(i + 3 * j, k)] = u[(i, a)] * v[(j, b)];
                }
            }
        }
        let rotated = q.transpose() * sym * q;
        let mut clamped = Mat9::zeros();
        let mut changed = false;
        // The 3x3 scaling block.
        let scaling = rotated.fixed_view::<3, 3>(0, 0).into_owned();
        let scaling = (scaling + scaling.transpose()) * 0.5;
        let eig = SymmetricEigen::new(scaling);
        if eig.eigenvalues.iter().any(|&l| l < 0.0) {
            changed = true;
            let mut e = eig;
            e.eigenvalues.iter_mut().for_each(|l| *l = l.max(0.0));
            clamped
                .fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&e.recompose());
        } else {
            clamped.fixed_view_mut::<3, 3>(0, 0).copy_from(&scaling);
        }
        for o in [3, 5, 7] {
            let block = (
                rotated[(o, o)],
                rotated[(o, o + 1)],
                rotated[(o + 1, o + 1)],
            );
            let p = crate::energy::project_psd2(block.0, block.1, block.2);
            changed |= p != block;
            clamped[(o, o)] = p.0;
            clamped[(o, o + 1)] = p.1;
            clamped[(o + 1, o)] = p.1;
            clamped[(o + 1, o + 1)] = p.2;
        }
        if !changed {
            return sym;
        }
        q * clamped * q.transpose()
    }

    fn project_psd(d: &Mat9) -> Mat9 {
        let sym = (d + d.transpose()) * 0.5;
        if nalgebra::Cholesky::new(sym).is_some() {
            return sym;
        }
        let mut eig = SymmetricEigen::new(sym);
        if eig.eigenvalues.iter().all(|&l| l >= 0.0) {
            return sym;
        }
        eig.eigenvalues.iter_mut().for_each(|l| *l = l.max(0.0));
        eig.recompose()
    }

    fn min_eigenvalue(d: &Mat9) -> Real {
        SymmetricEigen::new((d + d.transpose()) * 0.5)
            .eigenvalues
            .min()
    }

    /// `sqrt(3/2 s:s)` with the deviator `s = sigma - tr(sigma)/3 I`.
    fn von_mises(sigma: &Mat3, _sigma_zz: Real) -> Real {
        let dev = sigma - Mat3::identity() * (sigma.trace() / 3.0);
        (1.5 * dev.norm_squared()).sqrt()
    }
}

/// `dR = U W V^T` for `F = U diag(s) V^T` (see [`Dim::drotation`] of [`D3`]).
fn drotation_from_svd(u: &Mat3, s: &Vec3, v: &Mat3, df: &Mat3) -> Mat3 {
    let m = u.transpose() * df * v;
    let mut w = Mat3::zeros();
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let denom = s[i] + s[j];
        let x = if denom.abs() > Real::EPSILON * s[0].abs() {
            (m[(i, j)] - m[(j, i)]) / denom
        } else {
            0.0
        };
        w[(i, j)] = x;
        w[(j, i)] = -x;
    }
    u * w * v.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drotation_tangent_is_drotation_in_every_direction() {
        let f = sample3();
        let t = D3::drotation_tangent(&f);
        let df = Mat3::new(0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2, 0.3, -0.6);
        assert!((D3::apply(&t, &df) - D3::drotation(&f, &df)).norm() < 1e-14);
    }

    fn sample3() -> Mat3 {
        Mat3::new(1.2, 0.3, -0.1, 0.2, 0.9, 0.25, -0.15, 0.1, 1.1)
    }

    #[test]
    fn cofactor_is_j_f_inverse_transpose() {
        let f = sample3();
        let want = f.try_inverse().unwrap().transpose() * f.determinant();
        assert!((D3::cofactor(&f) - want).norm() < 1e-14);
        let f2 = Mat2::new(1.2, 0.3, -0.4, 0.8);
        let want2 = f2.try_inverse().unwrap().transpose() * f2.determinant();
        assert!((D2::cofactor(&f2) - want2).norm() < 1e-14);
    }

    #[test]
    fn dcofactor_matches_central_difference() {
        let f = sample3();
        let df = Mat3::new(0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2, 0.3, -0.6);
        let h = 1e-6;
        let fd = (D3::cofactor(&(f + df * h)) - D3::cofactor(&(f - df * h))) / (2.0 * h);
        // cof is quadratic in F, so the central difference is exact up to round-off.
        assert!((D3::dcofactor(&f, &df) - fd).norm() < 1e-8);
    }

    #[test]
    fn svd_is_rotation_variant_and_reconstructs() {
        let mut f = sample3();
        for inverted in [false, true] {
            if inverted {
                f.column_mut(0).neg_mut();
            }
            let (u, s, v) = D3::svd_rotation_variant(&f);
            let back = u * Mat3::from_diagonal(&s) * v.transpose();
            assert!((back - f).norm() < 1e-13, "{back} vs {f}");
            assert!((u.determinant() - 1.0).abs() < 1e-13);
            assert!((v.determinant() - 1.0).abs() < 1e-13);
            assert!(s[0] >= s[1].abs() && s[1].abs() >= s[2].abs());
            assert_eq!(s[2] < 0.0, inverted);
        }
    }

    #[test]
    fn drotation_matches_central_difference() {
        let f = sample3();
        let df = Mat3::new(0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2, 0.3, -0.6);
        let h = 1e-6;
        let fd =
            (D3::polar_rotation(&(f + df * h)) - D3::polar_rotation(&(f - df * h))) / (2.0 * h);
        assert!((D3::drotation(&f, &df) - fd).norm() < 1e-7);
        let f2 = Mat2::new(1.2, 0.3, -0.4, 0.8);
        let df2 = Mat2::new(0.3, -0.2, 0.5, 0.1);
        let fd2 =
            (D2::polar_rotation(&(f2 + df2 * h)) - D2::polar_rotation(&(f2 - df2 * h))) / (2.0 * h);
        assert!((D2::drotation(&f2, &df2) - fd2).norm() < 1e-8);
    }

    #[test]
    fn von_mises_of_uniaxial_stress_is_the_stress() {
        let sigma = Mat3::from_diagonal(&Vec3::new(7.0, 0.0, 0.0));
        assert!((D3::von_mises(&sigma, 0.0) - 7.0).abs() < 1e-14);
        // Hydrostatic stress has none.
        assert!(D3::von_mises(&(Mat3::identity() * 3.0), 0.0) < 1e-14);
    }

    #[test]
    fn contract_of_identity_is_g_dot_h() {
        let g = Vec3::new(1.0, 2.0, 3.0);
        let h = Vec3::new(-1.0, 0.5, 2.0);
        let b = D3::contract(&D3::tangent_identity(), &g, &h);
        assert!((b - Mat3::identity() * g.dot(&h)).norm() < 1e-14);
    }
}
