//! `[[regions]]`: per-element materials from a scene file, as `fem2d run` builds them. A
//! bimaterial bar in tension (soft left half, a polygon region a hundred times stiffer on the
//! right half, `nu = 0`, static solver) has each half's analytic strain `t / E_i`; the masses
//! follow each region's density; bad regions are one-line errors naming the field.

use std::path::Path;

use fem_core::dispatch_energy;
use fem_core::math::Real;
use fem_scene::build::{NoFiles, build_mesh, build_model, build_stepper, energy, material_regions};
use fem_scene::scene::{LoadedScene, parse_scene};
use fem_solvers::{State, Stepper};

const BAR: &str = r#"
name = "bimaterial-bar"
energy = "corotational"
gravity = [0.0, 0.0]

[mesh]
kind = "rectangle"
width = 2.0
height = 0.2
nx = 20
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
density = 300.0

[solver]
kind = "static"
dt = 1.0
steps = 1

[[pinned]]
min = [0.0, 0.0]
max = [0.0, 0.2]

[[traction]]
min = [2.0, 0.0]
max = [2.0, 0.2]
traction = [500.0, 0.0]
"#;

fn scene(overrides: &[&str]) -> Result<LoadedScene, String> {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    parse_scene(BAR, "bar.toml", Path::new("."), &o).map_err(|e| e.to_string())
}

#[test]
fn a_polygon_region_gives_its_elements_their_own_stiffness_and_density() {
    let scene = scene(&[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let regions = material_regions(&scene, &mesh).unwrap();
    let names: Vec<&str> = regions.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["soft", "stiff"]);
    assert_eq!(regions.tags.iter().filter(|&&t| t == 1).count(), 40);
    let e = energy(&scene).unwrap();
    dispatch_energy!(e, e => {
        let model = build_model(&scene, mesh, e).unwrap();
        // 0.2 m^2 at 100 kg/m^3 and 0.2 m^2 at 300 kg/m^3.
        let total: Real = model.masses().iter().sum();
        assert!((total - 80.0).abs() < 1e-9, "{total}");
        let mut stepper = build_stepper(&scene, &model).unwrap();
        let mut state = State::at_rest(&model);
        for _ in 0..100 {
            if state.t >= 1.0 {
                break;
            }
            stepper.step(&model, &mut state).unwrap();
        }
        assert_eq!(state.t, 1.0);
        let ux = |at: Real| {
            let v = model.mesh().vertices();
            let on: Vec<usize> = (0..v.len()).filter(|&i| (v[i].x - at).abs() < 1e-9).collect();
            on.iter().map(|&i| state.x[i].x - v[i].x).sum::<Real>() / on.len() as Real
        };
        let (soft, stiff) = (ux(1.0), ux(2.0) - ux(1.0));
        assert!((soft / 0.05 - 1.0).abs() < 1e-6, "soft half strain {soft}");
        assert!((stiff / 5e-4 - 1.0).abs() < 1e-6, "stiff half strain {stiff}");
    });
}

#[test]
fn a_total_mass_is_shared_by_what_the_regions_with_a_density_leave() {
    let text = BAR.replace("density = 100.0", "total_mass = 100.0");
    let scene = parse_scene(&text, "bar.toml", Path::new("."), &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let regions = material_regions(&scene, &mesh).unwrap();
    // The stiff half weighs 0.2 x 300 = 60 kg; the soft half gets the other 40 kg.
    assert!((regions.materials[0].density - 200.0).abs() < 1e-9);
    let light = BAR.replace("density = 100.0", "total_mass = 50.0");
    let scene = parse_scene(&light, "bar.toml", Path::new("."), &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let e = material_regions(&scene, &mesh).unwrap_err().to_string();
    assert!(
        e.contains("material.total_mass = 50: must exceed the 60 kg"),
        "{e}"
    );
}

#[test]
fn bad_regions_are_one_line_errors_naming_the_field() {
    let cases: [(&[&str], &str); 5] = [
        (
            &["regions.0.youngs_modulus=-1"],
            "regions.0.youngs_modulus = -1: must be a finite number > 0",
        ),
        (
            &["regions.0.poisson_ratio=0.5"],
            "regions.0.poisson_ratio = 0.5: must lie in the open interval",
        ),
        (
            &["regions.0.name=\"soft\""],
            "regions.0.name = \"soft\": must be non-empty, without commas",
        ),
        (
            &["regions.0.mesh_regions=[\"bone\"]"],
            "regions.0.polygon = (given): give exactly one of polygon and mesh_regions",
        ),
        (
            &["regions.0.polygon=[[0.0, 0.0], [1.0, 0.0]]"],
            "regions.0.polygon = 2 points: needs at least 3 points",
        ),
    ];
    for (overrides, want) in cases {
        let e = scene(overrides).unwrap_err();
        assert!(e.contains(want) && !e.contains('\n'), "{overrides:?}: {e}");
    }
    // Claims nothing; names a mesh region the rectangle does not carry.
    let empty = scene(&["regions.0.polygon=[[5.0, 5.0], [6.0, 5.0], [6.0, 6.0]]"]).unwrap();
    let mesh = build_mesh(&empty, &NoFiles).unwrap();
    let e = material_regions(&empty, &mesh).unwrap_err().to_string();
    assert!(e.contains("regions.0 = stiff: contains no element"), "{e}");
    let text = BAR.replace(
        "polygon = [[1.0, -1.0], [3.0, -1.0], [3.0, 1.0], [1.0, 1.0]]",
        "mesh_regions = [\"femur\"]",
    );
    let named = parse_scene(&text, "bar.toml", Path::new("."), &[]).unwrap();
    let mesh = build_mesh(&named, &NoFiles).unwrap();
    let e = material_regions(&named, &mesh).unwrap_err().to_string();
    assert!(
        e.contains("\"femur\": is not a region of the mesh (it has: none)"),
        "{e}"
    );
}

#[test]
fn each_region_reports_its_stress_strain_and_area_above_the_threshold() {
    use fem_scene::run::{RunEnv, run};
    // Uniaxial tension with nu = 0: the Cauchy stress is the traction, 500 Pa, in both
    // halves, so is the von Mises stress; nothing is compressed.
    for (threshold, above) in [(400.0, 1.0), (600.0, 0.0)] {
        let set = format!("output.stress_threshold={threshold}");
        let scene = scene(&[&set]).unwrap();
        let result = run(&scene, &mut RunEnv::default()).unwrap();
        let regions = &result.summary.regions;
        assert_eq!(regions.len(), 2);
        assert_eq!(result.summary.stress_threshold, threshold);
        for r in regions {
            assert!((r.area - 0.2).abs() < 1e-12, "{}: {}", r.name, r.area);
            assert!(
                (r.peak_von_mises - 500.0).abs() < 1e-6,
                "{}: {}",
                r.name,
                r.peak_von_mises
            );
            assert!((r.last.mean_von_mises - 500.0).abs() < 1e-6);
            assert!(
                r.max_compressive_strain < 1e-9,
                "{}",
                r.max_compressive_strain
            );
            assert_eq!(r.last.area_above_threshold, above, "{}", r.name);
        }
        assert_eq!((regions[0].density, regions[1].density), (100.0, 300.0));
        assert_eq!(regions[1].youngs_modulus, 1.0e6);
        // One series entry per recorded frame and region.
        assert!(
            result
                .region_series
                .iter()
                .all(|s| s.len() == result.frame_times.len())
        );
    }
}

/// A second `[[regions]]` entry over the whole of the first: the first owns no element, which
/// the docs call an error (before: accepted, with area 0 in the outputs).
#[test]
fn an_entry_every_element_of_which_a_later_entry_claims_again_is_an_error_naming_both() {
    let text = BAR.replace(
        "\n[solver]",
        "\n[[regions]]\nname = \"cover\"\npolygon = [[0.5, -1.0], [3.0, -1.0], [3.0, 1.0], [0.5, 1.0]]\n\n[solver]",
    );
    let scene = parse_scene(&text, "bar.toml", Path::new("."), &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let e = material_regions(&scene, &mesh).unwrap_err().to_string();
    assert_eq!(
        e,
        "bar.toml: regions.0 = stiff: every element it claims is claimed again by regions.1 (later entries override earlier ones), so it applies nowhere"
    );
    // Overridden by two later entries, each over one half: both are named.
    let two = BAR.replace(
        "\n[solver]",
        "\n[[regions]]\nname = \"lower\"\npolygon = [[0.5, -1.0], [3.0, -1.0], [3.0, 0.1], [0.5, 0.1]]\n\n[[regions]]\nname = \"upper\"\npolygon = [[0.5, 0.1], [3.0, 0.1], [3.0, 1.0], [0.5, 1.0]]\n\n[solver]",
    );
    let scene = parse_scene(&two, "bar.toml", Path::new("."), &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let e = material_regions(&scene, &mesh).unwrap_err().to_string();
    assert!(
        e.contains(
            "regions.0 = stiff: every element it claims is claimed again by regions.1 and regions.2"
        ),
        "{e}"
    );
    // Partly overridden is fine: the first keeps what the later entry leaves.
    let part = BAR.replace(
        "\n[solver]",
        "\n[[regions]]\nname = \"tip\"\npolygon = [[1.5, -1.0], [3.0, -1.0], [3.0, 1.0], [1.5, 1.0]]\n\n[solver]",
    );
    let scene = parse_scene(&part, "bar.toml", Path::new("."), &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let regions = material_regions(&scene, &mesh).unwrap();
    assert_eq!(regions.tags.iter().filter(|&&t| t == 1).count(), 20);
}

/// More `[[regions]]` entries than `fem_scene::scene::MAX_REGIONS`: one line naming the count
/// (before: 50,000 entries were accepted).
#[test]
fn more_regions_than_the_bound_are_an_error_naming_the_count() {
    use fem_scene::scene::MAX_REGIONS;
    let entries = |n: usize| -> String {
        (0..n)
            .map(|k| {
                format!(
                    "[[regions]]\nname = \"r{k}\"\npolygon = [[1.0, -1.0], [3.0, -1.0], [3.0, 1.0]]\n"
                )
            })
            .collect()
    };
    let text = |n: usize| BAR.replace("\n[solver]", &format!("\n{}\n[solver]", entries(n)));
    // At the bound the entries parse (the later ones override the earlier ones: that is
    // found when the mesh is tagged, not here).
    parse_scene(&text(MAX_REGIONS - 1), "bar.toml", Path::new("."), &[]).unwrap();
    let e = parse_scene(&text(MAX_REGIONS), "bar.toml", Path::new("."), &[])
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        format!(
            "bar.toml: regions = ({} entries): must be at most {MAX_REGIONS} entries (fem_scene::scene::MAX_REGIONS)",
            MAX_REGIONS + 1
        )
    );
}

/// Region names are one CSV field and one line as they are: a comma, a double quote or a line
/// break in `regions.N.name` or `material.name` is an error (before: a line break split the
/// header of regions.csv, and `material.name` took commas).
#[test]
fn region_names_with_commas_quotes_or_line_breaks_are_errors() {
    for bad in ["a,b", "a\"b", "a\nb", "a\tb", " "] {
        let quoted = toml::Value::String(bad.into()).to_string();
        let e = scene(&[&format!("regions.0.name={quoted}")]).unwrap_err();
        assert!(
            e.contains(&format!("regions.0.name = {bad:?}: must be non-empty, without commas, double quotes or control characters")),
            "{bad:?}: {e}"
        );
        assert!(!e.contains('\n'), "{e}");
        let e = scene(&[&format!("material.name={quoted}")]).unwrap_err();
        assert!(
            e.contains(&format!(
                "material.name = {bad:?}: must be non-empty, without commas"
            )),
            "{bad:?}: {e}"
        );
    }
    // Spaces, dashes and other punctuation are fine.
    scene(&["regions.0.name=\"cortical bone (left)\""]).unwrap();
}

/// A region density so small that the vertex masses underflow names the region's field and
/// value (before: `masses[0] = 0`); so does a Young's modulus or a Poisson ratio out of range
/// (before: reported under `material.youngs_modulus`).
#[test]
fn a_regions_density_or_elastic_constants_out_of_range_name_its_own_fields() {
    use fem_scene::run::{RunEnv, run};
    let s = scene(&["regions.0.density=5e-324"]).unwrap();
    let e = run(&s, &mut RunEnv::default()).unwrap_err().to_string();
    assert!(
        e.starts_with(
            "bar.toml: regions.0.density = 5e-324: too small: the lumped vertex masses underflow"
        ),
        "{e}"
    );
    // The base material's density, by the same rule.
    let s = scene(&["material.density=1e-320"]).unwrap();
    let e = run(&s, &mut RunEnv::default()).unwrap_err().to_string();
    assert!(
        e.starts_with("bar.toml: material.density = 1e-320: too small"),
        "{e}"
    );
    let cases: [(&str, &str); 4] = [
        (
            "regions.0.youngs_modulus=5e-324",
            "bar.toml: regions.0.youngs_modulus = 5e-324: must be at least 1e-290 Pa",
        ),
        (
            "regions.0.youngs_modulus=1e300",
            "bar.toml: regions.0.youngs_modulus = 1e300: must be at most 1e290 Pa",
        ),
        (
            "regions.0.poisson_ratio=-1",
            "bar.toml: regions.0.poisson_ratio = -1: must lie in the open interval (-1, 0.5)",
        ),
        (
            "material.youngs_modulus=1e300",
            "bar.toml: material.youngs_modulus = 1e300: must be at most 1e290 Pa",
        ),
    ];
    for (set, want) in cases {
        let e = scene(&[set]).unwrap_err();
        assert!(e.starts_with(want), "{set}: {e}");
    }
}

/// `material.total_mass` with every element in a region of its own density has nothing to
/// weigh: the message says so (before: "total_mass 1e9 must exceed 120 kg").
#[test]
fn a_total_mass_with_nothing_left_to_weigh_says_so() {
    let text = BAR.replace("density = 100.0", "total_mass = 1e9").replace(
        "polygon = [[1.0, -1.0], [3.0, -1.0], [3.0, 1.0], [1.0, 1.0]]",
        "polygon = [[-1.0, -1.0], [3.0, -1.0], [3.0, 1.0], [-1.0, 1.0]]",
    );
    let scene = parse_scene(&text, "bar.toml", Path::new("."), &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let e = material_regions(&scene, &mesh).unwrap_err().to_string();
    assert_eq!(
        e,
        "bar.toml: material.total_mass = 1000000000: every element belongs to a [[regions]] entry with its own density (together 120 kg), so nothing is left for total_mass to weigh; give material.density instead"
    );
}
