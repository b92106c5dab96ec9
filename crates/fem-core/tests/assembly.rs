//! Mesh-level checks of assembly: forces against finite differences of the total energy,
//! stiffness against finite differences of the forces, the patch test, and the parallel paths
//! against the serial reference, bit for bit, for 1, 2 and 4 threads.

mod common;

use common::{Diagonal, Rng, deformed, rectangle};
use fem_core::assembly::{
    AssemblyReport, Scratch, Stiffness, Tangent, elastic_energy, elastic_energy_serial,
    populate_forces, populate_forces_serial, populate_stiffness, populate_stiffness_serial,
};
use fem_core::energy::{AnyEnergy, Energy, EnergyKind};
use fem_core::fd::{FdOptions, check_gradient, check_jacobian};
use fem_core::material::{Material, PlaneModel};
use fem_core::math::{Mat2, Real, Vec2};
use fem_core::mesh::Mesh;
use fem_core::{Lame, dispatch_energy};

/// See `energy_battery.rs` for why 1e-7 separates right from wrong derivatives.
const FD_TOL: Real = 1e-7;

fn lame() -> Lame {
    Material::new(1000.0, 0.3, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain)
}

fn energies() -> Vec<AnyEnergy> {
    EnergyKind::ALL
        .iter()
        .map(|k| k.build(lame()).unwrap())
        .collect()
}

fn flatten(x: &[Vec2]) -> Vec<Real> {
    x.iter().flat_map(|p| [p.x, p.y]).collect()
}

fn unflatten(v: &[Real]) -> Vec<Vec2> {
    v.chunks(2).map(|c| Vec2::new(c[0], c[1])).collect()
}

fn small_mesh() -> Mesh {
    rectangle(2.0, 1.0, 4, 2, Diagonal::Alternating)
}

#[test]
fn forces_are_minus_the_fd_gradient_of_the_energy() {
    let mesh = small_mesh();
    let x = deformed(&mesh, &mut Rng::new(7), 0.2);
    for energy in energies() {
        let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
        dispatch_energy!(&energy, e => populate_forces_serial(&mesh, e, &x, &mut f));
        let minus_f: Vec<Real> = flatten(&f).iter().map(|v| -v).collect();
        let r = check_gradient(
            |v| elastic_energy_serial(&mesh, &energy, &unflatten(v)),
            &flatten(&x),
            &minus_f,
            &FdOptions::default(),
        );
        assert!(
            r.relative_error < FD_TOL,
            "{}: assembled forces differ from -dE/dx: relative error {:e}",
            energy.name(),
            r.relative_error
        );
    }
}

#[test]
fn stiffness_is_minus_the_fd_jacobian_of_the_forces() {
    let mesh = small_mesh();
    let x = deformed(&mesh, &mut Rng::new(8), 0.2);
    let n = 2 * mesh.n_vertices();
    for energy in energies() {
        let mut k = Stiffness::new(&mesh);
        populate_stiffness_serial(&mesh, &energy, &x, Tangent::Exact, &mut k);
        let mut dense = vec![0.0; n * n];
        for (r, c, v) in k.matrix.triplets() {
            dense[r * n + c] = v;
        }
        let r = check_jacobian(
            |v| {
                let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
                populate_forces_serial(&mesh, &energy, &unflatten(v), &mut f);
                flatten(&f).iter().map(|v| -v).collect()
            },
            &flatten(&x),
            &dense,
            &FdOptions::default(),
        );
        assert!(
            r.relative_error < FD_TOL,
            "{}: stiffness differs from -df/dx: relative error {:e}",
            energy.name(),
            r.relative_error
        );
        // Symmetric, as a Hessian must be.
        for (r, c, v) in k.matrix.triplets() {
            let t = k.matrix.get(c, r);
            assert!(
                (v - t).abs() <= 1e-10 * v.abs().max(1.0),
                "{}: K not symmetric",
                energy.name()
            );
        }
    }
}

#[test]
fn projected_stiffness_is_positive_semidefinite() {
    let mesh = small_mesh();
    // A strongly compressed state, where StVK and co-rotational have indefinite tangents.
    let x: Vec<Vec2> = mesh
        .vertices()
        .iter()
        .map(|p| Vec2::new(0.45 * p.x, 1.1 * p.y))
        .collect();
    let n = 2 * mesh.n_vertices();
    let mut rng = Rng::new(9);
    for energy in energies() {
        let mut k = Stiffness::new(&mesh);
        populate_stiffness_serial(&mesh, &energy, &x, Tangent::Projected, &mut k);
        for _ in 0..50 {
            let v: Vec<Real> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let mut kv = vec![0.0; n];
            k.matrix.mul_vec(&v, &mut kv);
            let q: Real = v.iter().zip(&kv).map(|(a, b)| a * b).sum();
            assert!(q >= -1e-9, "{}: v^T K v = {q} < 0", energy.name());
        }
    }
}

/// Patch test: under an affine map every element has the same F, and the elastic force on every
/// interior node cancels (equilibrium of a homogeneous stress), on a mesh with irregular
/// interior nodes.
#[test]
fn patch_test_affine_deformation_gives_uniform_f_and_zero_interior_force() {
    let mut rng = Rng::new(10);
    let base = rectangle(3.0, 2.0, 6, 4, Diagonal::Alternating);
    // Jitter interior nodes so the patch is irregular.
    let vertices: Vec<Vec2> = base
        .vertices()
        .iter()
        .map(|p| {
            let interior = p.x > 1e-9 && p.x < 3.0 - 1e-9 && p.y > 1e-9 && p.y < 2.0 - 1e-9;
            if interior {
                p + Vec2::new(rng.uniform(-0.12, 0.12), rng.uniform(-0.12, 0.12))
            } else {
                *p
            }
        })
        .collect();
    let mesh = Mesh::new(vertices, base.triangles().to_vec()).unwrap();
    let a = Mat2::new(1.25, 0.3, -0.15, 0.85);
    let x: Vec<Vec2> = mesh
        .vertices()
        .iter()
        .map(|p| a * p + Vec2::new(0.4, -2.0))
        .collect();
    for (t, el) in mesh.elements().iter().enumerate() {
        let f = el.deformation_gradient(mesh.gather(t, &x));
        assert!((f - a).norm() < 1e-13, "element {t}: F = {f:?}");
    }
    for energy in energies() {
        let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
        populate_forces_serial(&mesh, &energy, &x, &mut f);
        let scale = energy.pk1(&a).norm() * 3.0; // |P| times a boundary length
        let mut boundary_total = Vec2::zeros();
        for (v, p) in mesh.vertices().iter().enumerate() {
            let interior = p.x > 1e-9 && p.x < 3.0 - 1e-9 && p.y > 1e-9 && p.y < 2.0 - 1e-9;
            if interior {
                assert!(
                    f[v].norm() < 1e-12 * scale,
                    "{}: interior node {v} feels {:?}",
                    energy.name(),
                    f[v]
                );
            } else {
                boundary_total += f[v];
            }
        }
        // Boundary forces are the traction P N integrated on each edge; they sum to zero.
        assert!(
            boundary_total.norm() < 1e-12 * scale,
            "{}: net force",
            energy.name()
        );
        // And on the right edge (N = +x, length 2) they sum to -(P N) * 2... with the sign of
        // an internal force: the body pulls the edge back.
        let right: Vec2 = mesh
            .vertices()
            .iter()
            .zip(&f)
            .filter(|(p, _)| p.x > 3.0 - 1e-9)
            .map(|(_, f)| *f)
            .sum();
        let traction = energy.pk1(&a) * Vec2::new(1.0, 0.0) * 2.0;
        assert!(
            (right + traction).norm() < 1e-11 * scale,
            "{}: right-edge force {right:?} vs traction {traction:?}",
            energy.name()
        );
    }
}

fn with_threads<T: Send>(n: usize, job: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
        .install(job)
}

fn bits(v: &[Vec2]) -> Vec<u64> {
    v.iter()
        .flat_map(|p| [p.x.to_bits(), p.y.to_bits()])
        .collect()
}

/// Parallel assembly equals the serial reference bit for bit with 1, 2 and 4 threads, on a
/// mesh large enough to span many parallel chunks.
#[test]
fn parallel_assembly_is_bit_identical_to_serial_for_1_2_4_threads() {
    let mesh = rectangle(5.0, 1.0, 120, 24, Diagonal::Alternating); // 5760 triangles
    let x = deformed(&mesh, &mut Rng::new(11), 0.3);
    for energy in energies() {
        let mut f_ref = vec![Vec2::zeros(); mesh.n_vertices()];
        let rep_ref = populate_forces_serial(&mesh, &energy, &x, &mut f_ref);
        let e_ref = elastic_energy_serial(&mesh, &energy, &x);
        let mut k_ref = Stiffness::new(&mesh);
        populate_stiffness_serial(&mesh, &energy, &x, Tangent::Projected, &mut k_ref);
        for threads in [1, 2, 4] {
            let (f, rep, e, k) = with_threads(threads, || {
                let mut scratch = Scratch::new();
                let mut f = vec![Vec2::new(9.0, 9.0); mesh.n_vertices()];
                let rep: AssemblyReport = populate_forces(&mesh, &energy, &x, &mut f, &mut scratch);
                let e = elastic_energy(&mesh, &energy, &x, &mut scratch);
                let mut k = Stiffness::new(&mesh);
                populate_stiffness(&mesh, &energy, &x, Tangent::Projected, &mut k, &mut scratch);
                (f, rep, e, k)
            });
            let name = energy.name();
            assert_eq!(
                bits(&f),
                bits(&f_ref),
                "{name}: forces differ with {threads} threads"
            );
            assert_eq!(
                rep, rep_ref,
                "{name}: report differs with {threads} threads"
            );
            assert_eq!(
                e.to_bits(),
                e_ref.to_bits(),
                "{name}: energy differs with {threads} threads"
            );
            let kb: Vec<u64> = k.matrix.values.iter().map(|v| v.to_bits()).collect();
            let kb_ref: Vec<u64> = k_ref.matrix.values.iter().map(|v| v.to_bits()).collect();
            assert!(
                kb == kb_ref,
                "{name}: stiffness differs with {threads} threads"
            );
        }
    }
}

/// The assembly report counts inverted elements and the smallest det F.
#[test]
fn report_counts_inverted_elements() {
    let mesh = small_mesh();
    let mut x = mesh.vertices().to_vec();
    // Push the middle bottom vertex far up through its neighbours.
    let v = mesh
        .vertices()
        .iter()
        .position(|p| (p.x - 1.0).abs() < 1e-12 && p.y.abs() < 1e-12)
        .unwrap();
    x[v].y = 2.0;
    let energy = EnergyKind::StableNeoHookean.build(lame()).unwrap();
    let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
    let rep = populate_forces_serial(&mesh, &energy, &x, &mut f);
    let expected = mesh
        .elements()
        .iter()
        .enumerate()
        .filter(|(t, el)| el.deformation_gradient(mesh.gather(*t, &x)).determinant() <= 0.0)
        .count();
    assert!(expected > 0);
    assert_eq!(rep.inverted, expected);
    assert!(rep.min_det_f < 0.0);
}

/// A randomly renumbered mesh (vertices and triangles shuffled) defeats the chunk ownership, so
/// most vertices go through the shared-slot path: still bit-identical to the serial loop.
#[test]
fn parallel_forces_on_a_shuffled_mesh_are_bit_identical_to_serial() {
    let base = rectangle(5.0, 1.0, 60, 40, Diagonal::Alternating); // 4800 triangles, 3 chunks
    let mut rng = Rng::new(12);
    let n = base.n_vertices();
    let mut perm: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        perm.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    let mut vertices = vec![Vec2::zeros(); n];
    for (old, &new) in perm.iter().enumerate() {
        vertices[new] = base.vertices()[old];
    }
    let mut triangles: Vec<[u32; 3]> = base
        .triangles()
        .iter()
        .map(|t| t.map(|v| perm[v as usize] as u32))
        .collect();
    for i in (1..triangles.len()).rev() {
        triangles.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    let mesh = Mesh::new(vertices, triangles).unwrap();
    assert!(mesh.scatter_plan().shared_fraction(n) > 0.5);
    let x = deformed(&mesh, &mut rng, 0.3);
    let energy = EnergyKind::Corotational.build(lame()).unwrap();
    let mut f_ref = vec![Vec2::zeros(); n];
    populate_forces_serial(&mesh, &energy, &x, &mut f_ref);
    for threads in [2, 4] {
        let f = with_threads(threads, || {
            let mut f = vec![Vec2::new(7.0, 7.0); n];
            populate_forces(&mesh, &energy, &x, &mut f, &mut Scratch::new());
            f
        });
        assert_eq!(
            bits(&f),
            bits(&f_ref),
            "forces differ with {threads} threads"
        );
    }
}
