//! Rigid regions: parts of the body (bones) that move as rigid bodies with the soft tissue
//! attached.
//!
//! Each connected component of the rigid triangles (two triangles connect when they share a
//! vertex) is one [`RigidBody`] with three degrees of freedom: its centroid and an angle. Every
//! vertex of its triangles is *slaved* to it, `x_v = p + R(theta) r_v` with `r_v` the vertex's
//! rest offset from the rest centroid; the vertices it shares with soft triangles (the
//! interface) carry the soft tissue's forces to it, and through them the tissue pushes and
//! turns the body (two-way coupling). A rigid triangle has no elastic energy and no stress: the
//! model's elastic mesh leaves it out.
//!
//! Mass and inertia are integrated exactly over the rigid triangles with their region's
//! density; the share of the soft triangles' mass that the lumped masses put on the interface
//! vertices moves with the body too, as point masses. So the body weighs exactly what its
//! vertices' lumped masses add up to, and its centroid is their mass centre (a triangle's
//! lumped corners have its centroid), which makes gravity's torque about it zero.
//!
//! A body is free, or kinematic: when one of its vertices is pinned the whole body is pinned,
//! else when one is moved by a prescribed motion the whole body follows that motion (a limb
//! held by a fixture). [`BodyState`] (shared with dynamic obstacles) holds its pose and
//! velocity; [`BodyState::advance`] is the symplectic Euler step both use in the explicit
//! solver.

use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;

use super::{BodyState, Frame, cross};

/// How a rigid region's body moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BodyMotion {
    /// Moved by the forces on it (the tissue's, gravity, contact): three unknowns.
    Free,
    /// Held still: one of its vertices is pinned.
    Pinned,
    /// Translated by the prescribed motion with this index (one of its vertices is in its
    /// region).
    Scheduled(u32),
}

/// One rigid body of the rigid regions (see the [module docs](self)).
#[derive(Clone, Debug, PartialEq)]
pub struct RigidBody {
    /// Mass, kg per unit thickness.
    pub mass: Real,
    /// Rotational inertia about the centroid, kg m^2 per unit thickness.
    pub inertia: Real,
    /// Rest centroid (the mass centre), m.
    pub centroid: Vec2,
    /// The region tag of its triangles (the first one's, when it spans several).
    pub region: u32,
    /// Its triangles, increasing.
    pub triangles: Vec<u32>,
    /// Its vertices, increasing.
    pub vertices: Vec<u32>,
    /// Each vertex's rest offset from the rest centroid, m.
    pub offsets: Vec<Vec2>,
    /// Its vertices that soft triangles use too (the interface), increasing.
    pub interface: Vec<u32>,
    /// How it moves (from the boundary conditions on its vertices).
    pub motion: BodyMotion,
}

impl RigidBody {
    /// At rest at its rest pose.
    pub fn initial_state(&self) -> BodyState {
        BodyState {
            position: self.centroid,
            angle: 0.0,
            velocity: Vec2::zeros(),
            angular_velocity: 0.0,
        }
    }

    /// Whether the body's pose is an unknown (not pinned or scheduled).
    pub fn is_free(&self) -> bool {
        self.motion == BodyMotion::Free
    }

    /// `(1 / mass, 1 / inertia)`.
    pub fn inverse_mass(&self) -> (Real, Real) {
        (1.0 / self.mass, 1.0 / self.inertia)
    }

    /// Write the positions and velocities of the body's vertices at pose `b`.
    pub fn place(&self, b: &BodyState, x: &mut [Vec2], v: &mut [Vec2]) {
        let frame = Frame::of(b);
        for (&i, &r) in self.vertices.iter().zip(&self.offsets) {
            let p = frame.apply(r);
            x[i as usize] = p;
            v[i as usize] = b.point_velocity(p);
        }
    }

    /// Write the positions of the body's vertices at pose `b`.
    pub fn place_positions(&self, b: &BodyState, x: &mut [Vec2]) {
        let frame = Frame::of(b);
        for (&i, &r) in self.vertices.iter().zip(&self.offsets) {
            x[i as usize] = frame.apply(r);
        }
    }

    /// Net force and torque (about the centroid `b.position`) of the nodal forces `f` on the
    /// body's vertices at positions `x`.
    pub fn wrench(&self, b: &BodyState, x: &[Vec2], f: &[Vec2]) -> (Vec2, Real) {
        let mut force = Vec2::zeros();
        let mut torque = 0.0;
        for &i in &self.vertices {
            let fi = f[i as usize];
            force += fi;
            torque += cross(x[i as usize] - b.position, fi);
        }
        (force, torque)
    }

    /// The generalised inverse mass of the body at world point `p` in direction `n` (unit):
    /// `1/m + (r x n)^2 / I` with `r = p - centroid` (Mueller et al. 2020, Eq. 2-3).
    #[inline]
    pub fn generalised_inverse_mass(&self, b: &BodyState, p: Vec2, n: Vec2) -> Real {
        let rn = cross(p - b.position, n);
        1.0 / self.mass + rn * rn / self.inertia
    }
}

impl BodyState {
    /// One step of a rigid body under net force `force` (gravity excluded), torque `torque`,
    /// gravity `g` and inverse masses `(im, ii)`: the velocities gain `dt (force im + g)` and
    /// `dt torque ii`, then are scaled by `decay`; the pose moves with the new velocities
    /// (symplectic Euler) or the old ones (`symplectic == false`, forward Euler). Dynamic
    /// obstacles and rigid regions share it.
    #[allow(clippy::too_many_arguments)]
    pub fn advance(
        &mut self,
        (im, ii): (Real, Real),
        force: Vec2,
        torque: Real,
        g: Vec2,
        dt: Real,
        decay: Real,
        symplectic: bool,
    ) {
        let (v_old, om_old) = (self.velocity, self.angular_velocity);
        self.velocity = (self.velocity + (force * im + g) * dt) * decay;
        self.angular_velocity = (self.angular_velocity + torque * ii * dt) * decay;
        let (v, om) = if symplectic {
            (self.velocity, self.angular_velocity)
        } else {
            (v_old, om_old)
        };
        self.position += v * dt;
        self.angle += om * dt;
    }
}

/// The rigid bodies of a mesh whose triangles `rigid` selects, with `density[t]` the density
/// (kg/m^3) of triangle `t` and `masses` the lumped vertex masses. Returns the bodies (in
/// order of their first triangle) and, per vertex, the body it is slaved to (`u32::MAX`:
/// none).
pub(crate) fn build_bodies(
    mesh: &Mesh,
    rigid: &[bool],
    density: impl Fn(usize) -> Real,
    tags: &[u32],
    masses: &[Real],
) -> (Vec<RigidBody>, Vec<u32>) {
    let n = mesh.n_vertices();
    let tris = mesh.triangles();
    // Union-find over vertices, joining the corners of every rigid triangle.
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut a: u32) -> u32 {
        while parent[a as usize] != a {
            parent[a as usize] = parent[parent[a as usize] as usize];
            a = parent[a as usize];
        }
        a
    }
    for (t, tri) in tris.iter().enumerate() {
        if rigid[t] {
            for k in 1..3 {
                let (a, b) = (find(&mut parent, tri[0]), find(&mut parent, tri[k]));
                if a != b {
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
    }
    let mut body_of_root = vec![u32::MAX; n];
    let mut slave = vec![u32::MAX; n];
    let mut groups: Vec<Vec<u32>> = Vec::new();
    for (t, tri) in tris.iter().enumerate() {
        if !rigid[t] {
            continue;
        }
        let root = find(&mut parent, tri[0]) as usize;
        if body_of_root[root] == u32::MAX {
            body_of_root[root] = groups.len() as u32;
            groups.push(Vec::new());
        }
        let b = body_of_root[root];
        groups[b as usize].push(t as u32);
        for &v in tri {
            slave[v as usize] = b;
        }
    }
    let mut soft_user = vec![false; n];
    for (t, tri) in tris.iter().enumerate() {
        if !rigid[t] {
            for &v in tri {
                soft_user[v as usize] = true;
            }
        }
    }
    let x0 = mesh.vertices();
    let bodies = groups
        .into_iter()
        .enumerate()
        .map(|(b, triangles)| {
            let mut vertices: Vec<u32> = (0..n as u32)
                .filter(|&v| slave[v as usize] == b as u32)
                .collect();
            vertices.sort_unstable();
            // The rigid triangles' own share of each vertex's lumped mass.
            let mut own = vec![0.0; vertices.len()];
            let (mut m_tri, mut first) = (0.0, Vec2::zeros());
            for &t in &triangles {
                let m = density(t as usize) * mesh.elements()[t as usize].area;
                m_tri += m;
                let c: Vec2 = tris[t as usize].iter().map(|&v| x0[v as usize]).sum();
                first += c * (m / 3.0);
                for &v in &tris[t as usize] {
                    let k = vertices.binary_search(&v).expect("corner of the body");
                    own[k] += m / 3.0;
                }
            }
            // The soft triangles' share on the interface vertices: point masses.
            let soft: Vec<Real> = (vertices.iter().zip(&own))
                .map(|(&v, o)| (masses[v as usize] - o).max(0.0))
                .collect();
            let mass = m_tri + soft.iter().sum::<Real>();
            let centroid = (first
                + (vertices.iter().zip(&soft))
                    .map(|(&v, m)| x0[v as usize] * *m)
                    .sum::<Vec2>())
                / mass;
            // Exact polar moment of each triangle about the centroid:
            // rho A / 6 (|a|^2 + |b|^2 + |c|^2 + a.b + b.c + c.a), corners relative to it.
            let mut inertia = 0.0;
            for &t in &triangles {
                let m = density(t as usize) * mesh.elements()[t as usize].area;
                let [a, b, c] = tris[t as usize].map(|v| x0[v as usize] - centroid);
                inertia += m / 6.0
                    * (a.norm_squared()
                        + b.norm_squared()
                        + c.norm_squared()
                        + a.dot(&b)
                        + b.dot(&c)
                        + c.dot(&a));
            }
            for (&v, m) in vertices.iter().zip(&soft) {
                inertia += m * (x0[v as usize] - centroid).norm_squared();
            }
            let offsets = vertices
                .iter()
                .map(|&v| x0[v as usize] - centroid)
                .collect();
            let interface = vertices
                .iter()
                .copied()
                .filter(|&v| soft_user[v as usize])
                .collect();
            RigidBody {
                mass,
                inertia,
                centroid,
                region: tags.get(triangles[0] as usize).copied().unwrap_or(0),
                triangles,
                vertices,
                offsets,
                interface,
                motion: BodyMotion::Free,
            }
        })
        .collect();
    (bodies, slave)
}

#[cfg(test)]
mod tests {
    use super::*;
    use fem_core::math::sin_cos;

    fn rotate(angle: Real, r: Vec2) -> Vec2 {
        let (s, c) = sin_cos(angle);
        Vec2::new(c * r.x - s * r.y, s * r.x + c * r.y)
    }

    /// A unit square of two triangles plus a soft triangle on its right side.
    fn square_with_tail() -> Mesh {
        let v = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(2.0, 0.5),
        ];
        Mesh::new(v, vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]]).unwrap()
    }

    #[test]
    fn mass_and_inertia_of_a_square_are_exact() {
        let mesh = square_with_tail();
        let rho = [2.0, 2.0, 3.0];
        let masses = mesh.lumped_masses_from_densities(&rho).unwrap();
        let (bodies, slave) =
            build_bodies(&mesh, &[true, true, false], |t| rho[t], &[1, 1, 0], &masses);
        assert_eq!(bodies.len(), 1);
        assert_eq!(slave, vec![0, 0, 0, 0, u32::MAX]);
        let b = &bodies[0];
        assert_eq!(b.interface, vec![1, 2]);
        // The soft triangle (area 0.5, density 3) puts 0.5 kg on each of its corners.
        let soft = 0.5;
        assert!((b.mass - (2.0 + 2.0 * soft)).abs() < 1e-14);
        let total: Real = b.vertices.iter().map(|&v| masses[v as usize]).sum();
        assert!((b.mass - total).abs() < 1e-14, "weighs its lumped masses");
        let c = Vec2::new((2.0 * 0.5 + soft * 2.0) / 3.0, 0.5);
        assert!((b.centroid - c).norm() < 1e-14);
        // Square of side 1 and mass 2 about its own centre: 2 (1 + 1) / 12, shifted to c;
        // the point masses at (1, 0) and (1, 1) add their own.
        let shift = (Vec2::new(0.5, 0.5) - c).norm_squared();
        let expect = 2.0 * 2.0 / 12.0
            + 2.0 * shift
            + soft * (Vec2::new(1.0, 0.0) - c).norm_squared()
            + soft * (Vec2::new(1.0, 1.0) - c).norm_squared();
        assert!(
            (b.inertia - expect).abs() < 1e-14,
            "{} {}",
            b.inertia,
            expect
        );
    }

    #[test]
    fn place_moves_vertices_rigidly_and_the_wrench_sums_forces() {
        let mesh = square_with_tail();
        let masses = mesh.lumped_masses_from_density(1.0).unwrap();
        let (bodies, _) = build_bodies(&mesh, &[true, true, false], |_| 1.0, &[1, 1, 0], &masses);
        let b = &bodies[0];
        let mut s = b.initial_state();
        s.angle = 0.3;
        s.angular_velocity = 2.0;
        s.velocity = Vec2::new(1.0, -1.0);
        let mut x = mesh.vertices().to_vec();
        let mut v = vec![Vec2::zeros(); 5];
        b.place(&s, &mut x, &mut v);
        for i in 0..4 {
            for j in 0..4 {
                let d0 = (mesh.vertices()[i] - mesh.vertices()[j]).norm();
                assert!(((x[i] - x[j]).norm() - d0).abs() < 1e-14);
            }
            assert!((x[i] - (s.position + rotate(0.3, b.offsets[i]))).norm() < 1e-14);
        }
        assert_eq!(x[4], mesh.vertices()[4], "the soft vertex is not moved");
        let mut f = vec![Vec2::zeros(); 5];
        f[1] = Vec2::new(0.0, 1.0);
        f[4] = Vec2::new(5.0, 5.0);
        let (force, torque) = b.wrench(&s, &x, &f);
        assert_eq!(force, Vec2::new(0.0, 1.0));
        assert!((torque - cross(x[1] - s.position, f[1])).abs() < 1e-15);
        let n = Vec2::new(0.0, 1.0);
        let w = b.generalised_inverse_mass(&s, x[1], n);
        let rn = cross(x[1] - s.position, n);
        assert!((w - (1.0 / b.mass + rn * rn / b.inertia)).abs() < 1e-15);
    }
}
