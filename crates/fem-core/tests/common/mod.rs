//! Test and bench support: a deterministic random source and structured rectangle meshes.
//!
//! Kept here rather than in the library: structured meshing belongs to `fem-mesh`, and
//! `fem-core` may not depend on it.
#![allow(dead_code)]

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
}

/// The diagonal each quad of a structured mesh is split along.
#[derive(Clone, Copy, Debug)]
pub enum Diagonal {
    /// From lower-left to upper-right in every quad.
    Right,
    /// Alternating in a checkerboard (the "union jack"-free criss-cross pattern).
    Alternating,
}

/// A structured `nx x ny` quad mesh of `[0, lx] x [0, ly]`, each quad split into two
/// counter-clockwise triangles. Node `(i, j)` has index `i (ny + 1) + j`.
pub fn rectangle(lx: Real, ly: Real, nx: usize, ny: usize, diagonal: Diagonal) -> Mesh {
    let mut vertices = Vec::with_capacity((nx + 1) * (ny + 1));
    for i in 0..=nx {
        for j in 0..=ny {
            vertices.push(Vec2::new(
                i as Real * lx / nx as Real,
                j as Real * ly / ny as Real,
            ));
        }
    }
    let id = |i: usize, j: usize| (i * (ny + 1) + j) as u32;
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for i in 0..nx {
        for j in 0..ny {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            let flip = matches!(diagonal, Diagonal::Alternating) && (i + j) % 2 == 1;
            if flip {
                triangles.push([a, b, d]);
                triangles.push([b, c, d]);
            } else {
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
    }
    Mesh::new(vertices, triangles).expect("structured rectangle meshes are valid")
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
