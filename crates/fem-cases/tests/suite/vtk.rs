//! The run's VTK output of a body with material regions: the integer cell arrays `region`
//! (and `mesh_region` for a mesh that carries regions) equal the run's tags in every frame,
//! their names are in the field data, and a homogeneous body's files carry none of them.

use std::path::{Path, PathBuf};

use fem_cases::run::{RunOptions, RunResult, run_scene};
use fem_render::vtk::{VtuData, read_pvd, read_vtu};
use fem_scene::cases::load_case;
use fem_scene::scene::{LoadedScene, parse_scene};

/// A 2 m x 0.2 m bar, its right half a polygon region a hundred times stiffer, stretched
/// quasi-statically in two load increments.
const BAR: &str = r#"
name = "bimaterial-bar"
energy = "corotational"
gravity = [0.0, 0.0]

[mesh]
kind = "rectangle"
width = 2.0
height = 0.2
nx = 10
ny = 2

[material]
name = "soft"
youngs_modulus = 1.0e4
poisson_ratio = 0.0
density = 100.0

[[regions]]
name = "stiff"
polygon = [[1.0, -1.0], [3.0, -1.0], [3.0, 1.0], [1.0, 1.0]]
youngs_modulus = 1.0e6

[solver]
kind = "static"
dt = 1.0
steps = 2

[[pinned]]
min = [0.0, 0.0]
max = [0.0, 0.2]

[[traction]]
min = [2.0, 0.0]
max = [2.0, 0.2]
traction = [500.0, 0.0]
"#;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("fem2d-vtk-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn bar(overrides: &[&str]) -> LoadedScene {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    parse_scene(BAR, "bar.toml", Path::new("."), &o).unwrap_or_else(|e| panic!("{e}"))
}

/// Runs `scene` with VTK output into `dir`; the result and every frame's file.
fn run_with_vtk(scene: &LoadedScene, dir: &Path) -> (RunResult, Vec<VtuData>) {
    let result = run_scene(
        scene,
        &RunOptions {
            out_dir: Some(dir.to_path_buf()),
            threads: Some(1),
            vtk: true,
            ..RunOptions::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let frames: Vec<VtuData> = read_pvd(&dir.join("vtk/run.pvd"))
        .unwrap()
        .iter()
        .map(|(_, path)| read_vtu(path).unwrap())
        .collect();
    assert_eq!(frames.len(), result.frame_times.len());
    (result, frames)
}

fn as_f64(tags: &[u32]) -> Vec<f64> {
    tags.iter().map(|&t| t as f64).collect()
}

#[test]
fn polygon_region_is_written_as_a_region_cell_array_with_its_names() {
    let dir = scratch("polygon-region");
    let (result, frames) = run_with_vtk(&bar(&[]), &dir);
    // Both materials are present, so the test would see a swapped or constant array.
    assert!(result.region_tags.contains(&0) && result.region_tags.contains(&1));
    let want = as_f64(&result.region_tags);
    for (k, f) in frames.iter().enumerate() {
        assert_eq!(
            f.cell_array("region"),
            Some((1, want.as_slice())),
            "frame {k}"
        );
        assert_eq!(
            f.field_strings("region_names"),
            Some(["soft".to_owned(), "stiff".to_owned()].as_slice()),
            "frame {k}"
        );
        // A rectangle carries no mesh regions.
        assert!(
            f.cell_array("mesh_region").is_none() && f.field_strings("mesh_region_names").is_none()
        );
    }
    // The region array is an integer array; von Mises stays the active scalar.
    let text = std::fs::read_to_string(dir.join("vtk/run_000000.vtu")).unwrap();
    assert!(
        text.contains("<DataArray type=\"UInt32\" Name=\"region\""),
        "{text}"
    );
    assert!(text.contains("<CellData Scalars=\"von_mises\""));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn homogeneous_body_has_no_region_arrays() {
    let dir = scratch("homogeneous");
    let (_, frames) = run_with_vtk(&bar(&["regions=[]"]), &dir);
    for f in &frames {
        let names: Vec<&str> = f.cell_data.iter().map(|(n, _, _)| n.as_str()).collect();
        assert_eq!(names, ["von_mises", "det_F"]);
        assert!(f.field_data.is_empty());
    }
    let text = std::fs::read_to_string(dir.join("vtk/run_000000.vtu")).unwrap();
    assert!(!text.contains("FieldData") && !text.contains("UInt32"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Case D's body carries its bones as mesh regions, and its `[[regions]]` entry gives them
/// the bone material: both arrays, each with its names.
#[test]
fn body_with_bones_writes_region_and_mesh_region() {
    let dir = scratch("body");
    let scene = load_case("case-d", &["solver.steps=1".into()]).unwrap();
    let (result, frames) = run_with_vtk(&scene, &dir);
    let (mesh_tags, mesh_names) = &result.mesh_regions;
    assert!(mesh_names.iter().any(|n| n == "femur"), "{mesh_names:?}");
    let last = frames.last().unwrap();
    assert_eq!(
        last.cell_array("region"),
        Some((1, as_f64(&result.region_tags).as_slice()))
    );
    assert_eq!(
        last.field_strings("region_names"),
        Some(["soft-tissue".to_owned(), "bone".to_owned()].as_slice())
    );
    assert_eq!(
        last.cell_array("mesh_region"),
        Some((1, as_f64(mesh_tags).as_slice()))
    );
    assert_eq!(
        last.field_strings("mesh_region_names"),
        Some(mesh_names.as_slice())
    );
    let _ = std::fs::remove_dir_all(&dir);
}
