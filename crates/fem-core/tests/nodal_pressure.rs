//! The averaged nodal pressure triangle (`fem_core::nodal_pressure`) against its oracles:
//! forces against finite differences of its energy, its stiffness against finite differences of
//! its forces (with the wider stencil), the projected stiffness positive semi-definite, the patch
//! test (a uniform deformation gives the plain triangle's energy, forces and stress), the rest
//! state, two materials (nodes per region), and 1/2/4-thread bit identity.

mod common;

use common::{Diagonal, Rng, deformed, rectangle};
use fem_core::assembly::{
    Scratch, Stiffness, Tangent, elastic_energy, elastic_energy_serial, populate_forces,
    populate_forces_serial, populate_stiffness, populate_stiffness_serial,
};
use fem_core::energy::{AnyEnergy, ElementEnergies, EnergyKind};
use fem_core::fd::{FdOptions, check_gradient, check_jacobian};
use fem_core::material::{Material, PlaneModel};
use fem_core::math::{Mat2, Real, Vec2};
use fem_core::mesh::Mesh;
use fem_core::nodal_pressure::NodalPressure;
use fem_core::stress::{ElementStress, VonMisesFormula, populate_element_stress};

/// See `energy_battery.rs` for why 1e-7 separates right from wrong derivatives.
const FD_TOL: Real = 1e-7;

fn energy(kind: EnergyKind, youngs: Real, nu: Real) -> AnyEnergy {
    let lame = Material::new(youngs, nu, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    kind.build(lame).unwrap()
}

/// Two regions (a stiffer band in the middle columns), nearly incompressible, with the
/// formulation on `mesh`.
fn averaged(kind: EnergyKind, mesh: &Mesh, nu: Real) -> ElementEnergies<AnyEnergy> {
    let tags: Vec<u32> = (0..mesh.n_triangles())
        .map(|t| {
            let c = mesh.gather(t, mesh.vertices());
            let x = (c[0].x + c[1].x + c[2].x) / 3.0;
            u32::from((0.8..1.2).contains(&x))
        })
        .collect();
    ElementEnergies::new(
        vec![energy(kind, 1000.0, nu), energy(kind, 5000.0, 0.3)],
        tags,
    )
    .unwrap()
    .with_nodal_pressure(mesh)
    .unwrap()
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
fn nodes_are_vertex_region_pairs_with_a_third_of_their_triangles_area() {
    let mesh = small_mesh();
    let e = averaged(EnergyKind::NeoHookean, &mesh, 0.49);
    let np = fem_core::energy::EnergyOf::nodal_pressure(&e).unwrap();
    // Interface vertices (x = 1.0 has both regions around it) get two nodes.
    let interface = mesh
        .vertices()
        .iter()
        .filter(|p| {
            (p.x - 1.0).abs() < 1e-12 || (p.x - 0.5).abs() < 1e-12 || (p.x - 1.5).abs() < 1e-12
        })
        .count();
    assert!(np.n_nodes() > mesh.n_vertices() && np.n_nodes() <= mesh.n_vertices() + interface);
    let total: Real = (0..np.n_nodes()).map(|n| np.volume(n)).sum();
    assert!((total - mesh.area()).abs() < 1e-12 * mesh.area());
}

#[test]
fn forces_are_minus_the_fd_gradient_of_the_energy() {
    let mesh = small_mesh();
    let x = deformed(&mesh, &mut Rng::new(17), 0.15);
    for kind in EnergyKind::ALL {
        let e = averaged(kind, &mesh, 0.45);
        let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
        populate_forces_serial(&mesh, &e, &x, &mut f);
        let minus_f: Vec<Real> = flatten(&f).iter().map(|v| -v).collect();
        let r = check_gradient(
            |v| elastic_energy_serial(&mesh, &e, &unflatten(v)),
            &flatten(&x),
            &minus_f,
            &FdOptions::default(),
        );
        assert!(
            r.relative_error < FD_TOL,
            "{kind:?}: forces differ from -dE/dx: relative error {:e}",
            r.relative_error
        );
        // And they differ from the plain triangle's (the test would pass on a no-op otherwise).
        let mut plain = vec![Vec2::zeros(); mesh.n_vertices()];
        populate_forces_serial(&mesh, &e.clone().without_nodal_pressure(), &x, &mut plain);
        let diff: Real = f.iter().zip(&plain).map(|(a, b)| (a - b).norm()).sum();
        assert!(
            diff > 1e-3 * f.iter().map(|a| a.norm()).sum::<Real>(),
            "{kind:?}"
        );
    }
}

#[test]
fn stiffness_is_minus_the_fd_jacobian_of_the_forces_on_the_wider_stencil() {
    let mesh = small_mesh();
    let x = deformed(&mesh, &mut Rng::new(18), 0.15);
    let n = 2 * mesh.n_vertices();
    for kind in EnergyKind::ALL {
        let e = averaged(kind, &mesh, 0.45);
        let mut k = Stiffness::for_energy(&mesh, &e);
        assert!(k.matrix.col_indices.len() > Stiffness::new(&mesh).matrix.col_indices.len());
        populate_stiffness_serial(&mesh, &e, &x, Tangent::Exact, &mut k);
        let mut dense = vec![0.0; n * n];
        for (r, c, v) in k.matrix.triplets() {
            dense[r * n + c] = v;
        }
        let r = check_jacobian(
            |v| {
                let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
                populate_forces_serial(&mesh, &e, &unflatten(v), &mut f);
                flatten(&f).iter().map(|v| -v).collect()
            },
            &flatten(&x),
            &dense,
            &FdOptions::default(),
        );
        assert!(
            r.relative_error < FD_TOL,
            "{kind:?}: stiffness differs from -df/dx: relative error {:e}",
            r.relative_error
        );
        for (r, c, v) in k.matrix.triplets() {
            let t = k.matrix.get(c, r);
            assert!(
                (v - t).abs() <= 1e-10 * v.abs().max(1.0),
                "{kind:?}: K not symmetric"
            );
        }
    }
}

#[test]
fn projected_stiffness_is_positive_semidefinite() {
    let mesh = small_mesh();
    let x: Vec<Vec2> = mesh
        .vertices()
        .iter()
        .map(|p| Vec2::new(0.55 * p.x + 0.1 * p.y * p.y, 1.2 * p.y))
        .collect();
    let n = 2 * mesh.n_vertices();
    let mut rng = Rng::new(19);
    for kind in EnergyKind::ALL {
        let e = averaged(kind, &mesh, 0.49);
        let mut k = Stiffness::for_energy(&mesh, &e);
        populate_stiffness_serial(&mesh, &e, &x, Tangent::Projected, &mut k);
        let scale: Real = k.matrix.values.iter().map(|v| v.abs()).fold(0.0, Real::max);
        for _ in 0..50 {
            let v: Vec<Real> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let mut kv = vec![0.0; n];
            k.matrix.mul_vec(&v, &mut kv);
            let q: Real = v.iter().zip(&kv).map(|(a, b)| a * b).sum();
            assert!(
                q >= -1e-12 * scale * n as Real,
                "{kind:?}: v^T K v = {q} < 0"
            );
        }
    }
}

/// Patch test: under an affine map (every element the same `F`) every nodal average equals
/// every element's measure, so energy, forces and stress equal the plain triangle's to
/// round-off, and the interior forces cancel.
#[test]
fn a_uniform_deformation_gives_the_plain_triangles_answer() {
    let mut rng = Rng::new(20);
    let base = rectangle(3.0, 2.0, 6, 4, Diagonal::Alternating);
    // Irregular interior nodes.
    let vertices: Vec<Vec2> = base
        .vertices()
        .iter()
        .map(|p| {
            let interior = p.x > 1e-9 && p.x < 3.0 - 1e-9 && p.y > 1e-9 && p.y < 2.0 - 1e-9;
            if interior {
                p + Vec2::new(rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1))
            } else {
                *p
            }
        })
        .collect();
    let mesh = Mesh::new(vertices, base.triangles().to_vec()).unwrap();
    let a = Mat2::new(1.1, 0.2, -0.05, 0.93);
    let x: Vec<Vec2> = mesh
        .vertices()
        .iter()
        .map(|p| a * p + Vec2::new(0.3, -0.2))
        .collect();
    for kind in EnergyKind::ALL {
        let plain = ElementEnergies::uniform(energy(kind, 1000.0, 0.4999));
        let e = plain.clone().with_nodal_pressure(&mesh).unwrap();
        let (ep, ea) = (
            elastic_energy_serial(&mesh, &plain, &x),
            elastic_energy_serial(&mesh, &e, &x),
        );
        assert!(
            (ep - ea).abs() <= 1e-10 * ep.abs(),
            "{kind:?}: energy {ea} vs {ep}"
        );
        let mut fp = vec![Vec2::zeros(); mesh.n_vertices()];
        let mut fa = vec![Vec2::zeros(); mesh.n_vertices()];
        populate_forces_serial(&mesh, &plain, &x, &mut fp);
        populate_forces_serial(&mesh, &e, &x, &mut fa);
        let scale = fp.iter().map(|f| f.norm()).fold(0.0, Real::max);
        for (v, (p, q)) in fp.iter().zip(&fa).enumerate() {
            assert!(
                (p - q).norm() <= 1e-9 * scale,
                "{kind:?}: force at {v}: {q:?} vs {p:?}"
            );
        }
        let (mut sp, mut sa): (Vec<ElementStress>, Vec<ElementStress>) = (vec![], vec![]);
        populate_element_stress(&mesh, &plain, &x, VonMisesFormula::PlaneStrain, &mut sp);
        populate_element_stress(&mesh, &e, &x, VonMisesFormula::PlaneStrain, &mut sa);
        for (p, q) in sp.iter().zip(&sa) {
            let tol = 1e-9 * p.cauchy.norm();
            assert!((p.cauchy - q.cauchy).norm() <= tol, "{kind:?}");
            assert!((p.sigma_zz - q.sigma_zz).abs() <= tol, "{kind:?}");
            assert!((p.von_mises - q.von_mises).abs() <= tol, "{kind:?}");
        }
    }
}

#[test]
fn the_rest_state_is_stress_free() {
    let mesh = rectangle(2.0, 1.0, 8, 4, Diagonal::Alternating);
    let x = mesh.vertices().to_vec();
    for kind in EnergyKind::ALL {
        let e = averaged(kind, &mesh, 0.4999);
        let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
        populate_forces_serial(&mesh, &e, &x, &mut f);
        // lambda at nu = 0.4999 is 1.7e6 Pa: forces are its round-off.
        let max = f.iter().map(|f| f.norm()).fold(0.0, Real::max);
        assert!(max < 1e-8, "{kind:?}: rest force {max:e} N");
        assert!(
            elastic_energy_serial(&mesh, &e, &x).abs() < 1e-9,
            "{kind:?}"
        );
        let mut s = vec![];
        populate_element_stress(&mesh, &e, &x, VonMisesFormula::PlaneStrain, &mut s);
        let vm = s
            .iter()
            .map(|s| s.von_mises.abs() + s.cauchy.norm())
            .fold(0.0, Real::max);
        assert!(vm < 1e-8, "{kind:?}: rest stress {vm:e} Pa");
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

#[test]
fn parallel_assembly_is_bit_identical_to_serial_for_1_2_4_threads() {
    let mesh = rectangle(5.0, 1.0, 120, 24, Diagonal::Alternating);
    let x = deformed(&mesh, &mut Rng::new(21), 0.2);
    for kind in [
        EnergyKind::NeoHookean,
        EnergyKind::Corotational,
        EnergyKind::Linear,
    ] {
        let e = averaged(kind, &mesh, 0.49);
        let mut f_ref = vec![Vec2::zeros(); mesh.n_vertices()];
        let rep_ref = populate_forces_serial(&mesh, &e, &x, &mut f_ref);
        let e_ref = elastic_energy_serial(&mesh, &e, &x);
        let mut k_ref = Stiffness::for_energy(&mesh, &e);
        populate_stiffness_serial(&mesh, &e, &x, Tangent::Projected, &mut k_ref);
        for threads in [1, 2, 4] {
            let (f, rep, en, k) = with_threads(threads, || {
                let mut scratch = Scratch::new();
                let mut f = vec![Vec2::new(9.0, 9.0); mesh.n_vertices()];
                let rep = populate_forces(&mesh, &e, &x, &mut f, &mut scratch);
                let en = elastic_energy(&mesh, &e, &x, &mut scratch);
                let mut k = Stiffness::for_energy(&mesh, &e);
                populate_stiffness(&mesh, &e, &x, Tangent::Projected, &mut k, &mut scratch);
                (f, rep, en, k)
            });
            assert_eq!(
                bits(&f),
                bits(&f_ref),
                "{kind:?}: forces, {threads} threads"
            );
            assert_eq!(rep, rep_ref, "{kind:?}: report, {threads} threads");
            assert_eq!(
                en.to_bits(),
                e_ref.to_bits(),
                "{kind:?}: energy, {threads} threads"
            );
            let kb: Vec<u64> = k.matrix.values.iter().map(|v| v.to_bits()).collect();
            let kr: Vec<u64> = k_ref.matrix.values.iter().map(|v| v.to_bits()).collect();
            assert!(kb == kr, "{kind:?}: stiffness, {threads} threads");
        }
    }
}

#[test]
fn nodal_pressure_of_a_mesh_matches_its_definition() {
    // theta_n is a third of the current area around the node over a third of the rest area.
    let mesh = rectangle(1.0, 1.0, 3, 3, Diagonal::Alternating);
    let np = NodalPressure::new(&mesh, &[]);
    let x = deformed(&mesh, &mut Rng::new(22), 0.1);
    let e = ElementEnergies::uniform(energy(EnergyKind::StableNeoHookean, 1000.0, 0.45))
        .with_nodal_pressure(&mesh)
        .unwrap();
    let mut scratch = Scratch::new();
    let _ = elastic_energy(&mesh, &e, &x, &mut scratch);
    for n in 0..np.n_nodes() {
        let (mut now, mut rest) = (0.0, 0.0);
        for &(t, _) in np.entries(n) {
            let xs = mesh.gather(t as usize, &x);
            now += 0.5 * (xs[1] - xs[0]).perp(&(xs[2] - xs[0]));
            rest += mesh.elements()[t as usize].area;
        }
        let theta = scratch.pressure().node_theta()[n];
        assert!(
            (theta - now / rest).abs() < 1e-13,
            "node {n}: {theta} vs {}",
            now / rest
        );
    }
}
