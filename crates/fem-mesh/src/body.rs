//! A procedural human body and its skeleton, built in code from ellipsoids and capsules, in
//! metres, +Y up, +Z forward (toes and face), +X the body's left, soles of the standing foot at
//! y = 0. It lets the pipeline (and case D) run on a fresh machine without any model file.
//!
//! [`human_body`] is the skin: an adult of about 1.75 m (head, neck, chest, abdomen, pelvis,
//! arms, hands, legs with calves, feet). The arms hang mirror-symmetric, clear of the trunk. The
//! legs differ, so a side view shows two legs: the right leg stands straight, the left is bent,
//! flexed 65 degrees at the hip and 130 at the knee (lying on the back: the knee up and the
//! foot flat beside the other thigh, the hook-lying pose), and the silhouette stays one
//! connected region. The right shin, from the knee to the ankle, has nothing above it.
//!
//! [`human_skeleton`] gives the bones inside it, each made of closed convex parts (capsules and
//! ellipsoids) for [`crate::pipeline::mesh_surface_with_skeleton`]: `skull`, `spine` (a chain
//! of capsules along the back, neck to lumbar), `pelvis`, `femur`, `tibia`, `fibula` and
//! `humerus` (left and right parts under one name). The tibia is a shaft with a wider proximal
//! plateau, its anterior surface 13 mm under the shin's skin (the thin soft tissue of a real
//! shin); the fibula is a separate bone, lateral and clearly posterior to the tibia, so the two
//! are disjoint in side and front views. Every bone keeps at least 1 cm of soft tissue to the
//! skin in the side and front views, and bones of different names are disjoint in both.
//!
//! The surfaces are unions of closed, overlapping shells (one per part), not boolean unions: the
//! pipeline only needs the projected vertices.

use std::f64::consts::PI;

use crate::types::{Bone, Skeleton, Surface3};

/// Target vertex spacing on the part surfaces (metres): fine enough for an alpha radius of a
/// few centimetres.
const SPACING: f64 = 0.015;

/// Soft tissue between the tibia's anterior surface and the shin's skin (metres).
pub const SHIN_SOFT_TISSUE: f64 = 0.013;

/// Shoulder, elbow and wrist of the left arm (the right arm is its mirror image, x -> -x).
const SHOULDER: [f64; 3] = [0.19, 1.40, 0.0];
const ELBOW: [f64; 3] = [0.33, 1.12, 0.0];
const WRIST: [f64; 3] = [0.40, 0.90, 0.05];

/// One leg: hip, knee and ankle joints and which side (+1 left, -1 right).
#[derive(Clone, Copy)]
struct Leg {
    hip: [f64; 3],
    knee: [f64; 3],
    ankle: [f64; 3],
    side: f64,
}

/// Skin radius of the shank at the knee and at the ankle (metres).
const SHANK_RADII: [f64; 2] = [0.05, 0.04];

impl Leg {
    /// The right leg, straight (knee over ankle).
    fn right() -> Self {
        Self {
            hip: [-0.095, 0.90, 0.0],
            knee: [-0.10, 0.48, 0.01],
            ankle: [-0.105, 0.08, -0.01],
            side: -1.0,
        }
    }

    /// The left leg bent: thigh 0.42 m flexed 65 degrees forward, knee flexed 130 degrees, so
    /// the shank (0.40 m) slopes back 65 degrees from vertical and the ankle comes back to the
    /// plane of the right leg. Lying on the back, this is the hook-lying pose: the knee up,
    /// the foot flat beside the other thigh.
    fn left() -> Self {
        let (s65, c65) = libm::sincos(65f64.to_radians());
        let hip = [0.095, 0.90, 0.0];
        let knee = [0.10, hip[1] - 0.42 * c65, 0.42 * s65];
        let ankle = [0.105, knee[1] - 0.40 * c65, knee[2] - 0.40 * s65];
        Self {
            hip,
            knee,
            ankle,
            side: 1.0,
        }
    }

    /// The foot: centre and semi-axes of its ellipsoid. The straight leg's foot points
    /// forward (+Z); the bent leg's points down (-Y), its sole towards -Z, so that lying on
    /// the back both soles face the same way as the body.
    fn foot(&self) -> ([f64; 3], [f64; 3]) {
        let a = self.ankle;
        if self.side < 0.0 {
            (
                [a[0] - 0.005, a[1] - 0.035, a[2] + 0.06],
                [0.045, 0.045, 0.125],
            )
        } else {
            (
                [a[0] + 0.005, a[1] - 0.06, a[2] - 0.035],
                [0.045, 0.125, 0.045],
            )
        }
    }

    /// The shank's frame: unit axis (knee to ankle), anterior and lateral directions, length.
    fn shank_frame(&self) -> Frame {
        Frame::along(self.knee, self.ankle, self.side)
    }

    /// The thigh's frame (hip to knee).
    fn thigh_frame(&self) -> Frame {
        Frame::along(self.hip, self.knee, self.side)
    }

    /// Skin radius of the shank at distance `s` from the knee.
    fn shank_radius(&self, s: f64) -> f64 {
        let len = self.shank_frame().length;
        SHANK_RADII[0] + (SHANK_RADII[1] - SHANK_RADII[0]) * (s / len)
    }
}

/// A limb segment's local frame: `origin + s * axis + a * anterior + l * lateral`.
#[derive(Clone, Copy)]
struct Frame {
    origin: [f64; 3],
    axis: [f64; 3],
    anterior: [f64; 3],
    lateral: [f64; 3],
    length: f64,
}

impl Frame {
    /// The frame from `a` to `b`; anterior is +Z made orthogonal to the axis, lateral points
    /// to the body's `side` (+1 left, +X).
    fn along(a: [f64; 3], b: [f64; 3], side: f64) -> Self {
        let d = sub(b, a);
        let length = norm(d);
        let axis = d.map(|c| c / length);
        let z = [0.0, 0.0, 1.0];
        let along = dot(z, axis);
        let anterior = normalise(sub(z, axis.map(|c| c * along)));
        let mut lateral = cross(axis, anterior);
        if lateral[0] * side < 0.0 {
            lateral = lateral.map(|c| -c);
        }
        Self {
            origin: a,
            axis,
            anterior,
            lateral,
            length,
        }
    }

    /// The point at `s` along the axis, `a` anterior and `l` lateral.
    fn at(&self, s: f64, a: f64, l: f64) -> [f64; 3] {
        std::array::from_fn(|k| {
            self.origin[k] + s * self.axis[k] + a * self.anterior[k] + l * self.lateral[k]
        })
    }
}

/// Builds the body surface (the skin).
pub fn human_body() -> Surface3 {
    let mut s = Surface3::default();
    // Head, neck, trunk (chest, abdomen, pelvis).
    ellipsoid(&mut s, [0.0, 1.635, 0.01], [0.078, 0.115, 0.098]);
    capsule(&mut s, [0.0, 1.45, -0.01], [0.0, 1.56, 0.0], 0.055, 0.055);
    ellipsoid(&mut s, [0.0, 1.30, 0.0], [0.17, 0.20, 0.11]);
    ellipsoid(&mut s, [0.0, 1.09, 0.01], [0.15, 0.15, 0.11]);
    ellipsoid(&mut s, [0.0, 0.95, -0.01], [0.175, 0.12, 0.115]);
    // The arms: the left one, then its exact mirror image, so that mirror twins project to
    // bit-identical points in a side view and merge.
    let mut arm = Surface3::default();
    capsule(&mut arm, SHOULDER, ELBOW, 0.05, 0.04);
    capsule(&mut arm, ELBOW, WRIST, 0.038, 0.03);
    ellipsoid(&mut arm, [0.41, 0.82, 0.065], [0.025, 0.07, 0.045]);
    append(&mut s, &arm, false);
    append(&mut s, &arm, true);
    // The legs: thigh, shank, calf, foot.
    for leg in [Leg::right(), Leg::left()] {
        capsule(&mut s, leg.hip, leg.knee, 0.08, 0.055);
        capsule(&mut s, leg.knee, leg.ankle, SHANK_RADII[0], SHANK_RADII[1]);
        let f = leg.shank_frame();
        ellipsoid_in(
            &mut s,
            f.at(0.14, -0.03, 0.0),
            [f.axis, f.anterior, f.lateral],
            [0.13, 0.058, 0.05],
        );
        let (foot, radii) = leg.foot();
        ellipsoid(&mut s, foot, radii);
    }
    s
}

/// Builds the skeleton inside [`human_body`] (see the module docs for the bones and margins).
pub fn human_skeleton() -> Skeleton {
    let part = |build: &dyn Fn(&mut Surface3)| {
        let mut s = Surface3::default();
        build(&mut s);
        s
    };
    let skull = part(&|s| ellipsoid(s, [0.0, 1.645, 0.005], [0.058, 0.085, 0.075]));
    // Cervical, thoracic and lumbar spine: a chain along the back, its curves following the
    // neck and trunk.
    let spine_points: [[f64; 3]; 6] = [
        [0.0, 1.52, -0.02],
        [0.0, 1.42, -0.035],
        [0.0, 1.30, -0.06],
        [0.0, 1.18, -0.06],
        [0.0, 1.10, -0.045],
        [0.0, 1.06, -0.05],
    ];
    let spine = spine_points
        .windows(2)
        .map(|w| part(&|s| capsule(s, w[0], w[1], 0.012, 0.012)))
        .collect();
    let pelvis = part(&|s| ellipsoid(s, [0.0, 0.97, -0.015], [0.12, 0.055, 0.06]));
    let (mut femur, mut tibia, mut fibula) = (Vec::new(), Vec::new(), Vec::new());
    for leg in [Leg::right(), Leg::left()] {
        let t = leg.thigh_frame();
        femur.push(part(&|s| {
            capsule(
                s,
                t.at(0.03, 0.0, 0.0),
                // Short of the knee by 6 cm: room for the bent knee's tibial plateau.
                t.at(t.length - 0.06, 0.0, 0.0),
                0.014,
                0.014,
            )
        }));
        let f = leg.shank_frame();
        // Tibia: the shaft (25 mm thick) with its anterior surface SHIN_SOFT_TISSUE under the
        // skin all along, slightly medial; the plateau under the knee, wider.
        let (top, bottom) = (0.06, f.length - 0.06);
        let r = 0.0125;
        let anterior = |s: f64| leg.shank_radius(s) - SHIN_SOFT_TISSUE - r;
        tibia.push(part(&|s| {
            capsule(
                s,
                f.at(top, anterior(top), -0.006),
                f.at(bottom, anterior(bottom), -0.006),
                r,
                r,
            )
        }));
        tibia.push(part(&|s| {
            ellipsoid_in(
                s,
                f.at(0.035, 0.005, -0.006),
                [f.axis, f.anterior, f.lateral],
                [0.022, 0.028, 0.032],
            )
        }));
        // Fibula: thin, lateral and posterior, below the tibial plateau. The bent leg's shank
        // points almost along the front view's line of sight, so there its fibula starts lower
        // (its head would otherwise hide behind the plateau's outline).
        let head = if leg.side > 0.0 { 0.2 } else { 0.09 };
        fibula.push(part(&|s| {
            capsule(
                s,
                f.at(head, -0.02, 0.023),
                f.at(bottom, -0.02, 0.023),
                0.0065,
                0.0065,
            )
        }));
    }
    let mut humerus = Vec::new();
    let arm = Frame::along(SHOULDER, ELBOW, 1.0);
    let left_humerus = part(&|s| {
        capsule(
            s,
            arm.at(0.04, 0.0, 0.0),
            arm.at(arm.length - 0.03, 0.0, 0.0),
            0.012,
            0.012,
        )
    });
    for mirror in [false, true] {
        let mut h = Surface3::default();
        append(&mut h, &left_humerus, mirror);
        humerus.push(h);
    }
    let bone = |name: &str, parts: Vec<Surface3>| Bone {
        name: name.to_owned(),
        parts,
    };
    Skeleton {
        bones: vec![
            bone("skull", vec![skull]),
            bone("spine", spine),
            bone("pelvis", vec![pelvis]),
            bone("femur", femur),
            bone("tibia", tibia),
            bone("fibula", fibula),
            bone("humerus", humerus),
        ],
    }
}

/// Appends `part` to `s`, mirrored (x -> -x) when asked.
fn append(s: &mut Surface3, part: &Surface3, mirror: bool) {
    let base = s.vertices.len();
    s.vertices.extend(
        part.vertices
            .iter()
            .map(|&[x, y, z]| [if mirror { -x } else { x }, y, z]),
    );
    // Mirroring flips orientation: swap two corners to keep the winding outward.
    s.triangles.extend(part.triangles.iter().map(|&[a, b, c]| {
        if mirror {
            [base + a, base + c, base + b]
        } else {
            [base + a, base + b, base + c]
        }
    }));
}

/// Appends a closed latitude-longitude ellipsoid with the given centre and semi-axes along x,
/// y and z.
fn ellipsoid(s: &mut Surface3, centre: [f64; 3], radii: [f64; 3]) {
    let axes = [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]];
    ellipsoid_in(s, centre, axes, [radii[1], radii[2], radii[0]]);
}

/// Appends a closed ellipsoid with semi-axes `radii[k]` along the orthonormal `axes[k]`; the
/// poles lie on `axes[0]`.
fn ellipsoid_in(s: &mut Surface3, centre: [f64; 3], axes: [[f64; 3]; 3], radii: [f64; 3]) {
    let big = radii.iter().copied().fold(0.0, f64::max);
    let segments = ((2.0 * PI * big / SPACING).ceil() as usize).max(12);
    let rings = ((PI * big / SPACING).ceil() as usize).max(6);
    lat_long(s, rings, segments, |theta, phi| {
        let (st, ct) = libm::sincos(theta);
        let (sp, cp) = libm::sincos(phi);
        let local = [radii[0] * ct, radii[1] * st * sp, radii[2] * st * cp];
        let mut p = centre;
        for (k, axis) in axes.iter().enumerate() {
            for c in 0..3 {
                p[c] += local[k] * axis[c];
            }
        }
        p
    });
}

/// Appends a closed capsule from `a` (radius `ra`) to `b` (radius `rb`): a cone frustum with
/// hemispherical caps. Convex when `ra == rb`; the skin's tapered limbs only need to be closed.
fn capsule(s: &mut Surface3, a: [f64; 3], b: [f64; 3], ra: f64, rb: f64) {
    let axis = sub(b, a);
    let len = norm(axis);
    let w = axis.map(|c| c / len);
    // Any unit vector orthogonal to w, then the third by a cross product.
    let helper = if w[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let u = normalise(cross(w, helper));
    let v = cross(w, u);
    let segments = ((2.0 * PI * ra.max(rb) / SPACING).ceil() as usize).max(12);
    // Parameter t runs over cap (pi/2 * ra), body (len), cap (pi/2 * rb).
    let (cap_a, cap_b) = (0.5 * PI * ra, 0.5 * PI * rb);
    let total = cap_a + len + cap_b;
    let rings = ((total / SPACING).ceil() as usize).max(6);
    lat_long(s, rings, segments, |theta, phi| {
        let t = theta / PI * total;
        // Position along the axis from `a`, and distance from the axis.
        let (along, r) = if t < cap_a {
            let alpha = t / ra;
            (-ra * libm::cos(alpha), ra * libm::sin(alpha))
        } else if t > cap_a + len {
            let alpha = (total - t) / rb;
            (len + rb * libm::cos(alpha), rb * libm::sin(alpha))
        } else {
            let f = (t - cap_a) / len;
            (t - cap_a, ra + (rb - ra) * f)
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
    let n = norm(a);
    a.map(|c| c / n)
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
