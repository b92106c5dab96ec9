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
//! result for element `i`; written this way the compiler vectorises it for whichever
//! instruction set [`crate::simd::Isa::run`] compiles it for.

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

/// `e^x`, the same bits on every target (the `libm` crate: the platform's own `exp` differs
/// between a native build and WebAssembly in the last bit, which a damped run would carry).
#[inline]
pub fn exp(x: Real) -> Real {
    libm::exp(x)
}

/// `ln(1 + x)`, the same bits on every target (see [`exp`]).
#[inline]
pub fn ln_1p(x: Real) -> Real {
    libm::log1p(x)
}

/// `(sin x, cos x)`, the same bits on every target (see [`exp`]).
#[inline]
pub fn sin_cos(x: Real) -> (Real, Real) {
    libm::sincos(x)
}

/// Rotation matrix by angle `theta` (counter-clockwise).
#[inline]
pub fn rotation(theta: Real) -> Mat2 {
    let (s, c) = sin_cos(theta);
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

/// `v` as Rust prints it, or in scientific notation when that would be long: error messages
/// show `5e-324` and `-1e300`, not hundreds of digits.
pub fn readable(v: Real) -> String {
    let plain = v.to_string();
    if plain.len() > 24 {
        format!("{v:e}")
    } else {
        plain
    }
}

/// The natural logarithm, correct to within one unit in the last place, in plain IEEE
/// arithmetic and no branches, so that the batched kernels vectorise it and every machine,
/// instruction set and WebAssembly build computes the same bits (see [`crate::simd`]).
///
/// The algorithm is fdlibm's `__ieee754_log` (Sun Microsystems, 1993), unchanged in its
/// arithmetic: write `x = 2^k (1 + f)` with `sqrt(2)/2 <= 1 + f < sqrt(2)`, then
/// `ln(1 + f) = 2s + 2s^3/3 + ...` with `s = f / (2 + f)`, the series tail a degree-14
/// minimax polynomial in `s`, and `k ln 2` split into a high part exact in `k` and a low part.
/// Its two accuracy branches (near 1 and away from 1) are both evaluated and one selected.
/// Special values follow IEEE: `ln(0) = -inf`, `ln(x < 0) = NaN`, `ln(inf) = inf`,
/// `ln(NaN) = NaN`; subnormal inputs are scaled into the normal range first.
#[inline(always)]
pub fn ln(x: Real) -> Real {
    const LN2_HI: Real = f64::from_bits(0x3fe6_2e42_fee0_0000);
    const LN2_LO: Real = f64::from_bits(0x3dea_39ef_3579_3c76);
    const LG1: Real = f64::from_bits(0x3fe5_5555_5555_5593);
    const LG2: Real = f64::from_bits(0x3fd9_9999_9997_fa04);
    const LG3: Real = f64::from_bits(0x3fd2_4924_9422_9359);
    const LG4: Real = f64::from_bits(0x3fcc_71c5_1d8e_78af);
    const LG5: Real = f64::from_bits(0x3fc7_4664_96cb_03de);
    const LG6: Real = f64::from_bits(0x3fc3_9a09_d078_c69f);
    const LG7: Real = f64::from_bits(0x3fc2_f112_df3e_5244);
    const TWO54: Real = f64::from_bits(0x4350_0000_0000_0000);
    // 2^52 as a double: or-ing a small integer into its mantissa and subtracting it converts
    // the integer exactly, with no integer-to-float instruction (which AVX2 lacks for 64 bits).
    const MAGIC: u64 = 0x4330_0000_0000_0000;
    let magic = f64::from_bits(MAGIC);

    let subnormal = x < f64::MIN_POSITIVE;
    let xs = if subnormal { x * TWO54 } else { x };
    let bits = xs.to_bits();
    // The mantissa as a number in [1, 2). fdlibm tests the high 20 bits of the mantissa, `hx`,
    // with integer arithmetic; the same tests are written here as comparisons of `m` with the
    // doubles whose high words are fdlibm's thresholds (exactly equivalent, and cheaper in
    // vector registers, which lack most 64-bit integer comparisons below AVX-512).
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    // fdlibm's `(hx + 0x95f64) & 0x100000`: the mantissa is at least about sqrt(2) (hx >=
    // 0x6a09c); then m / 2 (exact) is used and k is one more.
    let high = m >= f64::from_bits(0x3ff6_a09c_0000_0000);
    let y = if high { m * 0.5 } else { m };
    let exponent = f64::from_bits(MAGIC | (bits >> 52)) - magic;
    let dk =
        (exponent - 1023.0 + if high { 1.0 } else { 0.0 }) - if subnormal { 54.0 } else { 0.0 };

    let f = y - 1.0;
    let s = f / (2.0 + f);
    let z = s * s;
    let w = z * z;
    let t1 = w * (LG2 + w * (LG4 + w * LG6));
    let t2 = z * (LG1 + w * (LG3 + w * (LG5 + w * LG7)));
    let r = t2 + t1;
    let hfsq = 0.5 * f * f;
    // fdlibm's `(hx - 0x6147a) | (0x6b851 - hx) > 0` (0x6147a <= hx <= 0x6b851): the mantissa
    // near sqrt(2), where |f| is largest and the `hfsq` form is the more accurate one.
    let away =
        m >= f64::from_bits(0x3ff6_147a_0000_0000) && m <= f64::from_bits(0x3ff6_b851_ffff_ffff);
    let near = dk * LN2_HI - ((s * (f - r) - dk * LN2_LO) - f);
    let far = dk * LN2_HI - ((hfsq - (s * (hfsq + r) + dk * LN2_LO)) - f);
    let out = if away { far } else { near };

    let out = if x == Real::INFINITY { x } else { out };
    let out = if x == 0.0 { Real::NEG_INFINITY } else { out };
    if x >= 0.0 { out } else { Real::NAN }
}

/// Number of elements a batched kernel evaluates together (see [`Lanes`]).
///
/// Eight: one AVX-512 register of `f64`, two AVX2 registers, four SSE2 registers. The lane
/// count never changes a result (the arithmetic is lane-wise).
pub const LANES: usize = 8;

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

    /// Lane-wise natural logarithm: [`ln`] per lane, which the compiler vectorises (the
    /// C library's `log` cannot be).
    #[inline(always)]
    pub fn ln(self) -> Self {
        self.map(ln)
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

    /// Distance in units in the last place between two finite doubles of the same sign.
    fn ulps(a: Real, b: Real) -> u64 {
        a.to_bits().abs_diff(b.to_bits())
    }

    /// The oracle is the C library's `log` (correctly rounded in all but rare cases): ours is
    /// within one unit in the last place of it over 4 million arguments spread over the whole
    /// range (log-uniform in the exponent), the neighbourhood of 1 (where cancellation is
    /// hardest: `J` of an almost undeformed element) and the subnormals. At 1 it is exactly 0;
    /// the special values follow IEEE.
    #[test]
    fn ln_is_within_one_ulp_of_the_c_library_and_exact_at_one() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            // xorshift64*: a fixed, dependency-free stream.
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            state.wrapping_mul(0x2545_f491_4f6c_dd1d)
        };
        let mut worst = (0, 0.0);
        let mut exact = 0usize;
        let n = 1_000_000;
        for k in 0..4 * n {
            let u = (next() >> 11) as Real / (1u64 << 53) as Real;
            let x = match k / n {
                // Any positive normal double.
                0 => f64::from_bits(0x0010_0000_0000_0000 + next() % 0x7fe0_0000_0000_0000),
                // J of a strained element, 0.5..2.
                1 => 0.5 + 1.5 * u,
                // Within 1e-6 of 1, either side.
                2 => 1.0 + (u - 0.5) * 2e-6,
                // Subnormals.
                _ => f64::from_bits(1 + next() % 0x000f_ffff_ffff_ffff),
            };
            let (ours, libm) = (ln(x), x.ln());
            let d = if ours.signum() == libm.signum() {
                ulps(ours, libm)
            } else {
                u64::MAX
            };
            exact += usize::from(d == 0);
            if d > worst.0 {
                worst = (d, x);
            }
        }
        assert!(worst.0 <= 1, "ln({:e}) is {} ulps off", worst.1, worst.0);
        // Mostly the same bits as the C library (measured: 98.0 %).
        assert!(
            exact as f64 > 0.97 * (4 * n) as f64,
            "{exact} exact of {}",
            4 * n
        );

        assert_eq!(ln(1.0).to_bits(), 0.0f64.to_bits());
        assert_eq!(ln(2.0), std::f64::consts::LN_2);
        assert_eq!(ln(0.0), Real::NEG_INFINITY);
        assert_eq!(ln(-0.0), Real::NEG_INFINITY);
        assert_eq!(ln(Real::INFINITY), Real::INFINITY);
        for bad in [-1.0, -Real::MIN_POSITIVE, Real::NEG_INFINITY, Real::NAN] {
            assert!(ln(bad).is_nan(), "ln({bad})");
        }
    }

    #[test]
    fn batched_ln_equals_ln_lane_by_lane() {
        let xs: [Real; LANES] = std::array::from_fn(|i| 0.3 + 0.45 * i as Real);
        let lanes = Lanes(xs).ln();
        for (l, x) in lanes.0.iter().zip(xs) {
            assert_eq!(l.to_bits(), ln(x).to_bits());
        }
    }
}
