//! The registry's promise, tested: a new solver is its own file plus one line in the list.
//!
//! This module plays a developer adding a solver. [`TwoHalves`] is a real solver written the
//! way a new one is (a stepper implementing `Stepper` and `Solver`, its parameter struct with
//! serde names and one `validate`): each step is two explicit steps of `dt / 2`. Its "file" is
//! this module; its "line" is the last entry of the `registry!` invocation below, which is the
//! crate's own list plus that one line. The tests then use it through the generated registry
//! alone (by name, through `SolverParams` and `AnyStepper`), as scenes and tools do.

use fem_core::energy::Energy;
use fem_core::math::Real;
use serde::{Deserialize, Serialize};

use super::Stepper;
use super::explicit::{ExplicitParams, ExplicitStepper};
use super::report::StepReport;
use crate::error::SolverError;
use crate::model::Model;
use crate::model::state::State;
use crate::steppers::registry::{Capabilities, Clock, Solver};

/// Parameters of [`TwoHalves`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TwoHalvesParams {
    /// Time step, s (two explicit steps of half of it). Default `1e-3`.
    pub dt: Real,
    /// Velocity damping rate, 1/s. Default 0.
    pub damping: Real,
}

impl Default for TwoHalvesParams {
    fn default() -> Self {
        TwoHalvesParams {
            dt: 1e-3,
            damping: 0.0,
        }
    }
}

/// Two explicit (symplectic Euler) steps of `dt / 2` per step.
#[derive(Clone, Debug)]
pub struct TwoHalves {
    dt: Real,
    half: ExplicitStepper,
}

impl Stepper for TwoHalves {
    fn dt(&self) -> Real {
        self.dt
    }

    fn step<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError> {
        let step = state.step;
        self.half.step(model, state)?;
        let report = self.half.step(model, state)?;
        state.step = step + 1;
        Ok(report)
    }
}

impl Solver for TwoHalves {
    type Params = TwoHalvesParams;
    const NAME: &'static str = "two-halves";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "Two half steps",
        summary: "two explicit steps of dt / 2 per step (a solver added in a test)",
        paper: false,
        contact: true,
        rigid_regions: false,
        averaged_pressure: false,
        dims: 2,
        implicit: false,
        iterations: false,
        substeps: false,
        factorisation: false,
        deterministic_across_threads: true,
        clock: Clock::Time,
        converges_to: "explicit FEM at dt / 2",
    };

    fn validate_params(p: &TwoHalvesParams, prefix: &str) -> Result<(), SolverError> {
        ExplicitParams {
            dt: p.dt,
            damping: p.damping,
            ..ExplicitParams::default()
        }
        .validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &TwoHalvesParams) -> Result<Self, SolverError> {
        let half = ExplicitStepper::new(
            model,
            ExplicitParams {
                dt: p.dt / 2.0,
                damping: p.damping,
                ..ExplicitParams::default()
            },
        )?;
        Ok(TwoHalves { dt: p.dt, half })
    }

    fn dt_mut(p: &mut TwoHalvesParams) -> Option<&mut Real> {
        Some(&mut p.dt)
    }
}

/// The crate's registry list, plus one line (not every generated method is used here).
#[allow(dead_code)]
mod extended {
    use fem_core::energy::Energy;
    use fem_core::math::Real;

    use crate::error::SolverError;
    use crate::model::Model;
    use crate::model::state::State;
    use crate::steppers::Stepper;
    use crate::steppers::registry::{Capabilities, Solver};
    use crate::steppers::report::StepReport;

    crate::steppers::registry::registry! {
        Explicit => crate::steppers::explicit::ExplicitStepper,
        Pbd => crate::steppers::position_based::PbdStepper,
        Xpbd => crate::steppers::position_based::XpbdStepper,
        Implicit => crate::steppers::implicit::ImplicitStepper,
        Static => crate::steppers::statics::StaticStepper,
        Vbd => crate::steppers::vbd::VbdStepper,
        Pd => crate::steppers::projective::PdStepper,
        QuasiNewton => crate::steppers::quasi_newton::QuasiNewtonStepper,
        LinearImplicit => crate::steppers::linear_implicit::LinearImplicitStepper,
        TwoHalves => crate::steppers::registry_extension::TwoHalves,
    }
}

#[cfg(test)]
mod tests {
    use super::extended::{SolverKind, SolverParams};
    use crate::model::Model;
    use crate::model::state::State;
    use crate::steppers::Stepper;
    use crate::testing::beam_mesh;
    use fem_core::PlaneModel;
    use fem_core::energy::NeoHookean;
    use fem_core::material::Material;

    fn model() -> Model<NeoHookean> {
        let lame = Material::new(1000.0, 0.3, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain);
        let mut model = Model::with_total_mass(
            beam_mesh(10, 2).unwrap(),
            NeoHookean::new(lame).unwrap(),
            1.0,
        )
        .unwrap();
        model.set_standard_gravity();
        model
    }

    #[test]
    fn one_line_adds_the_solver_to_the_names_the_parameters_and_the_steppers() {
        assert_eq!(
            SolverKind::ALL.len(),
            crate::steppers::registry::SolverKind::ALL.len() + 1
        );
        let kind = *SolverKind::ALL.last().unwrap();
        assert_eq!(kind.name(), "two-halves");
        assert!(!kind.capabilities().implicit);
        // Its parameters from a table of scene keys (other solvers' keys are ignored).
        let table = serde_json::json!({"dt": 2e-3, "damping": 0.5, "iterations": 7});
        let params = SolverParams::deserialize_as(kind, table).unwrap();
        assert_eq!(params.kind(), kind);
        assert_eq!(params.dt(), Some(2e-3));
        // Its own validation, with the scene's field names.
        let mut bad = params.clone();
        bad.set_dt(-1.0);
        let e = bad.validate_as("solver").unwrap_err().to_string();
        assert!(e.starts_with("solver.dt = -1"), "{e}");
        // Built and stepped through the registry alone.
        let model = model();
        let mut stepper = params.build(&model).unwrap();
        assert_eq!(stepper.kind(), kind);
        assert_eq!(stepper.dt(), 2e-3);
        let mut state = State::at_rest(&model);
        for _ in 0..10 {
            stepper.step(&model, &mut state).unwrap();
        }
        assert_eq!(state.step, 10);
        // Free fall at first: ten steps of 2 ms in twenty symplectic half steps of 1 ms
        // fall g h^2 n(n+1)/2 with h = 1 ms, n = 20 (damped by exp(-0.5 t)).
        let fall = -9.8 * 1e-6 * 20.0 * 21.0 / 2.0;
        let y = state
            .x
            .iter()
            .zip(model.mesh().vertices())
            .map(|(x, x0)| x.y - x0.y);
        for dy in y {
            assert!((dy - fall).abs() < 0.05 * fall.abs(), "{dy} vs {fall}");
        }
    }

    #[test]
    fn the_crates_own_solvers_keep_their_names_and_order() {
        let names: Vec<&str> = SolverKind::ALL.iter().map(|k| k.name()).collect();
        let own: Vec<&str> = crate::steppers::registry::SolverKind::ALL
            .iter()
            .map(|k| k.name())
            .collect();
        assert_eq!(&names[..own.len()], &own[..]);
    }
}
