//! Hyperelastic energy densities `psi(F)` of a 2D body, one per file, behind one trait.
//!
//! An energy sees only the deformation gradient `F` (and its own constants); the element owns
//! the kinematics and assembly does the chain rule. Each energy provides the strain energy
//! density `psi` (J/m^2 per unit thickness), the first Piola-Kirchhoff stress `P = dpsi/dF`, its
//! derivative `dP/dF` (a 4x4 matrix on `vec(F)`, see [`crate::math`]) and an SPD-projected
//! `dP/dF` for Newton-type solvers.
//!
//! | name                 | type                 | inverted elements (`J <= 0`)               |
//! |----------------------|----------------------|--------------------------------------------|
//! | `stvk`               | [`Stvk`]             | finite; can invert and stay inverted       |
//! | `corotational`       | [`Corotational`]     | finite; proper-rotation polar, resists     |
//! | `neo-hookean`        | [`NeoHookean`]       | undefined: `psi = +inf`, `P` is NaN        |
//! | `stable-neo-hookean` | [`StableNeoHookean`] | finite and smooth; pushes back             |
//! | `linear`             | [`Linear`]           | finite; not rotation invariant             |

mod corotational;
mod hyperelastic;
mod linear;
mod neo_hookean;
mod regions;
mod stable_neo_hookean;
mod stvk;
mod volumetric;

use std::fmt;
use std::str::FromStr;

pub use corotational::Corotational;
pub use hyperelastic::Hyperelastic;
pub use linear::Linear;
pub use neo_hookean::NeoHookean;
pub use regions::{ElementEnergies, EnergyOf};
pub use stable_neo_hookean::StableNeoHookean;
pub use stvk::Stvk;
pub use volumetric::{VolumeMeasure, Volumetric};

use nalgebra::SymmetricEigen;

use crate::material::Lame;
use crate::math::{LANES, Mat2, Mat2Lanes, Mat4, Real, Vec2, vec_index};

/// A hyperelastic energy density of the deformation gradient.
///
/// Implementations must be cheap to copy and free of interior state, so solvers can evaluate
/// them from many threads at once.
pub trait Energy: Send + Sync + Clone + fmt::Debug {
    /// The name used on the command line and in files (`stvk`, `neo-hookean`, ...).
    fn name(&self) -> &'static str;

    /// The same energy with other Lamé parameters: the energy of a region of another material
    /// in a body that shares one energy kind ([`ElementEnergies`]).
    fn with_lame(&self, lame: Lame) -> Result<Self, EnergyError>
    where
        Self: Sized;

    /// Strain energy density `psi(F)`, J/m^2 per unit thickness.
    fn psi(&self, f: &Mat2) -> Real;

    /// First Piola-Kirchhoff stress `P = dpsi/dF`, Pa.
    fn pk1(&self, f: &Mat2) -> Mat2;

    /// `dP/dF` as a 4x4 matrix on `vec(F)` (column-major flattening, see [`crate::math`]).
    fn dpk1(&self, f: &Mat2) -> Mat4;

    /// `dP/dF` projected onto the positive semi-definite cone (negative eigenvalues clamped to
    /// zero), for Newton solvers that need a descent direction. The default does a symmetric
    /// eigendecomposition of [`Energy::dpk1`] ([`project_psd`]); every energy here overrides
    /// it with a closed form (the isotropic ones with [`project_psd_isotropic`]).
    fn dpk1_projected(&self, f: &Mat2) -> Mat4 {
        project_psd(&self.dpk1(f))
    }

    /// The out-of-plane Cauchy stress `sigma_zz` of plane strain, Pa.
    ///
    /// Each 2D energy here is a 3D energy evaluated at `F33 = 1` (its module names that 3D
    /// form), so `sigma_zz = P33 / J` with `P33 = dpsi_3D/dF33` at `F33 = 1`: exact, where the
    /// small-strain estimate `nu (sigma_xx + sigma_yy)` holds only for linear elasticity. For the
    /// small-strain energy (`linear`) it is the small-strain stress `P33` itself.
    fn cauchy_zz(&self, f: &Mat2) -> Real;

    /// The energy's **volumetric part** `U(theta)`: the term of `psi` that the first Lamé
    /// parameter scales, as a function of one volume measure `theta` (`J = det F`, or
    /// `1 + tr(eps)` for the small-strain energy). The averaged nodal pressure triangle
    /// ([`crate::nodal_pressure`]) evaluates `psi - U(theta_e)` on each element and `U` on the
    /// nodal average of `theta`; the identity `psi = (psi - U) + U` makes the two formulations
    /// agree exactly under uniform deformation.
    fn volumetric(&self) -> Volumetric;

    /// The in-plane Cauchy stress, Pa: `P F^T / J` by default; the small-strain energy
    /// (`linear`) overrides it with its own stress `P` (it has no pushed-forward stress).
    fn cauchy(&self, f: &Mat2) -> Mat2 {
        self.pk1(f) * f.transpose() / f.determinant()
    }

    /// `P` and the 2x2 **corner block** `B_ik = sum_jl g_j dP_ij/dF_kl g_l` for a corner whose
    /// shape-function gradient is `g`: when that corner moves by `u`, `F` moves by `u g^T` and
    /// `dP g = B u`, so `a B` is the Hessian of the element energy `a psi` with respect to the
    /// corner's position (Vertex Block Descent's per-vertex Newton step sums it over the
    /// triangles around a vertex). `B` is symmetric, not necessarily positive definite.
    ///
    /// The default contracts [`Energy::dpk1`] (16 entries, 64 products); energies override it
    /// with a closed form in `g` that shares work with `P` (a test checks every override
    /// against the default to round-off).
    #[inline]
    fn pk1_corner_block(&self, f: &Mat2, g: &Vec2) -> (Mat2, Mat2) {
        (self.pk1(f), contract_corner(&self.dpk1(f), g))
    }

    /// `psi` and `P` together; energies override it when the two share work.
    fn psi_pk1(&self, f: &Mat2) -> (Real, Mat2) {
        (self.psi(f), self.pk1(f))
    }

    /// [`Energy::pk1`] for a batch of [`LANES`] deformation gradients in structure-of-arrays
    /// form, for element kernels that evaluate several elements at once.
    ///
    /// Contract: lane `i` of the result is bit-identical to `pk1(&f.lane(i))`. The default
    /// calls [`Energy::pk1`] per lane; energies override it with lane-wise arithmetic (the
    /// same operations in the same order, branches written as selects) that the compiler
    /// vectorises.
    #[inline(always)]
    fn pk1_lanes(&self, f: &Mat2Lanes) -> Mat2Lanes {
        let mut p = Mat2Lanes::default();
        for i in 0..LANES {
            p.set_lane(i, &self.pk1(&f.lane(i)));
        }
        p
    }
}

/// `B_ik = sum_jl g_j D_(ij),(kl) g_l`: the corner block of `dP/dF = D` (see
/// [`Energy::pk1_corner_block`]).
#[inline]
pub fn contract_corner(d: &Mat4, g: &Vec2) -> Mat2 {
    let mut b = Mat2::zeros();
    for i in 0..2 {
        for k in 0..2 {
            let mut s = 0.0;
            for j in 0..2 {
                for l in 0..2 {
                    s += g[j] * d[(vec_index(i, j), vec_index(k, l))] * g[l];
                }
            }
            b[(i, k)] = s;
        }
    }
    b
}

/// A rotation-variant singular value decomposition `F = U diag(s) V^T` of a 2x2 matrix: `U`
/// and `V` are proper rotations, and `s[1]` is negative when `det F < 0` (the reflection goes
/// into the smaller singular value, as inversion-aware elasticity wants). Closed form: the
/// polar rotation `R` ([`crate::polar::Polar2`]), then the symmetric eigendecomposition
/// `R^T F = W diag(s) W^T` with `W` a rotation, so `U = R W` and `V = W`. Only square roots; no
/// iteration and no trigonometry (bit-identical on every target).
pub fn svd_rotation_variant(f: &Mat2) -> (Mat2, Vec2, Mat2) {
    let r = crate::polar::Polar2::new(f).rotation();
    let s = r.transpose() * f;
    // `R^T F` is symmetric analytically; average its off-diagonal round-off away.
    let (a, b, d) = (s[(0, 0)], 0.5 * (s[(0, 1)] + s[(1, 0)]), s[(1, 1)]);
    let mean = 0.5 * (a + d);
    let half = 0.5 * (a - d);
    // `sqrt`, not `hypot`: IEEE-exact on every target (libm's `hypot` is not).
    let radius = (half * half + b * b).sqrt();
    // The eigenvector of the larger eigenvalue `mean + radius`, from whichever row of
    // `S - lambda I` is better conditioned.
    let v = if radius == 0.0 {
        Vec2::new(1.0, 0.0)
    } else if half >= 0.0 {
        Vec2::new(half + radius, b)
    } else {
        Vec2::new(b, radius - half)
    };
    let v = v / v.norm();
    let w = Mat2::new(v.x, -v.y, v.y, v.x);
    (r * w, Vec2::new(mean + radius, mean - radius), w)
}

/// The PSD projection of a symmetric 2x2 matrix `[[p, q], [q, r]]` (its negative eigenvalue
/// clamped to zero), in closed form: `A` itself when both eigenvalues are non-negative, zero
/// when both are non-positive, else `l_max (A - l_min I) / (l_max - l_min)`.
#[inline]
pub(crate) fn project_psd2(p: Real, q: Real, r: Real) -> (Real, Real, Real) {
    let mean = 0.5 * (p + r);
    let half = 0.5 * (p - r);
    let radius = (half * half + q * q).sqrt();
    let (hi, lo) = (mean + radius, mean - radius);
    if lo >= 0.0 {
        (p, q, r)
    } else if hi <= 0.0 {
        (0.0, 0.0, 0.0)
    } else {
        let c = hi / (hi - lo);
        (c * (p - lo), c * q, c * (r - lo))
    }
}

/// The PSD projection of `dP/dF` of an **isotropic** energy in closed form (Smith, de Goes and
/// Kim, "Analytic eigensystems for isotropic distortion energies", ACM TOG 2019, in 2D).
///
/// With the rotation-variant SVD `F = U diag(s) V^T` ([`svd_rotation_variant`]), the four
/// matrices `U e_a e_b^T V^T` form an orthonormal basis of 2x2 matrices in which the Hessian of
/// any isotropic `psi` is block diagonal: the two **scaling** directions (`a = b`) couple through
/// the 2x2 Hessian of `psi` in the singular values, and the **twist** and **flip** directions
/// (`a != b`) form a second 2x2 block whose eigenvalues are
/// `(psi_1 - psi_2) / (s_1 - s_2)` and `(psi_1 + psi_2) / (s_1 + s_2)`. So the eigenvectors are
/// known in closed form: rotate `dP/dF` (`d`, the energy's own exact tangent) into that basis,
/// clamp the two 2x2 blocks in closed form, and rotate back. It equals
/// [`project_psd`] of the same matrix to round-off (a test checks every isotropic energy, over
/// random and inverted `F`, to `1e-10` relative). When `d` is already PSD (a 4x4 Cholesky
/// proves most such tangents positive definite first, for a few dozen flops), its symmetric
/// part is returned as it is.
pub fn project_psd_isotropic(f: &Mat2, d: &Mat4) -> Mat4 {
    let sym = (d + d.transpose()) * 0.5;
    // Most elements are positive definite: a 4x4 Cholesky (a few dozen flops, cheaper than the
    // SVD and the two rotations) proves it, and the answer is then `sym` either way.
    if nalgebra::Cholesky::new(sym).is_some() {
        return sym;
    }
    let (u, _, v) = svd_rotation_variant(f);
    // Columns: vec(u_a v_b^T) for (a, b) = (0, 0), (1, 1), (0, 1), (1, 0).
    let mut q = Mat4::zeros();
    for (k, (a, b)) in [(0, 0), (1, 1), (0, 1), (1, 0)].into_iter().enumerate() {
        for j in 0..2 {
            for i in 0..2 {
                q[(vec_index(i, j), k)] = u[(i, a)] * v[(j, b)];
            }
        }
    }
    let rotated = q.transpose() * sym * q;
    let scaling = project_psd2(rotated[(0, 0)], rotated[(0, 1)], rotated[(1, 1)]);
    let pair = project_psd2(rotated[(2, 2)], rotated[(2, 3)], rotated[(3, 3)]);
    if scaling == (rotated[(0, 0)], rotated[(0, 1)], rotated[(1, 1)])
        && pair == (rotated[(2, 2)], rotated[(2, 3)], rotated[(3, 3)])
    {
        return sym;
    }
    let mut clamped = Mat4::zeros();
    for (o, (p, x, r)) in [(0, scaling), (2, pair)] {
        clamped[(o, o)] = p;
        clamped[(o, o + 1)] = x;
        clamped[(o + 1, o)] = x;
        clamped[(o + 1, o + 1)] = r;
    }
    q * clamped * q.transpose()
}

/// Clamp the eigenvalues of the symmetric part of `m` at zero and rebuild it: the general route,
/// by an iterative symmetric eigendecomposition, for any tangent ([`project_psd_isotropic`] is
/// the closed form for isotropic energies).
pub fn project_psd(m: &Mat4) -> Mat4 {
    let sym = (m + m.transpose()) * 0.5;
    // Most elements are positive definite: a 4x4 Cholesky (a few dozen flops) proves it and
    // returns the same matrix the eigen path would, without the iterative eigendecomposition.
    if nalgebra::Cholesky::new(sym).is_some() {
        return sym;
    }
    let mut eig = SymmetricEigen::new(sym);
    if eig.eigenvalues.iter().all(|&l| l >= 0.0) {
        return sym;
    }
    eig.eigenvalues.iter_mut().for_each(|l| *l = l.max(0.0));
    eig.recompose()
}

/// The energies by name, for the command line, scene files and runtime selection.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum EnergyKind {
    /// Saint Venant-Kirchhoff.
    Stvk,
    /// Co-rotational.
    Corotational,
    /// Compressible Neo-Hookean (standard form).
    NeoHookean,
    /// Stable Neo-Hookean (Smith et al. 2018).
    StableNeoHookean,
    /// Linear (small-strain) elasticity.
    Linear,
}

impl EnergyKind {
    /// Every energy, in the order tables list them.
    pub const ALL: [EnergyKind; 5] = [
        EnergyKind::Stvk,
        EnergyKind::Corotational,
        EnergyKind::NeoHookean,
        EnergyKind::StableNeoHookean,
        EnergyKind::Linear,
    ];

    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            EnergyKind::Stvk => "stvk",
            EnergyKind::Corotational => "corotational",
            EnergyKind::NeoHookean => "neo-hookean",
            EnergyKind::StableNeoHookean => "stable-neo-hookean",
            EnergyKind::Linear => "linear",
        }
    }

    /// Build the energy with the given Lamé parameters.
    pub fn build(self, lame: Lame) -> Result<AnyEnergy, EnergyError> {
        Ok(match self {
            EnergyKind::Stvk => AnyEnergy::Stvk(Stvk::new(lame)?),
            EnergyKind::Corotational => AnyEnergy::Corotational(Corotational::new(lame)?),
            EnergyKind::NeoHookean => AnyEnergy::NeoHookean(NeoHookean::new(lame)?),
            EnergyKind::StableNeoHookean => {
                AnyEnergy::StableNeoHookean(StableNeoHookean::new(lame)?)
            }
            EnergyKind::Linear => AnyEnergy::Linear(Linear::new(lame)?),
        })
    }
}

impl fmt::Display for EnergyKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for EnergyKind {
    type Err = EnergyError;
    fn from_str(s: &str) -> Result<Self, EnergyError> {
        EnergyKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| EnergyError::UnknownName(s.to_owned()))
    }
}

/// With the `serde` feature an energy kind is written as its name (`"neo-hookean"`); reading an
/// unknown name fails with the [`EnergyError::UnknownName`] message, which lists the valid ones.
#[cfg(feature = "serde")]
impl serde::Serialize for EnergyKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for EnergyKind {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = <String as serde::Deserialize>::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

/// Errors raised when choosing or building an energy.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EnergyError {
    /// The name is not one of [`EnergyKind::ALL`].
    #[error(
        "unknown energy `{0}` (expected one of: stvk, corotational, neo-hookean, stable-neo-hookean, linear)"
    )]
    UnknownName(String),
    /// The Lamé parameters are outside the energy's domain.
    #[error("{energy}: {message}")]
    Parameters {
        /// Energy name.
        energy: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// Any of the built-in energies, chosen at run time.
///
/// It implements [`Energy`] by a `match` per call. Hot loops should instead be monomorphised
/// with [`dispatch_energy!`](crate::dispatch_energy), which hands the concrete type to a
/// generic body.
#[derive(Clone, Debug)]
pub enum AnyEnergy {
    /// See [`Stvk`].
    Stvk(Stvk),
    /// See [`Corotational`].
    Corotational(Corotational),
    /// See [`NeoHookean`].
    NeoHookean(NeoHookean),
    /// See [`StableNeoHookean`].
    StableNeoHookean(StableNeoHookean),
    /// See [`Linear`].
    Linear(Linear),
}

/// Run `$body` with `$e` bound to the concrete energy inside an [`AnyEnergy`], so generic code
/// is monomorphised once per energy instead of matching per element.
///
/// ```
/// use fem_core::{dispatch_energy, energy::{Energy, EnergyKind}, material::Material, PlaneModel};
/// let lame = Material::new(1000.0, 0.3, 1.0).unwrap().lame(PlaneModel::PlaneStrain);
/// let any = EnergyKind::NeoHookean.build(lame).unwrap();
/// let psi = dispatch_energy!(&any, e => e.psi(&nalgebra::Matrix2::identity()));
/// assert_eq!(psi, 0.0);
/// ```
#[macro_export]
macro_rules! dispatch_energy {
    ($any:expr, $e:ident => $body:expr) => {
        match $any {
            $crate::energy::AnyEnergy::Stvk($e) => $body,
            $crate::energy::AnyEnergy::Corotational($e) => $body,
            $crate::energy::AnyEnergy::NeoHookean($e) => $body,
            $crate::energy::AnyEnergy::StableNeoHookean($e) => $body,
            $crate::energy::AnyEnergy::Linear($e) => $body,
        }
    };
}

impl AnyEnergy {
    /// Which energy this is.
    pub fn kind(&self) -> EnergyKind {
        match self {
            AnyEnergy::Stvk(_) => EnergyKind::Stvk,
            AnyEnergy::Corotational(_) => EnergyKind::Corotational,
            AnyEnergy::NeoHookean(_) => EnergyKind::NeoHookean,
            AnyEnergy::StableNeoHookean(_) => EnergyKind::StableNeoHookean,
            AnyEnergy::Linear(_) => EnergyKind::Linear,
        }
    }
}

impl Energy for AnyEnergy {
    fn with_lame(&self, lame: Lame) -> Result<Self, EnergyError> {
        self.kind().build(lame)
    }

    fn name(&self) -> &'static str {
        self.kind().name()
    }
    fn psi(&self, f: &Mat2) -> Real {
        dispatch_energy!(self, e => e.psi(f))
    }
    fn pk1(&self, f: &Mat2) -> Mat2 {
        dispatch_energy!(self, e => e.pk1(f))
    }
    fn dpk1(&self, f: &Mat2) -> Mat4 {
        dispatch_energy!(self, e => e.dpk1(f))
    }
    fn dpk1_projected(&self, f: &Mat2) -> Mat4 {
        dispatch_energy!(self, e => e.dpk1_projected(f))
    }
    fn psi_pk1(&self, f: &Mat2) -> (Real, Mat2) {
        dispatch_energy!(self, e => e.psi_pk1(f))
    }
    fn pk1_corner_block(&self, f: &Mat2, g: &Vec2) -> (Mat2, Mat2) {
        dispatch_energy!(self, e => e.pk1_corner_block(f, g))
    }
    fn cauchy_zz(&self, f: &Mat2) -> Real {
        dispatch_energy!(self, e => e.cauchy_zz(f))
    }
    fn volumetric(&self) -> Volumetric {
        dispatch_energy!(self, e => e.volumetric())
    }
    fn cauchy(&self, f: &Mat2) -> Mat2 {
        dispatch_energy!(self, e => e.cauchy(f))
    }
    fn pk1_lanes(&self, f: &Mat2Lanes) -> Mat2Lanes {
        dispatch_energy!(self, e => e.pk1_lanes(f))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_the_valid_ones() {
        for k in EnergyKind::ALL {
            assert_eq!(k.name().parse::<EnergyKind>().unwrap(), k);
        }
        let err = "neohookean".parse::<EnergyKind>().unwrap_err().to_string();
        assert!(err.contains("`neohookean`") && err.contains("stable-neo-hookean"));
    }

    #[test]
    fn projection_clamps_negative_eigenvalues_only() {
        let m = Mat4::from_diagonal(&crate::math::Vec4::new(2.0, -1.0, 3.0, 0.5));
        let p = project_psd(&m);
        assert_eq!(
            p,
            Mat4::from_diagonal(&crate::math::Vec4::new(2.0, 0.0, 3.0, 0.5))
        );
        let spd = Mat4::identity() * 4.0;
        assert_eq!(project_psd(&spd), spd);
    }
}
