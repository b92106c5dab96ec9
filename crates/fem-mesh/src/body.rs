//! A procedural human body: a 3D triangle surface built in code from ellipsoids and capsules
//! (head, neck, chest, pelvis, arms, hands, legs, feet), about 1.7 m tall, in metres, +Y up, +Z
//! forward (toes and face), +X the body's left, soles at y = 0. It lets the pipeline (and case D)
//! run on a fresh machine without any model file.
//!
//! The surface is a union of closed, overlapping shells (one per part), not a boolean union: the
//! pipeline only needs the projected vertices. Parts overlap generously so every silhouette
//! (side, front, oblique) is one connected region; the arms hang clear of the torso and the legs
//! apart, so the front view shows both gaps.

use std::f64::consts::PI;

use crate::types::Surface3;

/// Target vertex spacing on the part surfaces (metres): fine enough for an alpha radius of a
/// few centimetres.
const SPACING: f64 = 0.015;

/// Builds the body surface.
pub fn human_body() -> Surface3 {
    let mut s = Surface3::default();
    // Head, neck, trunk.
    ellipsoid(&mut s, [0.0, 1.58, 0.01], [0.075, 0.11, 0.095]);
    capsule(&mut s, [0.0, 1.38, 0.0], [0.0, 1.50, 0.0], 0.05);
    ellipsoid(&mut s, [0.0, 1.24, 0.0], [0.17, 0.22, 0.11]);
    ellipsoid(&mut s, [0.0, 0.97, 0.0], [0.16, 0.15, 0.11]);
    // One side's limbs, then their exact mirror image (x -> -x), so that mirror twins project to
    // bit-identical points in a side view and merge.
    let mut left = Surface3::default();
    // Arm: shoulder, elbow, wrist; hand.
    capsule(&mut left, [0.19, 1.40, 0.0], [0.33, 1.12, 0.0], 0.045);
    capsule(&mut left, [0.33, 1.12, 0.0], [0.40, 0.90, 0.05], 0.04);
    ellipsoid(&mut left, [0.41, 0.82, 0.065], [0.025, 0.07, 0.045]);
    // Leg: hip, knee, ankle; foot.
    capsule(&mut left, [0.095, 0.93, 0.0], [0.12, 0.50, 0.01], 0.075);
    capsule(&mut left, [0.12, 0.50, 0.01], [0.13, 0.08, -0.01], 0.055);
    ellipsoid(&mut left, [0.13, 0.045, 0.05], [0.045, 0.045, 0.12]);
    for mirror in [false, true] {
        let base = s.vertices.len();
        s.vertices.extend(
            left.vertices
                .iter()
                .map(|&[x, y, z]| [if mirror { -x } else { x }, y, z]),
        );
        // Mirroring flips orientation: swap two corners to keep the winding outward.
        s.triangles.extend(left.triangles.iter().map(|&[a, b, c]| {
            if mirror {
                [base + a, base + c, base + b]
            } else {
                [base + a, base + b, base + c]
            }
        }));
    }
    s
}

/// Appends a closed latitude-longitude ellipsoid with the given centre and semi-axes.
fn ellipsoid(s: &mut Surface3, centre: [f64; 3], radii: [f64; 3]) {
    let big = radii.iter().copied().fold(0.0, f64::max);
    let segments = ((2.0 * PI * big / SPACING).ceil() as usize).max(12);
    let rings = ((PI * big / SPACING).ceil() as usize).max(6);
    lat_long(s, rings, segments, |theta, phi| {
        let (st, ct) = libm::sincos(theta);
        let (sp, cp) = libm::sincos(phi);
        [
            centre[0] + radii[0] * st * cp,
            centre[1] + radii[1] * ct,
            centre[2] + radii[2] * st * sp,
        ]
    });
}

/// Appends a closed capsule (cylinder with hemispherical caps) from `a` to `b` with `radius`.
fn capsule(s: &mut Surface3, a: [f64; 3], b: [f64; 3], radius: f64) {
    let axis = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let len = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let w = axis.map(|c| c / len);
    // Any unit vector orthogonal to w, then the third by a cross product.
    let helper = if w[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let u = normalise(cross(w, helper));
    let v = cross(w, u);
    let segments = ((2.0 * PI * radius / SPACING).ceil() as usize).max(12);
    // Parameter t runs over cap (pi/2 * r), body (len), cap (pi/2 * r).
    let cap = 0.5 * PI * radius;
    let total = 2.0 * cap + len;
    let rings = ((total / SPACING).ceil() as usize).max(6);
    lat_long(s, rings, segments, |theta, phi| {
        let t = theta / PI * total;
        // Position along the axis from `a`, and distance from the axis.
        let (along, r) = if t < cap {
            let alpha = t / radius;
            (-radius * libm::cos(alpha), radius * libm::sin(alpha))
        } else if t > cap + len {
            let alpha = (total - t) / radius;
            (len + radius * libm::cos(alpha), radius * libm::sin(alpha))
        } else {
            (t - cap, radius)
        };
        let (sp, cp) = libm::sincos(phi);
        let mut p = [0.0; 3];
        for k in 0..3 {
            p[k] = a[k] + w[k] * along + r * (u[k] * cp + v[k] * sp);
        }
        p
    });
}

/// Appends a closed surface parametrised by `theta` in [0, pi] (pole to pole) and `phi` in
/// [0, 2 pi): `rings` latitude steps, `segments` longitude steps, one vertex at each pole.
fn lat_long(s: &mut Surface3, rings: usize, segments: usize, point: impl Fn(f64, f64) -> [f64; 3]) {
    let base = s.vertices.len();
    s.vertices.push(point(0.0, 0.0));
    for i in 1..rings {
        let theta = PI * i as f64 / rings as f64;
        for j in 0..segments {
            // A quarter-step phase keeps phi and -phi (and pi - phi) off the sample set, so
            // the two halves of a ring project between each other instead of onto nearly the same
            // spots: the projected points stay evenly spread.
            let phi = 2.0 * PI * (j as f64 + 0.25) / segments as f64;
            s.vertices.push(point(theta, phi));
        }
    }
    s.vertices.push(point(PI, 0.0));
    let south = s.vertices.len() - 1;
    let at = |i: usize, j: usize| base + 1 + (i - 1) * segments + j % segments;
    for j in 0..segments {
        s.triangles.push([base, at(1, j + 1), at(1, j)]);
        s.triangles
            .push([south, at(rings - 1, j), at(rings - 1, j + 1)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            s.triangles.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            s.triangles.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalise(a: [f64; 3]) -> [f64; 3] {
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|c| c / n)
}
