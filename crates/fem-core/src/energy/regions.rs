//! Per-element energies: a body made of several materials (soft tissue and bone) shares one
//! energy *kind* but gives each element the Lamé parameters of its region.
//!
//! [`EnergyOf`] is what assembly and the solvers' kernels ask for: "the energy of element `t`".
//! Every [`Energy`] is an `EnergyOf` (the same energy for every element), and so is an
//! [`ElementEnergies`] (one energy per region, a region tag per element). Code written against
//! `EnergyOf` therefore runs unchanged on a homogeneous body, with no lookup at all.

use std::sync::Arc;

use super::{Energy, EnergyError};
use crate::mesh::Mesh;
use crate::nodal_pressure::NodalPressure;

/// The energy of every element of a mesh.
pub trait EnergyOf: Send + Sync {
    /// The energy type shared by every element.
    type Energy: Energy;

    /// The energy of element (triangle) `t`.
    fn energy_of(&self, t: usize) -> &Self::Energy;

    /// The nodes of the averaged nodal pressure triangle ([`crate::nodal_pressure`]) when the
    /// body uses it; `None` (the default): plain linear triangles.
    fn nodal_pressure(&self) -> Option<&NodalPressure> {
        None
    }
}

impl<E: Energy> EnergyOf for E {
    type Energy = E;

    #[inline(always)]
    fn energy_of(&self, _t: usize) -> &E {
        self
    }
}

/// One energy per region and a region tag per element.
///
/// Region 0 is the body's own material (the *base*); a homogeneous body has one region and no
/// tags. All regions share the energy kind (the type `E`), each with its own constants.
#[derive(Clone, Debug, PartialEq)]
pub struct ElementEnergies<E> {
    energies: Vec<E>,
    /// One tag per element, or empty: every element is region 0.
    tags: Vec<u32>,
    /// The averaged nodal pressure triangle's nodes, when the body uses it.
    pressure: Option<Arc<NodalPressure>>,
}

impl<E: Energy> ElementEnergies<E> {
    /// The same energy for every element.
    pub fn uniform(energy: E) -> Self {
        Self {
            energies: vec![energy],
            tags: Vec::new(),
            pressure: None,
        }
    }

    /// Region `k` has `energies[k]`; element `t` is in region `tags[t]`. `tags` may be empty
    /// (every element in region 0); otherwise the caller checks its length against the mesh
    /// (see [`ElementEnergies::check_len`]). Errors when `energies` is empty or a tag has no
    /// energy.
    pub fn new(energies: Vec<E>, tags: Vec<u32>) -> Result<Self, EnergyError> {
        let Some(first) = energies.first() else {
            return Err(EnergyError::Parameters {
                energy: "regions",
                message: "at least one region energy is needed".into(),
            });
        };
        if let Some((t, &tag)) = tags
            .iter()
            .enumerate()
            .find(|&(_, &tag)| tag as usize >= energies.len())
        {
            return Err(EnergyError::Parameters {
                energy: first.name(),
                message: format!(
                    "region tag {tag} of element {t} has no material ({} regions)",
                    energies.len()
                ),
            });
        }
        Ok(Self {
            energies,
            tags,
            pressure: None,
        })
    }

    /// An error message when the tags do not cover `n_triangles` elements (none when there
    /// are no tags).
    pub fn check_len(&self, n_triangles: usize) -> Result<(), String> {
        if self.tags.is_empty() || self.tags.len() == n_triangles {
            Ok(())
        } else {
            Err(format!(
                "{} region tags for {n_triangles} triangles",
                self.tags.len()
            ))
        }
    }

    /// The same energies with the averaged nodal pressure triangle on `mesh` (the mesh whose
    /// triangles these energies' tags describe): a locking-free formulation for nearly
    /// incompressible bodies ([`crate::nodal_pressure`]). Errors when the tags do not cover the
    /// mesh.
    pub fn with_nodal_pressure(mut self, mesh: &Mesh) -> Result<Self, EnergyError> {
        self.check_len(mesh.n_triangles())
            .map_err(|message| EnergyError::Parameters {
                energy: self.base().name(),
                message,
            })?;
        self.pressure = Some(Arc::new(NodalPressure::new(mesh, &self.tags)));
        Ok(self)
    }

    /// The same energies on plain linear triangles.
    pub fn without_nodal_pressure(mut self) -> Self {
        self.pressure = None;
        self
    }

    /// The base energy (region 0).
    pub fn base(&self) -> &E {
        &self.energies[0]
    }

    /// The energy of each region.
    pub fn energies(&self) -> &[E] {
        &self.energies
    }

    /// The region of each element (empty: all in region 0).
    pub fn tags(&self) -> &[u32] {
        &self.tags
    }

    /// The region of element `t`.
    #[inline(always)]
    pub fn tag(&self, t: usize) -> u32 {
        if self.tags.is_empty() {
            0
        } else {
            self.tags[t]
        }
    }

    /// Whether every element has the base energy (one region, or no tags).
    pub fn is_uniform(&self) -> bool {
        self.tags.is_empty() || self.energies.len() == 1
    }

    /// The number of regions.
    pub fn n_regions(&self) -> usize {
        self.energies.len()
    }
}

impl<E: Energy> EnergyOf for ElementEnergies<E> {
    type Energy = E;

    #[inline(always)]
    fn energy_of(&self, t: usize) -> &E {
        &self.energies[self.tag(t) as usize]
    }

    fn nodal_pressure(&self) -> Option<&NodalPressure> {
        self.pressure.as_deref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PlaneModel;
    use crate::energy::EnergyKind;
    use crate::material::Material;
    use crate::math::Mat2;

    fn neo(e: f64) -> crate::energy::AnyEnergy {
        let lame = Material::new(e, 0.3, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain);
        EnergyKind::NeoHookean.build(lame).unwrap()
    }

    #[test]
    fn tags_select_the_region_energy_and_bad_tags_are_named() {
        let regions = ElementEnergies::new(vec![neo(1.0e3), neo(1.0e6)], vec![0, 1, 1]).unwrap();
        let f = Mat2::new(1.1, 0.0, 0.0, 1.0);
        assert_eq!(regions.energy_of(0).psi(&f), neo(1.0e3).psi(&f));
        assert_eq!(regions.energy_of(2).psi(&f), neo(1.0e6).psi(&f));
        assert!(regions.check_len(3).is_ok() && regions.check_len(4).is_err());
        let e = ElementEnergies::new(vec![neo(1.0e3)], vec![0, 2]).unwrap_err();
        assert!(e.to_string().contains("region tag 2 of element 1"), "{e}");
        assert!(ElementEnergies::<crate::energy::AnyEnergy>::new(vec![], vec![]).is_err());
        let uniform = ElementEnergies::uniform(neo(5.0));
        assert!(uniform.is_uniform() && uniform.tag(7) == 0);
    }
}
