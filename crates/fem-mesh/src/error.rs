//! The one error type of the crate: every failure is a one-line message that names the file (or
//! stage), the place (line, element, field) and the offending value.

use std::path::Path;

/// Everything that can go wrong between a 3D model file and a 2D mesh.
///
/// `Display` is always a single line, suitable as a command-line error message.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: String,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// A file was read but its contents are malformed.
    #[error("{path}: {location}: {message}")]
    Parse {
        /// The file concerned.
        path: String,
        /// Where in the file: `line 12`, `triangle 5`, `header`, ...
        location: String,
        /// What is wrong, including the offending value.
        message: String,
    },
    /// A parameter or an intermediate result is unusable (degenerate camera, collinear points,
    /// alpha too small, epsilon too large, ...).
    #[error("{stage}: {message}")]
    Invalid {
        /// The pipeline stage or parameter concerned (`camera`, `alpha shape`, `simplify`, ...).
        stage: &'static str,
        /// What is wrong, including the offending value.
        message: String,
    },
}

impl MeshError {
    /// A parse error at `location` (for example `line 7`) of the file at `path`.
    pub fn parse(path: &Path, location: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Parse {
            path: path.display().to_string(),
            location: location.into(),
            message: message.into(),
        }
    }

    /// An I/O error on the file at `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.display().to_string(),
            source,
        }
    }

    /// An invalid parameter or intermediate result in pipeline stage `stage`.
    pub fn invalid(stage: &'static str, message: impl Into<String>) -> Self {
        Self::Invalid {
            stage,
            message: message.into(),
        }
    }
}

/// Shorthand for results of this crate.
pub type Result<T, E = MeshError> = std::result::Result<T, E>;
