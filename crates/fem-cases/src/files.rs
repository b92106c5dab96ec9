//! Scenes and meshes from the file system: reading a scene file, resolving a "case name or
//! scene file" argument, and the [`FileSource`] that gives `fem-scene` the bytes of the mesh
//! and model files a scene names (relative to the scene file's directory).

use std::path::{Path, PathBuf};

use fem_scene::SceneError;
use fem_scene::build::MeshSource;
use fem_scene::cases::{case_text, load_case, names};
use fem_scene::scene::{LoadedScene, parse_scene};

/// Read and parse a scene file with `overrides` (`key=value`).
pub fn load_scene_file(path: &Path, overrides: &[String]) -> Result<LoadedScene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        SceneError::Io(format!(
            "{}: cannot read the scene file: {e}",
            path.display()
        ))
    })?;
    let base = path
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."));
    parse_scene(&text, &path.display().to_string(), &base, overrides)
}

/// A case name (`case-a`..`case-d`) or the path of a scene file.
pub fn load_case_or_file(arg: &str, overrides: &[String]) -> Result<LoadedScene, SceneError> {
    if fem_scene::solid::case_text_3d(arg).is_some() {
        return Err(SceneError::Usage(format!(
            "`{arg}` is a 3D scene (dim = 3): only `fem2d run`, `compare` and `budget` take 3D scenes yet"
        )));
    }
    if case_text(arg).is_some() {
        load_case(arg, overrides)
    } else if Path::new(arg).exists() || arg.ends_with(".toml") {
        load_scene_file(Path::new(arg), overrides)
    } else {
        Err(SceneError::Usage(format!(
            "`{arg}` is neither a case ({}) nor an existing scene file",
            names().join(", ")
        )))
    }
}

/// A built-in case of either dimension (`case-a`, ..., `case-a-3d`) or a scene file: its
/// `dim` key decides which ([`fem_scene::solid::AnyScene`]).
pub fn load_any(arg: &str, overrides: &[String]) -> Result<fem_scene::solid::AnyScene, SceneError> {
    use fem_scene::solid::{AnyScene, case_text_3d, load_case3, parse_any};
    if case_text_3d(arg).is_some() {
        return Ok(AnyScene::Three(Box::new(load_case3(arg, overrides)?)));
    }
    if case_text(arg).is_none() && (Path::new(arg).exists() || arg.ends_with(".toml")) {
        let path = Path::new(arg);
        let text = std::fs::read_to_string(path).map_err(|e| {
            SceneError::Io(format!(
                "{}: cannot read the scene file: {e}",
                path.display()
            ))
        })?;
        let base = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        return parse_any(&text, &path.display().to_string(), &base, overrides);
    }
    Ok(AnyScene::Two(Box::new(load_case_or_file(arg, overrides)?)))
}

/// Mesh and model files read from disk, relative paths against a base directory (the scene
/// file's).
#[derive(Clone, Debug)]
pub struct FileSource {
    base_dir: PathBuf,
}

impl FileSource {
    /// Files relative to `scene`'s directory.
    pub fn for_scene(scene: &LoadedScene) -> Self {
        FileSource {
            base_dir: scene.base_dir.clone(),
        }
    }
}

impl MeshSource for FileSource {
    fn read(&self, name: &str) -> Result<Vec<u8>, String> {
        let path = Path::new(name);
        let path = if path.is_absolute() {
            path.to_path_buf()
        } else {
            self.base_dir.join(path)
        };
        std::fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))
    }
}
