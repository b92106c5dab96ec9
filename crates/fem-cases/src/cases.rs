//! The built-in cases A-D: their scene files (`fixtures/scenes/`) compiled into the binary, so
//! `fem2d run case-a` works from any directory, and the resolution of a
//! "case name or scene file" argument.

use std::path::Path;

use crate::error::CaseError;
use crate::scene::{LoadedScene, load_scene_file, parse_scene};

/// The built-in case names and their scene files' text.
pub const CASES: [(&str, &str); 4] = [
    (
        "case-a",
        include_str!("../../../fixtures/scenes/case-a.toml"),
    ),
    (
        "case-b",
        include_str!("../../../fixtures/scenes/case-b.toml"),
    ),
    (
        "case-c",
        include_str!("../../../fixtures/scenes/case-c.toml"),
    ),
    (
        "case-d",
        include_str!("../../../fixtures/scenes/case-d.toml"),
    ),
];

/// The text of built-in case `name`.
pub fn case_text(name: &str) -> Option<&'static str> {
    CASES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// Load a built-in case by name with overrides.
pub fn load_case(name: &str, overrides: &[String]) -> Result<LoadedScene, CaseError> {
    let text = case_text(name).ok_or_else(|| {
        CaseError::Usage(format!(
            "unknown case `{name}` (expected one of: case-a, case-b, case-c, case-d)"
        ))
    })?;
    parse_scene(text, &format!("built-in {name}"), Path::new("."), overrides)
}

/// A case name (`case-a`..`case-d`) or the path of a scene file.
pub fn load_case_or_file(arg: &str, overrides: &[String]) -> Result<LoadedScene, CaseError> {
    if case_text(arg).is_some() {
        load_case(arg, overrides)
    } else if Path::new(arg).exists() || arg.ends_with(".toml") {
        load_scene_file(Path::new(arg), overrides)
    } else {
        Err(CaseError::Usage(format!(
            "`{arg}` is neither a case (case-a, case-b, case-c, case-d) nor an existing scene file"
        )))
    }
}
