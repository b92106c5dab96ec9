//! The `[solver]` table: which solver, the time step, the step count, and the parameters of
//! every solver of the registry.
//!
//! The table is flat: `kind`, `dt` and `steps`, then the parameter keys of any solver
//! (`damping`, `iterations`, `xpbd_form`, `tolerance`, ...; each solver's keys are the serde
//! names of its parameter struct in `fem-solvers`, listed in `docs/solvers.md`). A key that no
//! solver knows is an error; a key of another solver than `kind` is kept, so that a scene run
//! under another solver (`--solver pbd`, a comparison) uses it. Each solver's parameters are
//! therefore held typed, one struct per solver, all read from the same table; a key shared by
//! several solvers (`damping`) has one value in all of them.
//!
//! Nothing here names a solver: the list, the keys and the rules come from
//! [`fem_solvers::SolverKind`] and [`fem_solvers::SolverParams`].

use fem_solvers::{SolverError, SolverKind, SolverParams};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Keys of the table that are not a solver parameter.
const RUN_KEYS: [&str; 3] = ["kind", "dt", "steps"];

/// The `[solver]` table, typed.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverSpec {
    /// Which solver runs the scene. Default: [`SolverKind::default`] (explicit).
    pub kind: SolverKind,
    /// Time step, s (> 0). A load-stepping solver does not use it, but prescribed motions are
    /// timed by `dt * steps`.
    pub dt: f64,
    /// Number of steps (>= 1).
    pub steps: u64,
    /// The parameters of every solver, in [`SolverKind::ALL`] order.
    params: Vec<SolverParams>,
}

impl SolverSpec {
    /// `kind` with time step `dt`, `steps` steps and every solver's default parameters.
    pub fn new(kind: SolverKind, dt: f64, steps: u64) -> Self {
        SolverSpec {
            kind,
            dt,
            steps,
            params: SolverKind::ALL.iter().map(|k| k.default_params()).collect(),
        }
    }

    /// The parameters of the chosen solver, with the spec's time step.
    pub fn params(&self) -> SolverParams {
        self.params_of(self.kind)
    }

    /// The parameters of solver `kind`, with the spec's time step.
    pub fn params_of(&self, kind: SolverKind) -> SolverParams {
        let mut p = self.params[index(kind)].clone();
        p.set_dt(self.dt);
        p
    }

    /// Mutable access to the parameters of solver `kind` (its time step is overwritten by
    /// [`SolverSpec::dt`] when read through [`SolverSpec::params`]).
    pub fn params_mut(&mut self, kind: SolverKind) -> &mut SolverParams {
        &mut self.params[index(kind)]
    }

    /// The value of parameter `key` of the chosen solver (`None` when it has no such key).
    pub fn get(&self, key: &str) -> Option<toml::Value> {
        to_table(&self.params()).remove(key)
    }

    /// Whether solver `kind` has a parameter named `key` (a key of the flat table).
    pub fn accepts(kind: SolverKind, key: &str) -> bool {
        parameter_keys(kind).iter().any(|k| k == key)
    }

    /// Set parameter `key` to `value` in every solver that has it (`set("iterations", 20)`):
    /// the typed edit of a comparison's variants. `kind`, `dt` and `steps` are set too. Errors
    /// when no solver has the key or the value does not fit its type; the values are not
    /// range-checked here ([`SolverSpec::validate`] does).
    pub fn set(&mut self, key: &str, value: impl Into<toml::Value>) -> Result<(), String> {
        let value = value.into();
        match key {
            "kind" => {
                self.kind = value
                    .try_into()
                    .map_err(|e: toml::de::Error| format!("solver.kind: {}", e.message().trim()))?;
                return Ok(());
            }
            "dt" => {
                self.dt = value
                    .as_float()
                    .or(value.as_integer().map(|i| i as f64))
                    .ok_or_else(|| format!("solver.dt = {value}: must be a number"))?;
                return Ok(());
            }
            "steps" => {
                self.steps = value
                    .as_integer()
                    .and_then(|i| u64::try_from(i).ok())
                    .ok_or_else(|| format!("solver.steps = {value}: must be an integer >= 0"))?;
                return Ok(());
            }
            _ => {}
        }
        let mut found = false;
        for (kind, params) in SolverKind::ALL.iter().zip(&mut self.params) {
            let mut table = to_table(params);
            if !table.contains_key(key) {
                continue;
            }
            found = true;
            table.insert(key.to_owned(), value.clone());
            *params = from_table(*kind, table).map_err(|e| format!("solver.{e}"))?;
        }
        if found {
            Ok(())
        } else {
            Err(format!(
                "solver.{key}: no solver has this parameter (known: {})",
                all_keys().join(", ")
            ))
        }
    }

    /// The steps the run plans: [`SolverSpec::steps`], or for a load-stepping solver its
    /// nominal load increments (its `load_steps`).
    pub fn planned_steps(&self) -> u64 {
        match self.kind.capabilities().clock {
            fem_solvers::Clock::Time => self.steps,
            fem_solvers::Clock::LoadFactor => to_table(&self.params())
                .get("load_steps")
                .and_then(toml::Value::as_integer)
                .and_then(|n| u64::try_from(n).ok())
                .unwrap_or(1),
        }
    }

    /// Check every solver's parameters by its own rules (fields named `solver.<key>`).
    pub fn validate(&self) -> Result<(), SolverError> {
        for kind in SolverKind::ALL {
            self.params_of(kind).validate_as("solver")?;
        }
        Ok(())
    }
}

fn index(kind: SolverKind) -> usize {
    SolverKind::ALL
        .iter()
        .position(|k| *k == kind)
        .expect("every kind is in ALL")
}

/// A solver's parameters as a TOML table (its serde field names).
fn to_table(params: &SolverParams) -> toml::Table {
    match toml::Value::try_from(params) {
        Ok(toml::Value::Table(t)) => t,
        // Parameter structs are plain numbers, counts and names: always a table.
        _ => toml::Table::new(),
    }
}

/// A solver's parameters from a table of its own keys; errors start with the key.
fn from_table(kind: SolverKind, table: toml::Table) -> Result<SolverParams, String> {
    let value = toml::Value::Table(table);
    let mut track = serde_path_to_error::Track::new();
    let de = serde_path_to_error::Deserializer::new(value, &mut track);
    SolverParams::deserialize_as(kind, de).map_err(|e: toml::de::Error| {
        let path = track.path().to_string();
        let message = e.message().trim().replace('\n', " ");
        if path == "." || path.is_empty() {
            message
        } else {
            format!("{path}: {message}")
        }
    })
}

/// The flat keys of solver `kind` (its parameter struct's serde names).
fn parameter_keys(kind: SolverKind) -> Vec<String> {
    to_table(&kind.default_params()).keys().cloned().collect()
}

/// `kind`, `dt`, `steps`, then every solver's keys in registry order, each once.
fn all_keys() -> Vec<String> {
    let mut keys: Vec<String> = RUN_KEYS.iter().map(|k| (*k).to_owned()).collect();
    for kind in SolverKind::ALL {
        for k in parameter_keys(kind) {
            if !keys.contains(&k) {
                keys.push(k);
            }
        }
    }
    keys
}

impl Serialize for SolverSpec {
    /// `kind`, `dt`, `steps`, then every solver's parameters (each key once; a solver's own
    /// `dt` is the spec's).
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut table = toml::Table::new();
        table.insert("kind".into(), self.kind.name().into());
        table.insert("dt".into(), self.dt.into());
        table.insert(
            "steps".into(),
            toml::Value::Integer(i64::try_from(self.steps).unwrap_or(i64::MAX)),
        );
        for params in &self.params {
            for (k, v) in to_table(params) {
                table.entry(k).or_insert(v);
            }
        }
        table.serialize(serializer)
    }
}

impl<'de> Deserialize<'de> for SolverSpec {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let mut table = toml::Table::deserialize(deserializer)?;
        let known = all_keys();
        if let Some(unknown) = table.keys().find(|k| !known.contains(k)) {
            let expected: Vec<String> = known.iter().map(|k| format!("`{k}`")).collect();
            return Err(D::Error::custom(format!(
                "{unknown}: unknown field `{unknown}`, expected one of {}",
                expected.join(", ")
            )));
        }
        let kind = match table.remove("kind") {
            None => SolverKind::default(),
            Some(v) => v.try_into().map_err(|e: toml::de::Error| {
                D::Error::custom(format!("kind: {}", e.message().trim()))
            })?,
        };
        let dt = match table.remove("dt") {
            None => return Err(D::Error::custom("missing field `dt`")),
            Some(toml::Value::Float(f)) => f,
            Some(toml::Value::Integer(i)) => i as f64,
            Some(other) => {
                return Err(D::Error::custom(format!(
                    "dt: invalid type: {}, expected a number",
                    other.type_str()
                )));
            }
        };
        let steps = match table.remove("steps") {
            None => return Err(D::Error::custom("missing field `steps`")),
            Some(toml::Value::Integer(i)) if i >= 0 => i as u64,
            Some(other) => {
                return Err(D::Error::custom(format!(
                    "steps: invalid value: {other}, expected an integer >= 0"
                )));
            }
        };
        let mut params = Vec::with_capacity(SolverKind::ALL.len());
        for kind in SolverKind::ALL {
            let keys = parameter_keys(kind);
            let own: toml::Table = table
                .iter()
                .filter(|(k, _)| keys.contains(k))
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect();
            params.push(from_table(kind, own).map_err(D::Error::custom)?);
        }
        Ok(SolverSpec {
            kind,
            dt,
            steps,
            params,
        })
    }
}
