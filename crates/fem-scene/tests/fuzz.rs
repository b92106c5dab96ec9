//! Property tests over adversarial input: random overrides of the built-in cases (numbers at
//! the edges of f64, wrong types, huge counts, broken arrays) and random scene and mesh JSON
//! text. Every input either runs (a few steps) or is a one-line error; none panics or hangs.

use fem_scene::cases::{case_text, load_case};
use fem_scene::run::{RunEnv, run};
use fem_scene::scene::parse_scene;
use proptest::prelude::*;

/// Keys a user can override, from every part of a scene.
const KEYS: &[&str] = &[
    "energy",
    "gravity",
    "mesh.nx",
    "mesh.ny",
    "mesh.width",
    "mesh.height",
    "mesh.diagonal",
    "mesh.rotate_deg",
    "mesh.align_min",
    "mesh.max_area",
    "material.youngs_modulus",
    "material.poisson_ratio",
    "material.density",
    "material.total_mass",
    "material.plane",
    "material.name",
    "regions.0.name",
    "regions.0.density",
    "regions.0.youngs_modulus",
    "regions.0.poisson_ratio",
    "regions.0.polygon",
    "solver.kind",
    "solver.dt",
    "solver.steps",
    "solver.damping",
    "solver.iterations",
    "solver.substeps",
    "solver.compliance",
    "solver.scheme",
    "solver.ordering",
    "solver.relaxation",
    "solver.tolerance",
    "solver.load_steps",
    "ground.height",
    "obstacles.0.polygon",
    "obstacles.0.mass",
    "obstacles.0.velocity",
    "obstacles.0.motion",
    "pinned.0.min",
    "pinned.0.max",
    "probes.0.point",
    "output.frame_every",
    "contact.stiffness",
    "nonsense.key",
];

/// Values: extremes of f64 and of integers, wrong types, arrays of the wrong length.
const VALUES: &[&str] = &[
    "0",
    "-1",
    "1",
    "2",
    "1e-3",
    "0.5",
    "0.4999999999",
    "-0.9999",
    "1e308",
    "-1e308",
    "5e-324",
    "nan",
    "inf",
    "-inf",
    "4294967296",
    "18446744073709551615",
    "9007199254740993",
    "\"stvk\"",
    "\"xpbd\"",
    "\"static\"",
    "\"bogus\"",
    "true",
    "[]",
    "[0.0]",
    "[0.0, 0.0]",
    "[1e308, 1e308]",
    "[1e300, 0.0]",
    "\"a\\nb\"",
    "\"a,b\"",
    "[[0.0, 0.0], [1.0, 0.0]]",
    "[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]",
    "[[1.4, 0.5], [1.6, 0.5], [1.5, 0.7]]",
    "{}",
    "\"\"",
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    /// Up to four random overrides of a random case: parsing gives a scene or a one-line
    /// error; a scene small enough is run for a few steps, which ends or fails in one line.
    #[test]
    fn overrides_of_the_cases_never_panic(
        case in prop::sample::select(vec!["case-a", "case-b", "case-c", "case-d"]),
        picks in prop::collection::vec((0..KEYS.len(), 0..VALUES.len()), 0..4),
    ) {
        let mut overrides: Vec<String> =
            picks.iter().map(|&(k, v)| format!("{}={}", KEYS[k], VALUES[v])).collect();
        // Keep runs short: at most 3 steps, and skip meshes too large to build quickly.
        overrides.push("solver.steps=3".into());
        match load_case(case, &overrides) {
            Err(e) => prop_assert_eq!(e.to_string().lines().count(), 1, "{}", e),
            Ok(scene) => {
                let m = &scene.scene.mesh;
                let cells = m.nx.unwrap_or(1).saturating_mul(m.ny.unwrap_or(1));
                if cells <= 20_000 && scene.scene.solver.planned_steps() <= 3
                    && let Err(e) = run(&scene, &mut RunEnv::default()) {
                        prop_assert_eq!(e.to_string().lines().count(), 1, "{}", e);
                    }
            }
        }
    }

    /// Random bytes spliced into a case's text: a one-line error or a scene, never a panic.
    #[test]
    fn mangled_scene_text_never_panics(
        case in prop::sample::select(vec!["case-a", "case-c", "case-d"]),
        at in 0usize..4000,
        junk in "[\\[\\]{}=\",.0-9a-z \n-]{0,12}",
    ) {
        let text = case_text(case).unwrap();
        let at = at.min(text.len());
        let at = (0..=at).rev().find(|&i| text.is_char_boundary(i)).unwrap_or(0);
        let mangled = format!("{}{}{}", &text[..at], junk, &text[at..]);
        if let Err(e) = parse_scene(&mangled, "fuzz.toml", std::path::Path::new("."), &[]) {
            prop_assert_eq!(e.to_string().lines().count(), 1, "{}", e);
        }
    }

    /// Random mesh JSON (coordinates at the edges of f64, repeated, collinear or out-of-range
    /// indices): parsed and validated into a mesh or a one-line error.
    #[test]
    fn random_mesh_json_never_panics(
        vertices in prop::collection::vec(
            prop::array::uniform2(prop::sample::select(vec![
                0.0, 1.0, -1.0, 0.5, 1e-300, 1e300, f64::MAX, 2.0, 3.0,
            ])),
            0..12,
        ),
        triangles in prop::collection::vec(prop::array::uniform3(0usize..14), 0..12),
    ) {
        let json = serde_json::json!({"vertices": vertices, "triangles": triangles}).to_string();
        match fem_mesh::io::parse_mesh_json(json.as_bytes(), std::path::Path::new("fuzz.json")) {
            Err(e) => prop_assert_eq!(e.to_string().lines().count(), 1, "{}", e),
            Ok(m) => {
                let v: Vec<[f64; 2]> = m.vertices.clone();
                if let Err(e) = fem_core::mesh::Mesh::from_arrays(&v, &m.triangles) {
                    prop_assert_eq!(e.to_string().lines().count(), 1, "{}", e);
                }
            }
        }
    }

    /// Random region keys on a valid mesh (tags in and out of range, names repeated, empty,
    /// with commas or line breaks): a mesh or a one-line error, and never a mesh whose names
    /// repeat or break the name rule.
    #[test]
    fn random_region_keys_never_panic_and_bad_names_are_refused(
        tags in prop::collection::vec(prop::sample::select(vec![0u32, 1, 2, 70_000, u32::MAX]), 0..4),
        names in prop::collection::vec(
            prop::sample::select(vec!["b", "b", "", " ", "a,b", "a\nb", "q\"q", "soft tissue"]),
            0..4,
        ),
    ) {
        let json = serde_json::json!({
            "vertices": [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            "triangles": [[0, 1, 2], [0, 2, 3]],
            "regions": tags,
            "region_names": names,
        })
        .to_string();
        match fem_mesh::io::parse_mesh_json(json.as_bytes(), std::path::Path::new("fuzz.json")) {
            Err(e) => prop_assert_eq!(e.to_string().lines().count(), 1, "{}", e),
            Ok(m) => {
                for (k, n) in m.region_names.iter().enumerate() {
                    prop_assert!(fem_mesh::io::check_region_name(n).is_ok(), "{:?}", n);
                    prop_assert!(!m.region_names[..k].contains(n), "{:?}", m.region_names);
                }
            }
        }
    }
}
