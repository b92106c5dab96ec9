//! Test and bench support: a deterministic random source and structured rectangle meshes.
//!
//! Kept here rather than in the library: structured meshing belongs to `fem-mesh`, and
//! `fem-core` may not depend on it.
#![allow(dead_code)]

use fem_core::dim::{Mat3, Vec3};
use fem_core::math::{Mat2, Real, Vec2};
use fem_core::mesh::Mesh;

/// SplitMix64: a tiny, well-mixed, reproducible generator (no dependency for a few numbers).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: Real, hi: Real) -> Real {
        lo + (hi - lo) * (self.next_u64() >> 11) as Real / (1u64 << 53) as Real
    }

    /// A deformation gradient `I + H` with entries of `H` in `[-amp, amp]` and
    /// `det F >= min_det` (rejection sampling).
    pub fn deformation_gradient(&mut self, amp: Real, min_det: Real) -> Mat2 {
        loop {
            let f = Mat2::new(
                1.0 + self.uniform(-amp, amp),
                self.uniform(-amp, amp),
                self.uniform(-amp, amp),
                1.0 + self.uniform(-amp, amp),
            );
            if f.determinant() >= min_det {
                return f;
            }
        }
    }

    /// The 3x3 analogue of [`Rng::deformation_gradient`]: `I + H` with entries of `H` in
    /// `[-amp, amp]` (column-major draw order) and `det F >= min_det` (rejection sampling).
    pub fn deformation_gradient3(&mut self, amp: Real, min_det: Real) -> Mat3 {
        loop {
            let mut f = Mat3::identity();
            for k in 0..9 {
                f[k] += self.uniform(-amp, amp);
            }
            if f.determinant() >= min_det {
                return f;
            }
        }
    }

    /// A uniformly distributed unit vector (rejection sampling in the unit ball).
    pub fn unit_vector3(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
            );
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }

    /// A random proper rotation (`det = +1`): a uniform axis and an angle in `[0, 2 pi)`,
    /// by Rodrigues' formula.
    pub fn rotation3(&mut self) -> Mat3 {
        let axis = nalgebra::Unit::new_unchecked(self.unit_vector3());
        let angle = self.uniform(0.0, std::f64::consts::TAU);
        nalgebra::Rotation3::from_axis_angle(&axis, angle).into_inner()
    }
}

pub use fem_core::structured::Diagonal;

/// The structured `nx x ny` mesh of `[0, lx] x [0, ly]` ([`fem_core::structured::rectangle`]).
pub fn rectangle(lx: Real, ly: Real, nx: usize, ny: usize, diagonal: Diagonal) -> Mesh {
    let params = fem_core::structured::RectangleParams {
        diagonal,
        ..fem_core::structured::RectangleParams::new(lx, ly, nx, ny)
    };
    fem_core::structured::rectangle(&params).expect("structured rectangle meshes are valid")
}

/// Rest positions moved by a smooth, large, non-affine deformation plus a small random jitter,
/// so no two elements share the same `F`.
pub fn deformed(mesh: &Mesh, rng: &mut Rng, amplitude: Real) -> Vec<Vec2> {
    mesh.vertices()
        .iter()
        .map(|p| {
            let bend = Vec2::new(
                p.x + amplitude * (0.7 * p.y).sin() + 0.1 * p.x * p.y,
                p.y + amplitude * (0.9 * p.x).sin() - 0.05 * p.x * p.x,
            );
            bend + Vec2::new(rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01))
        })
        .collect()
}
