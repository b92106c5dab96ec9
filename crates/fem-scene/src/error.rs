//! The one error type of scenes and runs (also used by the studies and the command built on
//! them): every variant carries a complete one-line message that names the file (or scene),
//! the field and the value.

use std::fmt;

/// An error of a scene, a run or a command; `Display` is the one-line message.
#[derive(Clone, Debug, PartialEq)]
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
