//! The one error type of scenes and runs (also used by the studies and the command built on
//! them): every variant carries a complete one-line message that names the file (or scene),
//! the field and the value.

use std::fmt;

use fem_solvers::SolverError;

/// An error of a scene, a run or a command; `Display` is the one-line message.
///
/// The errors of the crates below convert into it (`From`): [`SolverError`] (a blow-up becomes
/// [`SceneError::BlowUp`]), fem-mesh's and fem-core's errors. The conversions keep the message
/// but cannot add the scene's file name; the scene functions of this crate add it themselves.
/// New variants may be added.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum SceneError {
    /// A scene file is malformed or a value is out of range.
    Scene(String),
    /// A file (or, without a file system, a named mesh or model) could not be read or written.
    Io(String),
    /// The mesh could not be built (pipeline or mesh file).
    Mesh(String),
    /// The model or the solver rejected its input.
    Solver(String),
    /// The run blew up (non-finite or runaway state); the message names the step.
    BlowUp(String),
    /// A command-line argument is invalid.
    Usage(String),
}

impl SceneError {
    /// The message.
    pub fn message(&self) -> &str {
        match self {
            SceneError::Scene(m)
            | SceneError::Io(m)
            | SceneError::Mesh(m)
            | SceneError::Solver(m)
            | SceneError::BlowUp(m)
            | SceneError::Usage(m) => m,
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Messages from dependencies can span lines; the contract is one line.
        f.write_str(&self.message().replace('\n', " "))
    }
}

impl std::error::Error for SceneError {}

impl From<SolverError> for SceneError {
    fn from(e: SolverError) -> Self {
        match e {
            SolverError::NonFinite { .. }
            | SolverError::NonFiniteBody { .. }
            | SolverError::NonFiniteRigid { .. } => SceneError::BlowUp(e.to_string()),
            _ => SceneError::Solver(e.to_string()),
        }
    }
}

impl From<fem_mesh::MeshError> for SceneError {
    fn from(e: fem_mesh::MeshError) -> Self {
        SceneError::Mesh(e.to_string())
    }
}

impl From<fem_core::mesh::MeshError> for SceneError {
    fn from(e: fem_core::mesh::MeshError) -> Self {
        SceneError::Mesh(format!("mesh: {e}"))
    }
}

impl From<fem_core::MaterialError> for SceneError {
    fn from(e: fem_core::MaterialError) -> Self {
        SceneError::Scene(e.to_string())
    }
}

impl From<fem_core::energy::EnergyError> for SceneError {
    fn from(e: fem_core::energy::EnergyError) -> Self {
        SceneError::Scene(e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_of_the_crates_below_convert_with_their_message() {
        let blow_up = SolverError::NonFiniteBody { step: 3, body: 1 };
        assert_eq!(
            SceneError::from(blow_up.clone()),
            SceneError::BlowUp(blow_up.to_string())
        );
        let bad = SolverError::invalid("explicit.dt", -1, "must be a finite number > 0");
        assert_eq!(
            SceneError::from(bad).to_string(),
            "explicit.dt = -1: must be a finite number > 0"
        );
        let material = fem_core::Material::new(-1.0, 0.3, 1.0).unwrap_err();
        assert_eq!(
            SceneError::from(material).to_string(),
            "material.youngs_modulus = -1: must be a finite number > 0 (Pa)"
        );
        let mesh = fem_core::mesh::Mesh::from_arrays(&[], &[]).unwrap_err();
        assert!(matches!(SceneError::from(mesh), SceneError::Mesh(m) if m.starts_with("mesh: ")));
        let pipeline = fem_mesh::MeshError::invalid("simplify", "epsilon too large");
        assert_eq!(
            SceneError::from(pipeline),
            SceneError::Mesh("simplify: epsilon too large".into())
        );
    }
}
