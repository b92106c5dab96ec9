//! The one list of solvers: their names, capabilities, parameters and steppers, chosen at run
//! time.
//!
//! Each solver is one stepper type implementing [`Solver`] in its own file (its name, its
//! [`Capabilities`], its parameter struct with validation, and how to build it). The
//! `registry!` invocation below lists them, one line each, and generates from that list:
//! - [`SolverKind`]: the solvers by name ([`SolverKind::ALL`] in table order, [`FromStr`],
//!   [`Display`](fmt::Display), serde as the name string);
//! - [`SolverParams`]: any solver's parameters (validation with field names, `dt`, building
//!   the stepper, serde as the inner struct's fields);
//! - [`AnyStepper`]: any solver's stepper behind [`Stepper`], each `match` dispatching to the
//!   concrete type so its kernels stay monomorphised.
//!
//! This is the pattern of `fem_core::energy` (`EnergyKind`, `AnyEnergy`, `dispatch_energy!`).
//! Adding a solver takes its own file, one line in the list, and regenerating the capability
//! table of `docs/solvers.md` ([`capability_table`]); a test fails until each is done, and the
//! stepper battery (`tests/suite/battery.rs`) fails until the new name is added to it.

use std::fmt;
use std::fmt::Write as _;
use std::str::FromStr;

use fem_core::energy::Energy;
use fem_core::math::Real;

use super::Stepper;
use super::integrator::Integrator;
use crate::error::SolverError;
use crate::model::Model;
use crate::model::state::State;
use crate::steppers::report::StepReport;

/// What a state's clock [`State::t`] counts under a solver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Clock {
    /// Simulated time, s.
    Time,
    /// The load factor, from 0 (no load) to exactly 1 (the full load): quasi-static solvers.
    LoadFactor,
}

impl Clock {
    /// `time` or `load factor`.
    pub fn name(self) -> &'static str {
        match self {
            Clock::Time => "time",
            Clock::LoadFactor => "load factor",
        }
    }
}

/// What a solver is and can do: one row of the capability table ([`capability_table`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Capabilities {
    /// Display name in pictures and reports (`Explicit FEM`, `XPBD`).
    pub title: &'static str,
    /// One line: what it is.
    pub summary: &'static str,
    /// One of the paper's frameworks (explicit, PBD, XPBD); the others go beyond it.
    pub paper: bool,
    /// Handles a ground and rigid obstacles.
    pub contact: bool,
    /// Moves free rigid regions (bones, [`crate::rigid::body`]); a solver without it refuses
    /// a model with a free rigid body when it is built (pinned and scheduled bodies are
    /// kinematic vertices to every solver).
    pub rigid_regions: bool,
    /// Supports the averaged nodal pressure triangle ([`fem_core::nodal_pressure`],
    /// [`Model::set_averaged_pressure`]); a solver without it refuses such a model when it is
    /// built.
    pub averaged_pressure: bool,
    /// The largest dimension it runs in: 2, or 3 when it has a dimension-generic path
    /// ([`crate::nd`]) that steps tetrahedral meshes (without contact or rigid regions).
    pub dims: u8,
    /// Implicit in time.
    pub implicit: bool,
    /// Has an iteration-count parameter `iterations`.
    pub iterations: bool,
    /// Has a `substeps` parameter.
    pub substeps: bool,
    /// Needs a sparse factorisation.
    pub factorisation: bool,
    /// Bit-identical states for any number of rayon threads (checked by the stepper battery).
    pub deterministic_across_threads: bool,
    /// What [`State::t`] counts.
    pub clock: Clock,
    /// What it converges to, and under what refinement.
    pub converges_to: &'static str,
}

/// With the `serde` feature: `Serialize` and `DeserializeOwned`, which every solver's
/// parameter struct implements. Without it: no requirement.
#[cfg(feature = "serde")]
pub trait ParamsSerde: serde::Serialize + serde::de::DeserializeOwned {}
#[cfg(feature = "serde")]
impl<T: serde::Serialize + serde::de::DeserializeOwned> ParamsSerde for T {}

/// With the `serde` feature: `Serialize` and `DeserializeOwned`, which every solver's
/// parameter struct implements. Without it: no requirement.
#[cfg(not(feature = "serde"))]
pub trait ParamsSerde {}
#[cfg(not(feature = "serde"))]
impl<T> ParamsSerde for T {}

/// A solver the registry can list: a stepper with a name, capabilities and a parameter struct.
///
/// Implemented in each solver's own file; the registry knows nothing else about it.
pub trait Solver: Stepper + Sized {
    /// The parameters. With the `serde` feature their field names are the scene's `[solver]`
    /// keys; a key several solvers share has the same meaning and default in each.
    type Params: Clone + fmt::Debug + Default + PartialEq + ParamsSerde;
    /// The name on the command line and in files (lower case).
    const NAME: &'static str;
    /// Its row of the capability table.
    const CAPABILITIES: Capabilities;
    /// Check every field; errors name `<prefix>.<field>` with the serde field name.
    fn validate_params(p: &Self::Params, prefix: &str) -> Result<(), SolverError>;
    /// Build the stepper for `model` (validating the parameters with the solver's name).
    fn build<E: Energy>(model: &Model<E>, p: &Self::Params) -> Result<Self, SolverError>;
    /// The time step field, if the solver has one (a [`Clock::LoadFactor`] solver has none).
    fn dt_mut(p: &mut Self::Params) -> Option<&mut Real>;
    /// The time integrator field, if the solver minimises an incremental potential and can
    /// take BDF2 steps ([`Integrator`]); `None` by default.
    fn integrator_mut(_p: &mut Self::Params) -> Option<&mut Integrator> {
        None
    }
    /// A warning to show before a run (the explicit stability check); `None` by default.
    fn time_step_warning(&self) -> Option<String> {
        None
    }
}

/// The solvers' names, comma-separated in table order (for error messages).
pub(crate) fn solver_names() -> String {
    SolverKind::ALL.map(SolverKind::name).join(", ")
}

/// Number of entries of a list, as a constant.
macro_rules! count {
    ($($x:ident)*) => {
        [$(stringify!($x)),*].len()
    };
}

/// Generate [`SolverKind`], [`SolverParams`], [`AnyStepper`] and every dispatch from the list
/// `Variant => stepper type`, one line per solver, in table order (the first is the default).
macro_rules! registry {
    ($($variant:ident => $ty:path),+ $(,)?) => {
        /// A solver, by name. [`SolverKind::ALL`] lists them in table order; the first
        /// (explicit) is the default.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[non_exhaustive]
        pub enum SolverKind {
            $(
                #[doc = concat!("See [`", stringify!($ty), "`].")]
                $variant,
            )+
        }

        impl SolverKind {
            /// Every solver, in table order.
            pub const ALL: [SolverKind; $crate::steppers::registry::count!($($variant)+)] = [$(SolverKind::$variant),+];

            /// The name on the command line and in files (`explicit`, `pbd`, ...).
            pub fn name(self) -> &'static str {
                match self {
                    $(SolverKind::$variant => <$ty as Solver>::NAME,)+
                }
            }

            /// What the solver is and can do.
            pub fn capabilities(self) -> &'static Capabilities {
                match self {
                    $(SolverKind::$variant => &<$ty as Solver>::CAPABILITIES,)+
                }
            }

            /// The solver's default parameters.
            pub fn default_params(self) -> SolverParams {
                match self {
                    $(SolverKind::$variant => SolverParams::$variant(Default::default()),)+
                }
            }
        }

        /// The parameters of any solver.
        ///
        /// With the `serde` feature it serialises as the inner struct's fields alone
        /// (untagged); read it with `SolverParams::deserialize_as`, given the kind.
        #[derive(Clone, Debug, PartialEq)]
        #[non_exhaustive]
        pub enum SolverParams {
            $(
                #[doc = concat!("Parameters of [`", stringify!($ty), "`].")]
                $variant(<$ty as Solver>::Params),
            )+
        }

        impl SolverParams {
            /// Which solver these parameters are for.
            pub fn kind(&self) -> SolverKind {
                match self {
                    $(SolverParams::$variant(_) => SolverKind::$variant,)+
                }
            }

            /// Check every field; errors name `<solver name>.<field>` (`pbd.iterations`).
            pub fn validate(&self) -> Result<(), SolverError> {
                self.validate_as(self.kind().name())
            }

            /// Check every field; errors name `<prefix>.<field>` (a scene passes `solver`:
            /// `solver.iterations = 0: must be at least 1`).
            pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
                match self {
                    $(SolverParams::$variant(p) => <$ty as Solver>::validate_params(p, prefix),)+
                }
            }

            /// The time step, s; `None` for a solver without one (static).
            pub fn dt(&self) -> Option<Real> {
                match self {
                    $(SolverParams::$variant(p) => <$ty as Solver>::dt_mut(&mut p.clone()).map(|dt| *dt),)+
                }
            }

            /// Set the time step, s; does nothing for a solver without one (static).
            pub fn set_dt(&mut self, dt: Real) {
                match self {
                    $(SolverParams::$variant(p) => {
                        if let Some(field) = <$ty as Solver>::dt_mut(p) {
                            *field = dt;
                        }
                    })+
                }
            }

            /// The time integrator; `None` for a solver without the choice (explicit,
            /// position-based, static).
            pub fn integrator(&self) -> Option<$crate::steppers::integrator::Integrator> {
                match self {
                    $(SolverParams::$variant(p) => <$ty as Solver>::integrator_mut(&mut p.clone()).map(|i| *i),)+
                }
            }

            /// Set the time integrator; returns whether the solver has the choice (does
            /// nothing otherwise).
            pub fn set_integrator(&mut self, integrator: $crate::steppers::integrator::Integrator) -> bool {
                match self {
                    $(SolverParams::$variant(p) => match <$ty as Solver>::integrator_mut(p) {
                        Some(field) => {
                            *field = integrator;
                            true
                        }
                        None => false,
                    },)+
                }
            }

            /// Validate (fields named after the solver) and build the stepper for `model`. A
            /// solver that does not move rigid regions refuses a model with a free rigid body.
            pub fn build<E: Energy>(&self, model: &Model<E>) -> Result<AnyStepper, SolverError> {
                self.validate()?;
                Ok(match self {
                    $(SolverParams::$variant(p) => {
                        if !<$ty as Solver>::CAPABILITIES.rigid_regions {
                            $crate::steppers::refuse_free_rigid_bodies(model, <$ty as Solver>::NAME)?;
                        }
                        if !<$ty as Solver>::CAPABILITIES.averaged_pressure {
                            $crate::steppers::refuse_averaged_pressure(model, <$ty as Solver>::NAME)?;
                        }
                        AnyStepper::$variant(Box::new(<$ty as Solver>::build(model, p)?))
                    })+
                })
            }

            /// Read the parameters of solver `kind` from `d` (a map of its fields; missing
            /// fields take their defaults, fields of other solvers are ignored).
            #[cfg(feature = "serde")]
            pub fn deserialize_as<'de, D: serde::Deserializer<'de>>(
                kind: SolverKind,
                d: D,
            ) -> Result<SolverParams, D::Error> {
                Ok(match kind {
                    $(SolverKind::$variant => SolverParams::$variant(
                        <<$ty as Solver>::Params as serde::Deserialize>::deserialize(d)?,
                    ),)+
                })
            }
        }

        #[cfg(feature = "serde")]
        impl serde::Serialize for SolverParams {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                match self {
                    $(SolverParams::$variant(p) => p.serialize(s),)+
                }
            }
        }

        /// Any solver's stepper, chosen at run time ([`SolverParams::build`]). Each call
        /// dispatches to the concrete stepper, whose kernels are monomorphised.
        #[derive(Debug)]
        #[non_exhaustive]
        pub enum AnyStepper {
            $(
                #[doc = concat!("See [`", stringify!($ty), "`].")]
                $variant(Box<$ty>),
            )+
        }

        impl AnyStepper {
            /// Which solver this is.
            pub fn kind(&self) -> SolverKind {
                match self {
                    $(AnyStepper::$variant(_) => SolverKind::$variant,)+
                }
            }

            /// A warning to show before a run: the explicit stepper's stability check when
            /// `dt` exceeds the critical time step or, for forward Euler, when the highest mode
            /// grows per step; `None` otherwise and for other solvers.
            pub fn time_step_warning(&self) -> Option<String> {
                match self {
                    $(AnyStepper::$variant(s) => <$ty as Solver>::time_step_warning(s),)+
                }
            }
        }

        impl Stepper for AnyStepper {
            fn dt(&self) -> Real {
                match self {
                    $(AnyStepper::$variant(s) => s.dt(),)+
                }
            }

            fn step<E: Energy>(
                &mut self,
                model: &Model<E>,
                state: &mut State,
            ) -> Result<StepReport, SolverError> {
                match self {
                    $(AnyStepper::$variant(s) => s.step(model, state),)+
                }
            }

            fn contacts(&self) -> &[crate::contact::Contact] {
                match self {
                    $(AnyStepper::$variant(s) => s.contacts(),)+
                }
            }
        }
    };
}

// Path-visible, so the registry test can extend the list (`registry_extension`).
#[allow(unused_imports)]
pub(crate) use {count, registry};

registry! {
    Explicit => crate::steppers::explicit::ExplicitStepper,
    Pbd => crate::steppers::position_based::PbdStepper,
    Xpbd => crate::steppers::position_based::XpbdStepper,
    Implicit => crate::steppers::implicit::ImplicitStepper,
    Static => crate::steppers::statics::StaticStepper,
    Vbd => crate::steppers::vbd::VbdStepper,
    Pd => crate::steppers::projective::PdStepper,
    QuasiNewton => crate::steppers::quasi_newton::QuasiNewtonStepper,
    LinearImplicit => crate::steppers::linear_implicit::LinearImplicitStepper,
}

impl Default for SolverKind {
    /// The first solver of the table (explicit).
    fn default() -> Self {
        SolverKind::ALL[0]
    }
}

impl fmt::Display for SolverKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for SolverKind {
    type Err = SolverError;
    fn from_str(s: &str) -> Result<Self, SolverError> {
        SolverKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| SolverError::UnknownSolver {
                name: s.to_owned(),
                expected: solver_names(),
            })
    }
}

/// With the `serde` feature a solver kind is written as its name (`"xpbd"`); reading an
/// unknown name fails with the [`SolverError::UnknownSolver`] message, which lists the valid
/// ones.
#[cfg(feature = "serde")]
impl serde::Serialize for SolverKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for SolverKind {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = <String as serde::Deserialize>::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

/// The capability table as markdown: one row per solver of [`SolverKind::ALL`]. The block
/// between the `capabilities` markers of `docs/solvers.md` is this text (a test keeps it so).
pub fn capability_table() -> String {
    let yes = |b: bool| if b { "yes" } else { "no" };
    let mut out = String::from(
        "| solver | summary | paper | contact | rigid regions | averaged pressure | 3D | implicit | iterations | substeps | factorisation | deterministic | clock | converges to |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for kind in SolverKind::ALL {
        let c = kind.capabilities();
        let _ = writeln!(
            out,
            "| `{}` | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            kind.name(),
            c.summary,
            yes(c.paper),
            yes(c.contact),
            yes(c.rigid_regions),
            yes(c.averaged_pressure),
            yes(c.dims >= 3),
            yes(c.implicit),
            yes(c.iterations),
            yes(c.substeps),
            yes(c.factorisation),
            yes(c.deterministic_across_threads),
            c.clock.name(),
            c.converges_to,
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_every_solver() {
        for kind in SolverKind::ALL {
            assert_eq!(kind.name().parse::<SolverKind>().unwrap(), kind);
            assert_eq!(kind.to_string(), kind.name());
            assert_eq!(kind.default_params().kind(), kind);
            assert_eq!(kind.default_params().validate(), Ok(()));
        }
        assert_eq!(SolverKind::default(), SolverKind::Explicit);
        assert_eq!(
            "rk4".parse::<SolverKind>().unwrap_err().to_string(),
            "unknown solver `rk4` (expected one of: explicit, pbd, xpbd, implicit, static, vbd, pd, quasi-newton, linear-implicit)"
        );
    }

    #[test]
    fn capabilities_agree_with_the_parameters() {
        for kind in SolverKind::ALL {
            let c = kind.capabilities();
            let params = kind.default_params();
            assert_eq!(
                params.dt().is_none(),
                c.clock == Clock::LoadFactor,
                "{kind}: a time step exactly when the clock is time"
            );
            assert!(!c.title.is_empty() && !c.summary.is_empty() && !c.converges_to.is_empty());
            assert!(!c.summary.contains('|') && !c.converges_to.contains('|'));
        }
    }

    #[test]
    fn set_dt_reaches_the_time_step_field() {
        for kind in SolverKind::ALL {
            let mut p = kind.default_params();
            p.set_dt(0.25);
            let expected = (kind.capabilities().clock == Clock::Time).then_some(0.25);
            assert_eq!(p.dt(), expected, "{kind}");
        }
    }

    /// A key shared by several solvers (`dt`, `damping`, `iterations`, `ordering`, `tolerance`,
    /// ...) means one thing in a scene's flat `[solver]` table, so its default must be the same
    /// under every solver that has it.
    #[cfg(feature = "serde")]
    #[test]
    fn shared_keys_have_one_default() {
        let mut seen: std::collections::BTreeMap<String, (SolverKind, serde_json::Value)> =
            Default::default();
        for kind in SolverKind::ALL {
            let value = serde_json::to_value(kind.default_params()).unwrap();
            let map = value.as_object().expect("parameters serialise as a map");
            assert!(!map.is_empty(), "{kind}");
            for (key, v) in map {
                match seen.get(key) {
                    Some((first, w)) => assert_eq!(
                        v, w,
                        "key `{key}`: default {v} under {kind} but {w} under {first}"
                    ),
                    None => {
                        seen.insert(key.clone(), (kind, v.clone()));
                    }
                }
            }
            // And they read back to the same parameters.
            let back = SolverParams::deserialize_as(kind, &value).unwrap();
            assert_eq!(back, kind.default_params(), "{kind}");
        }
        for key in [
            "dt",
            "damping",
            "iterations",
            "substeps",
            "ordering",
            "tolerance",
        ] {
            assert!(seen.contains_key(key), "{key}");
        }
    }

    #[cfg(feature = "serde")]
    #[test]
    fn kinds_serialise_as_names() {
        for kind in SolverKind::ALL {
            let text = serde_json::to_string(&kind).unwrap();
            assert_eq!(text, format!("\"{kind}\""));
            assert_eq!(serde_json::from_str::<SolverKind>(&text).unwrap(), kind);
        }
        let e = serde_json::from_str::<SolverKind>("\"rk4\"").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("unknown solver `rk4` (expected one of: explicit, pbd"),
            "{e}"
        );
    }
}
