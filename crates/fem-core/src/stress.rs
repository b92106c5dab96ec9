//! Cauchy stress, von Mises stress and principal stresses, per element and per vertex.
//!
//! The in-plane Cauchy stress is the energy's [`Energy::cauchy`] (Pa): `P F^T / J`, or for the
//! small-strain energy its own stress `P`. The von Mises formula says what `sigma_zz` is:
//! - [`VonMisesFormula::PlaneStress`]: `sigma_zz = 0`,
//!   `sigma_vm = sqrt(sxx^2 - sxx syy + syy^2 + 3 sxy^2)`;
//! - [`VonMisesFormula::PlaneStrain`] (default, like [`PlaneModel`]'s): `sigma_zz` is the energy's out-of-plane stress at
//!   `F33 = 1` ([`Energy::cauchy_zz`], exact for every energy; the small-strain estimate
//!   `nu (sxx + syy)` under-reports a Neo-Hookean element at `F = [[1.2, 0.3], [0.1, 0.9]]` by
//!   1.2 %, StVK by 3.7 %), then the full 3D formula
//!   `sqrt(((sxx - syy)^2 + (syy - szz)^2 + (szz - sxx)^2) / 2 + 3 sxy^2)`.
//!
//! With the averaged nodal pressure triangle ([`crate::nodal_pressure`]) each element's normal
//! stresses (in plane, and out of plane in plane strain) are shifted by its correction
//! `p_e - U'(theta_e)`: the element's hydrostatic stress is the average of its nodes'
//! pressures. The von Mises stress of plane strain does not see a shift of all three normal
//! stresses; the formulation changes it through the displacements it no longer locks.
//!
//! For an inverted element (`J < 0`) `sigma` is the formula's value; at `J = 0`, and for energies
//! undefined at `J <= 0` (Neo-Hookean), it is not finite. Vertex averages skip non-finite
//! element values.

use crate::energy::{Energy, EnergyOf};
use crate::material::PlaneModel;
use crate::math::{Mat2, Real, Vec2};
use crate::mesh::Mesh;

/// Which out-of-plane stress the von Mises stress assumes (see the module docs). The default
/// and the conversion from a [`PlaneModel`] follow the body's 2D reduction: a plane-strain
/// body (the default) reports the plane-strain formula.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VonMisesFormula {
    /// `sigma_zz = 0`.
    PlaneStress,
    /// `sigma_zz` from the energy at `F33 = 1` ([`Energy::cauchy_zz`]). Default.
    #[default]
    PlaneStrain,
}

impl From<PlaneModel> for VonMisesFormula {
    /// The formula that matches the body's reduction: `sigma_zz = 0` for plane stress, the
    /// energy's `sigma_zz` at `F33 = 1` for plane strain.
    fn from(plane: PlaneModel) -> Self {
        match plane {
            PlaneModel::PlaneStrain => VonMisesFormula::PlaneStrain,
            PlaneModel::PlaneStress => VonMisesFormula::PlaneStress,
        }
    }
}

impl VonMisesFormula {
    /// A short description for run summaries.
    pub fn describe(&self) -> String {
        match self {
            VonMisesFormula::PlaneStress => "plane stress (sigma_zz = 0)".to_owned(),
            VonMisesFormula::PlaneStrain => {
                "plane strain (sigma_zz from the energy at F33 = 1, exact)".to_owned()
            }
        }
    }

    /// The out-of-plane stress this formula uses for `energy` at `f`, Pa.
    #[inline]
    pub fn sigma_zz<E: Energy>(&self, energy: &E, f: &Mat2) -> Real {
        match self {
            VonMisesFormula::PlaneStress => 0.0,
            VonMisesFormula::PlaneStrain => energy.cauchy_zz(f),
        }
    }
}

/// Cauchy stress `P F^T / J` of a first Piola-Kirchhoff stress (the finite-strain push-forward;
/// [`Energy::cauchy`] is the energy's own choice).
#[inline]
pub fn cauchy(f: &Mat2, p: &Mat2) -> Mat2 {
    p * f.transpose() / f.determinant()
}

/// Von Mises stress of an in-plane Cauchy stress with out-of-plane stress `sigma_zz` (0 for
/// plane stress): `sqrt(((sxx - syy)^2 + (syy - szz)^2 + (szz - sxx)^2) / 2 + 3 sxy^2)`.
#[inline]
pub fn von_mises(sigma: &Mat2, sigma_zz: Real) -> Real {
    let (sxx, syy) = (sigma[(0, 0)], sigma[(1, 1)]);
    let sxy = 0.5 * (sigma[(0, 1)] + sigma[(1, 0)]);
    if sigma_zz == 0.0 {
        // The plane-stress form: the same value, with fewer roundings.
        return (sxx * sxx - sxx * syy + syy * syy + 3.0 * sxy * sxy).sqrt();
    }
    let szz = sigma_zz;
    let d = (sxx - syy).powi(2) + (syy - szz).powi(2) + (szz - sxx).powi(2);
    (0.5 * d + 3.0 * sxy * sxy).sqrt()
}

/// In-plane principal stresses `(sigma_1, sigma_2)`, `sigma_1 >= sigma_2`.
#[inline]
pub fn principal(sigma: &Mat2) -> (Real, Real) {
    let (sxx, syy) = (sigma[(0, 0)], sigma[(1, 1)]);
    let sxy = 0.5 * (sigma[(0, 1)] + sigma[(1, 0)]);
    let c = 0.5 * (sxx + syy);
    let r = (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt();
    (c + r, c - r)
}

/// Stress state of one element.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementStress {
    /// Cauchy stress, Pa.
    pub cauchy: Mat2,
    /// Out-of-plane Cauchy stress the von Mises stress used, Pa (0 for plane stress).
    pub sigma_zz: Real,
    /// Von Mises stress, Pa.
    pub von_mises: Real,
    /// Principal stresses, Pa, largest first.
    pub principal: (Real, Real),
    /// `det F`.
    pub det_f: Real,
    /// Principal nominal (Biot) strains `s_i - 1`, with `s_i` the singular values of `F`
    /// (the principal stretches), largest first; the smaller one is the largest compression
    /// when it is negative.
    pub strain: (Real, Real),
}

impl ElementStress {
    /// An element that does not deform (a rigid region's): no stress, `det F = 1`, no strain.
    pub const UNSTRESSED: ElementStress = ElementStress {
        cauchy: Mat2::new(0.0, 0.0, 0.0, 0.0),
        sigma_zz: 0.0,
        von_mises: 0.0,
        principal: (0.0, 0.0),
        det_f: 1.0,
        strain: (0.0, 0.0),
    };
}

/// The principal nominal strains of `F` (see [`ElementStress::strain`]): the square roots of
/// the eigenvalues of `C = F^T F`, minus one, largest first.
pub fn principal_strains(f: &Mat2) -> (Real, Real) {
    let c = f.transpose() * f;
    let (big, small) = principal(&c);
    (big.max(0.0).sqrt() - 1.0, small.max(0.0).sqrt() - 1.0)
}

/// The stress of every element at positions `x`, in triangle order, into `out`.
pub fn populate_element_stress<M: EnergyOf>(
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
    formula: VonMisesFormula,
    out: &mut Vec<ElementStress>,
) {
    out.clear();
    // The averaged nodal pressure triangle shifts each element's normal stresses by its
    // correction (the nodal pressure replaces the element's own volumetric stress).
    let shift = energy
        .nodal_pressure()
        .map(|np| crate::nodal_pressure::stress_correction(np, mesh, energy, x));
    out.extend(mesh.elements().iter().enumerate().map(|(t, el)| {
        let f = el.deformation_gradient(mesh.gather(t, x));
        let energy = energy.energy_of(t);
        let mut sigma = energy.cauchy(&f);
        let mut sigma_zz = formula.sigma_zz(energy, &f);
        if let Some(shift) = &shift {
            sigma += Mat2::identity() * shift[t];
            if formula == VonMisesFormula::PlaneStrain {
                sigma_zz += shift[t];
            }
        }
        ElementStress {
            cauchy: sigma,
            sigma_zz,
            von_mises: von_mises(&sigma, sigma_zz),
            principal: principal(&sigma),
            det_f: f.determinant(),
            strain: principal_strains(&f),
        }
    }));
}

/// Area-weighted average at each vertex of a per-element field, skipping non-finite values
/// (a vertex with none left gets NaN). Writes one value per vertex into `out`.
pub fn vertex_average(mesh: &Mesh, per_element: &[Real], out: &mut [Real]) {
    assert_eq!(
        per_element.len(),
        mesh.n_triangles(),
        "one value per triangle"
    );
    assert_eq!(out.len(), mesh.n_vertices(), "one output per vertex");
    for (v, o) in out.iter_mut().enumerate() {
        let (mut sum, mut weight) = (0.0, 0.0);
        for &(e, _) in mesh.adjacency().of(v) {
            let value = per_element[e as usize];
            if value.is_finite() {
                let a = mesh.elements()[e as usize].area;
                sum += a * value;
                weight += a;
            }
        }
        *o = if weight > 0.0 {
            sum / weight
        } else {
            Real::NAN
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_formula_follows_the_default_plane_model() {
        assert_eq!(
            VonMisesFormula::default(),
            VonMisesFormula::from(PlaneModel::default())
        );
        assert_eq!(
            VonMisesFormula::from(PlaneModel::PlaneStress),
            VonMisesFormula::PlaneStress
        );
    }

    #[test]
    fn uniaxial_stress_has_von_mises_equal_to_the_stress() {
        let s = Mat2::new(5.0, 0.0, 0.0, 0.0);
        assert_eq!(von_mises(&s, 0.0), 5.0);
        assert_eq!(principal(&s), (5.0, 0.0));
    }

    #[test]
    fn pure_shear_has_von_mises_sqrt3_tau() {
        let s = Mat2::new(0.0, 2.0, 2.0, 0.0);
        let vm = von_mises(&s, 0.0);
        assert!((vm - 2.0 * 3f64.sqrt()).abs() < 1e-14);
        let (s1, s2) = principal(&s);
        assert!((s1 - 2.0).abs() < 1e-14 && (s2 + 2.0).abs() < 1e-14);
        // The full formula with sigma_zz = 0 agrees with the plane-stress form.
        let vm2 = von_mises(&s, 1e-300);
        assert!((vm - vm2).abs() < 1e-14);
    }

    #[test]
    fn hydrostatic_plane_strain_stress_has_von_mises_from_sigma_zz() {
        // sxx = syy = p, szz = 2 nu p: von Mises = |p - 2 nu p|.
        let s = Mat2::new(1.0, 0.0, 0.0, 1.0);
        let vm = von_mises(&s, 0.6);
        assert!((vm - 0.4).abs() < 1e-14);
        assert_eq!(von_mises(&s, 0.0), 1.0);
    }
}
