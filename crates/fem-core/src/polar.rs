//! Closed-form polar decomposition `F = R S` of a 2x2 matrix with `R` a proper rotation.
//!
//! In 2D the rotation that maximises `tr(R^T F)` over all rotations (the rotation factor of the
//! polar decomposition when `det F > 0`) is the rotation by `theta = atan2(F10 - F01, F00 + F11)`.
//! Written with `A = F00 + F11` and `B = F10 - F01`, `R = [[A, -B], [B, A]] / sqrt(A^2 + B^2)`.
//! It is always a proper rotation (`det R = +1`), also when `F` is inverted: then `S = R^T F`
//! is symmetric but indefinite, which is what inversion-aware co-rotational elasticity wants.
//! When `A = B = 0` (`F` is a scaled reflection, `[[a, b], [b, -a]]`) every rotation is a
//! maximiser; we return the identity.

use crate::math::{Mat2, Real};

/// The rotation factor of `F` and the derivative data needed by dP/dF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Polar2 {
    /// `cos(theta)`.
    pub c: Real,
    /// `sin(theta)`.
    pub s: Real,
    /// `1 / sqrt(A^2 + B^2)`, zero in the degenerate case (then `R` is frozen at the identity).
    pub inv_norm: Real,
}

impl Polar2 {
    /// Decompose `f`.
    #[inline]
    pub fn new(f: &Mat2) -> Self {
        let a = f[(0, 0)] + f[(1, 1)];
        let b = f[(1, 0)] - f[(0, 1)];
        let n2 = a * a + b * b;
        if n2 > 0.0 && n2.is_finite() {
            let inv = n2.sqrt().recip();
            Polar2 {
                c: a * inv,
                s: b * inv,
                inv_norm: inv,
            }
        } else {
            Polar2 {
                c: 1.0,
                s: 0.0,
                inv_norm: 0.0,
            }
        }
    }

    /// The rotation `R`.
    #[inline]
    pub fn rotation(&self) -> Mat2 {
        Mat2::new(self.c, -self.s, self.s, self.c)
    }

    /// `dtheta` for a perturbation `dF`: `(A dB - B dA) / (A^2 + B^2) = (c dB - s dA) / |(A, B)|`.
    #[inline]
    pub fn dtheta(&self, df: &Mat2) -> Real {
        let da = df[(0, 0)] + df[(1, 1)];
        let db = df[(1, 0)] - df[(0, 1)];
        (self.c * db - self.s * da) * self.inv_norm
    }

    /// `dR/dtheta = R [[0, -1], [1, 0]]`.
    #[inline]
    pub fn drotation(&self) -> Mat2 {
        Mat2::new(-self.s, -self.c, self.c, -self.s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rotation;

    #[test]
    fn recovers_rotation_and_symmetric_stretch() {
        let s = Mat2::new(1.4, 0.3, 0.3, 0.7);
        let r = rotation(0.83);
        let p = Polar2::new(&(r * s));
        assert!((p.rotation() - r).norm() < 1e-14);
        let stretch = p.rotation().transpose() * r * s;
        assert!((stretch - stretch.transpose()).norm() < 1e-14);
    }

    #[test]
    fn inverted_f_gives_proper_rotation_with_symmetric_indefinite_stretch() {
        let f = Mat2::new(-0.5, 0.2, 0.1, 1.1);
        let p = Polar2::new(&f);
        let r = p.rotation();
        assert!((r.determinant() - 1.0).abs() < 1e-14);
        let s = r.transpose() * f;
        assert!((s - s.transpose()).norm() < 1e-14);
        assert!(s.determinant() < 0.0);
    }

    #[test]
    fn scaled_reflection_falls_back_to_identity() {
        let p = Polar2::new(&Mat2::new(1.0, 2.0, 2.0, -1.0));
        assert_eq!(p.rotation(), Mat2::identity());
        assert_eq!(p.inv_norm, 0.0);
    }
}
