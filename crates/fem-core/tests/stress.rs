//! Stress recovery on a mesh: uniform states give uniform fields, and small-strain stresses
//! match Hooke's law in plane strain (including the out-of-plane stress the plane-strain von
//! Mises formula assumes).

mod common;

use common::{Diagonal, rectangle};
use fem_core::energy::{Energy, Linear, NeoHookean};
use fem_core::material::{Material, PlaneModel};
use fem_core::math::{Mat2, Real, Vec2};
use fem_core::stress::{VonMisesFormula, populate_element_stress, vertex_average};

#[test]
fn small_uniaxial_strain_matches_hookes_law_in_plane_strain() {
    let material = Material::new(1000.0, 0.3, 1.0).unwrap();
    let lame = material.lame(PlaneModel::PlaneStrain);
    let mesh = rectangle(2.0, 1.0, 4, 2, Diagonal::Right);
    let e = 1e-6;
    let x: Vec<Vec2> = mesh
        .vertices()
        .iter()
        .map(|p| Vec2::new((1.0 + e) * p.x, p.y))
        .collect();
    let plane_strain = VonMisesFormula::PlaneStrain {
        poisson_ratio: material.poisson_ratio(),
    };
    let mut out = Vec::new();
    let mut nh = Vec::new();
    populate_element_stress(&mesh, &Linear::new(lame), &x, plane_strain, &mut out);
    populate_element_stress(&mesh, &NeoHookean::new(lame), &x, plane_strain, &mut nh);
    out.extend(nh);
    // Hooke, plane strain: sxx = (lambda + 2 mu) e, syy = lambda e, szz = nu (sxx + syy) =
    // lambda e, so von Mises = 2 mu e. Finite-strain corrections are O(e^2), relative O(e).
    let tol = 10.0 * e;
    for s in &out {
        let sxx = (lame.lambda + 2.0 * lame.mu) * e;
        assert!(
            (s.cauchy[(0, 0)] - sxx).abs() < tol * sxx,
            "sxx {}",
            s.cauchy[(0, 0)]
        );
        assert!((s.cauchy[(1, 1)] - lame.lambda * e).abs() < tol * sxx);
        assert!(s.cauchy[(0, 1)].abs() < tol * sxx);
        assert!(
            (s.von_mises - 2.0 * lame.mu * e).abs() < tol * sxx,
            "vm {}",
            s.von_mises
        );
        assert!((s.principal.0 - sxx).abs() < tol * sxx);
    }
}

#[test]
fn uniform_state_gives_uniform_element_and_vertex_fields() {
    let lame = Material::new(1000.0, 0.3, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    let mesh = rectangle(3.0, 1.0, 6, 3, Diagonal::Alternating);
    let a = Mat2::new(1.3, 0.2, -0.1, 0.9);
    let x: Vec<Vec2> = mesh.vertices().iter().map(|p| a * p).collect();
    let energy = NeoHookean::new(lame);
    let mut out = Vec::new();
    populate_element_stress(&mesh, &energy, &x, VonMisesFormula::PlaneStress, &mut out);
    let vm: Vec<Real> = out.iter().map(|s| s.von_mises).collect();
    let expected = {
        let sigma = energy.pk1(&a) * a.transpose() / a.determinant();
        let (sxx, syy, sxy) = (sigma[(0, 0)], sigma[(1, 1)], sigma[(0, 1)]);
        (sxx * sxx - sxx * syy + syy * syy + 3.0 * sxy * sxy).sqrt()
    };
    for v in &vm {
        assert!((v - expected).abs() < 1e-12 * expected);
    }
    let mut per_vertex = vec![0.0; mesh.n_vertices()];
    vertex_average(&mesh, &vm, &mut per_vertex);
    for v in &per_vertex {
        assert!((v - expected).abs() < 1e-12 * expected);
    }
}

#[test]
fn vertex_average_skips_non_finite_values_and_weights_by_area() {
    let mesh = fem_core::mesh::Mesh::from_arrays(
        &[[0.0, 0.0], [2.0, 0.0], [0.0, 1.0], [2.0, 2.0]],
        &[[0, 1, 2], [1, 3, 2]],
    )
    .unwrap();
    let areas: Vec<Real> = mesh.elements().iter().map(|e| e.area).collect();
    let mut out = vec![0.0; 4];
    vertex_average(&mesh, &[1.0, 4.0], &mut out);
    assert_eq!(out[0], 1.0);
    assert_eq!(out[3], 4.0);
    let expected = (areas[0] * 1.0 + areas[1] * 4.0) / (areas[0] + areas[1]);
    assert!((out[1] - expected).abs() < 1e-15);
    vertex_average(&mesh, &[Real::NAN, 4.0], &mut out);
    assert!(out[0].is_nan());
    assert_eq!(out[1], 4.0);
}
