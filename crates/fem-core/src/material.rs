//! Linear-elastic material constants and the Lamé parameters the energies use.
//!
//! The paper's Eq. 2 gives `mu = E / (2 (1 + nu))` and `lambda = E nu / ((1 + nu)(1 - 2 nu))`.
//! These are the 3D Lamé parameters; used unchanged in 2D they describe **plane strain** (the
//! body is infinitely thick and `eps_zz = 0`), the default here. **Plane stress** (a thin sheet,
//! `sigma_zz = 0`) keeps `mu` and replaces `lambda` by `2 lambda mu / (lambda + 2 mu)
//! = E nu / (1 - nu^2)`. Every quantity is per unit thickness, in SI units.

use std::fmt;

use crate::math::Real;

/// Which 2D reduction of 3D elasticity a run uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PlaneModel {
    /// `eps_zz = 0`: the paper's Eq. 2 as printed. Default.
    #[default]
    PlaneStrain,
    /// `sigma_zz = 0`: a thin sheet.
    PlaneStress,
}

impl PlaneModel {
    /// The name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            PlaneModel::PlaneStrain => "plane-strain",
            PlaneModel::PlaneStress => "plane-stress",
        }
    }
}

impl fmt::Display for PlaneModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for PlaneModel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "plane-strain" => Ok(PlaneModel::PlaneStrain),
            "plane-stress" => Ok(PlaneModel::PlaneStress),
            other => Err(format!(
                "unknown plane model `{other}` (expected `plane-strain` or `plane-stress`)"
            )),
        }
    }
}

/// With the `serde` feature a plane model is written as its name (`"plane-strain"`,
/// `"plane-stress"`); reading another name fails with the [`FromStr`](std::str::FromStr)
/// message.
#[cfg(feature = "serde")]
impl serde::Serialize for PlaneModel {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for PlaneModel {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = <String as serde::Deserialize>::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

/// An invalid material constant: names the field, the value and the rule it breaks.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("material.{field} = {}: {rule}", crate::math::readable(*value))]
pub struct MaterialError {
    /// Field name as in scene files (`youngs_modulus`, `poisson_ratio`, `density`), or `mu`
    /// and `lambda` from [`Lame::new`].
    pub field: &'static str,
    /// The rejected value.
    pub value: Real,
    /// What the value must satisfy.
    pub rule: &'static str,
}

/// The Lamé parameters `mu` (shear modulus) and `lambda`, in Pa: validated, so every energy
/// built from them is well posed. Build them with [`Lame::new`] or from a [`Material`] with
/// [`Material::lame`] (which always gives valid parameters).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lame {
    mu: Real,
    lambda: Real,
}

impl Lame {
    /// Validate and build: `mu` finite and > 0, `lambda` finite, and the 2D bulk modulus
    /// `lambda + mu` > 0 (the in-plane stability condition: below it a uniform expansion
    /// lowers the linearised energy). Every [`Material`] satisfies them under either
    /// [`PlaneModel`].
    pub fn new(mu: Real, lambda: Real) -> Result<Self, MaterialError> {
        if !mu.is_finite() || mu <= 0.0 {
            return Err(MaterialError {
                field: "mu",
                value: mu,
                rule: "must be a finite number > 0 (Pa)",
            });
        }
        if !lambda.is_finite() || lambda + mu <= 0.0 {
            return Err(MaterialError {
                field: "lambda",
                value: lambda,
                rule: "must be finite with lambda + mu > 0 (a positive 2D bulk modulus)",
            });
        }
        Ok(Lame { mu, lambda })
    }

    /// Shear modulus `mu`, Pa.
    pub fn mu(&self) -> Real {
        self.mu
    }

    /// First Lamé parameter `lambda`, Pa.
    pub fn lambda(&self) -> Real {
        self.lambda
    }
}

/// Isotropic linear-elastic constants and density of a 2D body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    youngs_modulus: Real,
    poisson_ratio: Real,
    density: Real,
}

/// The smallest Young's modulus accepted, Pa: below it the Lamé parameters underflow to
/// subnormal numbers or zero.
pub const MIN_YOUNGS_MODULUS: Real = 1e-290;

/// The largest Young's modulus accepted, Pa: up to it the Lamé parameters stay finite at every
/// Poisson ratio in (-1, 0.5) (the nearest to either end, `1 - 2 nu` or `1 + nu` = 1.1e-16,
/// multiplies `E` by about 3e15), under either plane model. Steel is 2e11 Pa.
pub const MAX_YOUNGS_MODULUS: Real = 1e290;

impl Material {
    /// Validate and build. `youngs_modulus` in Pa (finite, > 0), `poisson_ratio` in (-1, 0.5),
    /// `density` in kg/m^3 (finite, > 0; with unit thickness, the mass per unit area).
    pub fn new(
        youngs_modulus: Real,
        poisson_ratio: Real,
        density: Real,
    ) -> Result<Self, MaterialError> {
        let err = |field, value, rule| Err(MaterialError { field, value, rule });
        if !youngs_modulus.is_finite() || youngs_modulus <= 0.0 {
            return err(
                "youngs_modulus",
                youngs_modulus,
                "must be a finite number > 0 (Pa)",
            );
        }
        if youngs_modulus < MIN_YOUNGS_MODULUS {
            return err(
                "youngs_modulus",
                youngs_modulus,
                "must be at least 1e-290 Pa (smaller values underflow the Lame parameters)",
            );
        }
        if youngs_modulus > MAX_YOUNGS_MODULUS {
            return err(
                "youngs_modulus",
                youngs_modulus,
                "must be at most 1e290 Pa (larger values overflow the Lame parameters)",
            );
        }
        if !poisson_ratio.is_finite() || poisson_ratio <= -1.0 || poisson_ratio >= 0.5 {
            return err(
                "poisson_ratio",
                poisson_ratio,
                "must lie in the open interval (-1, 0.5)",
            );
        }
        if !density.is_finite() || density <= 0.0 {
            return err("density", density, "must be a finite number > 0 (kg/m^3)");
        }
        Ok(Material {
            youngs_modulus,
            poisson_ratio,
            density,
        })
    }

    /// Young's modulus `E`, Pa.
    pub fn youngs_modulus(&self) -> Real {
        self.youngs_modulus
    }

    /// Poisson ratio `nu`.
    pub fn poisson_ratio(&self) -> Real {
        self.poisson_ratio
    }

    /// Density, kg/m^3 (mass per unit area per unit thickness).
    pub fn density(&self) -> Real {
        self.density
    }

    /// Lamé parameters for the given 2D reduction (see the module docs). Always valid in the
    /// sense of [`Lame::new`]: `mu > 0` and `lambda + mu` is `E / (2 (1 + nu) (1 - 2 nu))`
    /// (plane strain) or `E / (2 (1 - nu))` (plane stress), both > 0.
    pub fn lame(&self, plane: PlaneModel) -> Lame {
        let (e, nu) = (self.youngs_modulus, self.poisson_ratio);
        let mu = e / (2.0 * (1.0 + nu));
        let lambda = match plane {
            PlaneModel::PlaneStrain => e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            PlaneModel::PlaneStress => e * nu / (1.0 - nu * nu),
        };
        Lame { mu, lambda }
    }

    /// Dilatational (P-) wave speed `sqrt((lambda + 2 mu) / rho)` in m/s, the speed that bounds
    /// the explicit time step.
    pub fn dilatational_wave_speed(&self, plane: PlaneModel) -> Real {
        let l = self.lame(plane);
        ((l.lambda + 2.0 * l.mu) / self.density).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lame_parameters_follow_eq_2() {
        let m = Material::new(1000.0, 0.3, 1.0).unwrap();
        let l = m.lame(PlaneModel::PlaneStrain);
        assert!((l.mu - 1000.0 / 2.6).abs() < 1e-12);
        assert!((l.lambda - 300.0 / (1.3 * 0.4)).abs() < 1e-12);
        let ps = m.lame(PlaneModel::PlaneStress);
        assert_eq!(ps.mu, l.mu);
        let expected = 2.0 * l.lambda * l.mu / (l.lambda + 2.0 * l.mu);
        assert!((ps.lambda - expected).abs() < 1e-12);
    }

    #[test]
    fn lame_is_validated() {
        assert!(Lame::new(1.0, -0.5).is_ok());
        assert_eq!(Lame::new(-1.0, 1.0).unwrap_err().field, "mu");
        assert_eq!(Lame::new(0.0, 1.0).unwrap_err().field, "mu");
        assert_eq!(Lame::new(Real::NAN, 1.0).unwrap_err().field, "mu");
        assert_eq!(Lame::new(1.0, -1.0).unwrap_err().field, "lambda");
        assert_eq!(Lame::new(1.0, Real::INFINITY).unwrap_err().field, "lambda");
        assert_eq!(
            Lame::new(-2.0, 1.0).unwrap_err().to_string(),
            "material.mu = -2: must be a finite number > 0 (Pa)"
        );
        // Every material gives valid parameters, at the ends of the Poisson range too.
        for nu in [-0.999, -0.5, 0.0, 0.3, 0.499] {
            let m = Material::new(1.0e6, nu, 1.0).unwrap();
            for plane in [PlaneModel::PlaneStrain, PlaneModel::PlaneStress] {
                let l = m.lame(plane);
                assert_eq!(Lame::new(l.mu(), l.lambda()), Ok(l), "nu = {nu}, {plane}");
            }
        }
    }

    #[test]
    fn invalid_values_name_field_and_value() {
        let e = Material::new(0.0, 0.3, 1.0).unwrap_err();
        assert_eq!(e.field, "youngs_modulus");
        assert!(e.to_string().starts_with("material.youngs_modulus = 0"));
        assert_eq!(
            Material::new(1.0, 0.5, 1.0).unwrap_err().field,
            "poisson_ratio"
        );
        assert_eq!(
            Material::new(1.0, -1.0, 1.0).unwrap_err().field,
            "poisson_ratio"
        );
        assert_eq!(
            Material::new(1.0, Real::NAN, 1.0).unwrap_err().field,
            "poisson_ratio"
        );
        assert_eq!(
            Material::new(Real::INFINITY, 0.2, 1.0).unwrap_err().field,
            "youngs_modulus"
        );
        assert_eq!(
            Material::new(1.0, 0.2, -3.0).unwrap_err().to_string(),
            "material.density = -3: must be a finite number > 0 (kg/m^3)"
        );
    }

    #[test]
    fn youngs_modulus_bounds_keep_the_lame_parameters_finite() {
        // At both bounds, with the Poisson ratios nearest to either end of (-1, 0.5), both
        // plane models give finite, valid Lamé parameters and P-wave moduli.
        let ends = [-1.0 + Real::EPSILON, 0.0, 0.3, 0.5 - Real::EPSILON / 2.0];
        for e in [MIN_YOUNGS_MODULUS, MAX_YOUNGS_MODULUS] {
            for nu in ends {
                let m = Material::new(e, nu, 1.0).unwrap();
                for plane in [PlaneModel::PlaneStrain, PlaneModel::PlaneStress] {
                    let l = m.lame(plane);
                    assert_eq!(Lame::new(l.mu(), l.lambda()), Ok(l), "E = {e}, nu = {nu}");
                    assert!(
                        (l.lambda() + 2.0 * l.mu()).is_finite(),
                        "E = {e}, nu = {nu}"
                    );
                }
            }
        }
        assert_eq!(
            Material::new(1e300, 0.3, 1.0).unwrap_err().to_string(),
            "material.youngs_modulus = 1e300: must be at most 1e290 Pa (larger values overflow the Lame parameters)"
        );
    }
}
