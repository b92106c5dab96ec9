//! The built-in cases A-D and case D's lower-leg close-up: their scene files (`crates/fem-scene/cases/`, linked from
//! `fixtures/scenes/`) compiled in, so `fem2d run case-a` works from any directory, a browser
//! needs no file, and the published crate carries them.

use std::path::Path;

use crate::error::SceneError;
use crate::scene::{LoadedScene, parse_scene};

/// The built-in case names and their scene files' text.
pub const CASES: [(&str, &str); 5] = [
    ("case-a", include_str!("../cases/case-a.toml")),
    ("case-b", include_str!("../cases/case-b.toml")),
    ("case-c", include_str!("../cases/case-c.toml")),
    ("case-d", include_str!("../cases/case-d.toml")),
    ("lower-leg", include_str!("../cases/lower-leg.toml")),
];

/// The text of built-in case `name`.
pub fn case_text(name: &str) -> Option<&'static str> {
    CASES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// Load a built-in case by name with overrides.
pub fn load_case(name: &str, overrides: &[String]) -> Result<LoadedScene, SceneError> {
    let text = case_text(name).ok_or_else(|| {
        SceneError::Usage(format!(
            "unknown case `{name}` (expected one of: {})",
            names().join(", ")
        ))
    })?;
    parse_scene(text, &format!("built-in {name}"), Path::new("."), overrides)
}

/// The built-in case names.
pub fn names() -> Vec<&'static str> {
    CASES.iter().map(|(n, _)| *n).collect()
}
