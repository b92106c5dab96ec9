//! From a validated scene to the pieces of a run: the mesh, the model (masses, boundary
//! conditions, gravity, tractions, ground, obstacles), the probes' vertices and the stepper
//! (any solver of the registry, built from its own parameters).
//!
//! Mesh and model files are not opened here: a [`MeshSource`] supplied by the caller returns
//! their bytes by the name the scene gives (`mesh.path`).

use std::path::Path;

use fem_core::energy::{AnyEnergy, ElementEnergies, Energy};
use fem_core::math::{Real, Vec2, readable};
use fem_core::mesh::Mesh;
use fem_core::stress::VonMisesFormula;
use fem_core::structured::{NodeOrder, RectangleParams, rectangle};
use fem_core::{Lame, Material, PlaneModel};
use fem_mesh::Mesh2;
use fem_mesh::camera::{Camera, Projection};
use fem_mesh::pipeline::{PipelineParams, mesh_surface};
use fem_mesh::triangulate::TriangulateParams;
use fem_solvers::{
    AnyStepper, Clock, ContactParams, Ground, Model, ObstacleMotion, ObstacleMove,
    PrescribedMotion, Region, SolverError, State,
};

use crate::error::SceneError;
use crate::scene::{Formulation, LoadedScene, MeshKind, MeshSpec, MotionName, ViewName};

/// Where the bytes of the files a scene names (`mesh.path`: a mesh JSON or a 3D model) come
/// from: the file system next to the scene file for the command line, memory in a browser.
pub trait MeshSource {
    /// The bytes of the file the scene names `name` (as written in the scene); the error is a
    /// one-line reason (it is prefixed with the name).
    fn read(&self, name: &str) -> Result<Vec<u8>, String>;
}

/// A [`MeshSource`] without files: every name is an error. Scenes with a rectangle or the
/// built-in body need no file.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoFiles;

impl MeshSource for NoFiles {
    fn read(&self, name: &str) -> Result<Vec<u8>, String> {
        Err(format!(
            "no file source was given, so `{name}` cannot be read (the scene needs a mesh or model file)"
        ))
    }
}

/// The bytes of the scene's `mesh.path`, through `source`.
fn read_named(
    scene: &LoadedScene,
    source: &dyn MeshSource,
) -> Result<(String, Vec<u8>), SceneError> {
    let name = scene
        .scene
        .mesh
        .path
        .as_deref()
        .map(|p| p.to_string_lossy().into_owned())
        .unwrap_or_default();
    let bytes = source
        .read(&name)
        .map_err(|e| SceneError::Io(format!("{}: mesh.path = {name}: {e}", scene.origin)))?;
    Ok((name, bytes))
}

/// The camera of a preset view of a surface with bounds `lo`..`hi`: orthographic, aimed at
/// the bounding-box centre from twice the diagonal away.
pub fn preset_camera(view: ViewName, lo: [f64; 3], hi: [f64; 3]) -> Camera {
    let centre = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
    let diag = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2))
        .sqrt()
        .max(1.0);
    let (dir, up) = match view {
        ViewName::Side => ([-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ViewName::Front => ([0.0, 0.0, 1.0], [0.0, 1.0, 0.0]),
        ViewName::Back => ([0.0, 0.0, -1.0], [0.0, 1.0, 0.0]),
        ViewName::Top => ([0.0, 1.0, 0.0], [0.0, 0.0, -1.0]),
    };
    Camera {
        position: [0, 1, 2].map(|k| centre[k] + 2.0 * diag * dir[k]),
        focal_point: centre,
        up,
        projection: Projection::Orthographic,
    }
}

/// The last built-in mesh built (the body, the shank) and its spec.
static LAST_BUILT_IN: std::sync::Mutex<Option<(MeshSpec, Mesh)>> = std::sync::Mutex::new(None);

/// The scene's mesh: generated, read (through `source`) or meshed from a 3D model, then
/// rotated and placed.
///
/// The built-in geometries (`body`, `shank`) read no file, and their meshing is deterministic:
/// the last one built is kept and handed out again for the same `[mesh]` table, so the runs of
/// one scene's variants (a comparison's rows, a frame budget's rungs) mesh it once.
pub fn build_mesh(scene: &LoadedScene, source: &dyn MeshSource) -> Result<Mesh, SceneError> {
    let spec = &scene.scene.mesh;
    let built_in = matches!(spec.kind, Some(MeshKind::Body | MeshKind::Shank));
    if built_in
        && let Ok(last) = LAST_BUILT_IN.lock()
        && let Some((kept, mesh)) = last.as_ref()
        && kept == spec
    {
        return Ok(mesh.clone());
    }
    let mesh = build_mesh_uncached(scene, source)?;
    if built_in && let Ok(mut last) = LAST_BUILT_IN.lock() {
        *last = Some((spec.clone(), mesh.clone()));
    }
    Ok(mesh)
}

fn build_mesh_uncached(scene: &LoadedScene, source: &dyn MeshSource) -> Result<Mesh, SceneError> {
    let spec = &scene.scene.mesh;
    let mesh_err =
        |e: fem_mesh::MeshError| SceneError::Mesh(format!("{}: mesh: {e}", scene.origin));
    // Where the triangles came from, for the final checks' message.
    let mut from = String::from("mesh");
    let mut mesh2: Mesh2 = match spec.kind.unwrap_or(MeshKind::Rectangle) {
        MeshKind::Rectangle => {
            let params = RectangleParams {
                origin: spec.origin.unwrap_or([0.0, 0.0]),
                width: spec.width.unwrap_or(1.0),
                height: spec.height.unwrap_or(1.0),
                nx: spec.nx.unwrap_or(1),
                ny: spec.ny.unwrap_or(1),
                diagonal: spec.diagonal.unwrap_or_default(),
                order: NodeOrder::XFastest,
            };
            let mesh = rectangle(&params).map_err(|e| rectangle_error(scene, &params, &e))?;
            Mesh2 {
                vertices: mesh.vertices().iter().map(|p| [p.x, p.y]).collect(),
                triangles: mesh
                    .triangles()
                    .iter()
                    .map(|t| t.map(|i| i as usize))
                    .collect(),
                ..Default::default()
            }
        }
        MeshKind::File => {
            let (name, bytes) = read_named(scene, source)?;
            from = format!("mesh.path = {name}");
            fem_mesh::io::parse_mesh_json(&bytes, Path::new(&name)).map_err(mesh_err)?
        }
        MeshKind::Model | MeshKind::Body => match mesh_pipeline(scene, source)? {
            Some(out) => {
                check_refined(
                    scene,
                    &out.mesh,
                    &out.triangulate_report,
                    TriangulateParams::default().max_steiner_points,
                )?;
                out.mesh
            }
            None => unreachable!("a model or body mesh goes through the pipeline"),
        },
        MeshKind::Shank => {
            let (outline, bones) = fem_mesh::shank::shank_section();
            let defaults = fem_mesh::shank::shank_params();
            let params = TriangulateParams {
                max_area: spec.max_area.or(defaults.max_area),
                min_angle_deg: spec.min_angle.unwrap_or(defaults.min_angle_deg),
                ..defaults
            };
            let (mesh, report) =
                fem_mesh::triangulate::triangulate_regions(&[outline], &bones, &params)
                    .map_err(mesh_err)?;
            check_refined(scene, &mesh, &report, params.max_steiner_points)?;
            mesh
        }
    };
    let unplaced =
        (spec.rotate_deg.is_some() || spec.align_min.is_some()).then(|| mesh2.vertices.clone());
    place(&mut mesh2, spec.rotate_deg.unwrap_or(0.0), spec.align_min);
    let mut mesh = match core_mesh(&mesh2.vertices, &mesh2.triangles) {
        Ok(mesh) => mesh,
        Err(e) => {
            return Err(placement_error(scene, &mesh2, unplaced)
                .unwrap_or_else(|| SceneError::Mesh(format!("{}: {from}: {e}", scene.origin))));
        }
    };
    if !mesh2.regions.is_empty() {
        let names = if mesh2.region_names.is_empty() {
            let n = mesh2.regions.iter().max().map_or(0, |m| *m + 1);
            (0..n).map(|k| format!("region-{k}")).collect()
        } else {
            mesh2.region_names
        };
        mesh.set_regions(mesh2.regions, names)
            .map_err(|e| SceneError::Mesh(format!("{}: {from}: {e}", scene.origin)))?;
    }
    Ok(mesh)
}

/// The error of a rectangle whose triangles fail the mesh checks, naming the fields that made
/// them: `mesh.origin` when the same rectangle at the origin is valid (round-off far from it
/// collapsed the triangles), else `mesh.width` and `mesh.height` with the cell size.
fn rectangle_error(
    scene: &LoadedScene,
    params: &RectangleParams,
    e: &fem_core::mesh::MeshError,
) -> SceneError {
    let at_zero = RectangleParams {
        origin: [0.0, 0.0],
        ..*params
    };
    if params.origin != [0.0, 0.0] && rectangle(&at_zero).is_ok() {
        return scene.error(
            "mesh.origin",
            crate::scene::fmt_point(params.origin),
            &format!(
                "moves the rectangle where floating-point round-off breaks it ({e}); choose an origin nearer 0"
            ),
        );
    }
    scene.error(
        "mesh.width",
        readable(params.width),
        &format!(
            "with mesh.height = {}, nx = {} and ny = {} the cells are {:e} x {:e} m, too unequal, too small or too large for their triangles to pass the mesh checks ({e})",
            readable(params.height),
            params.nx,
            params.ny,
            params.width / params.nx as f64,
            params.height / params.ny as f64
        ),
    )
}

/// A fem-core mesh (validated) of the vertices and triangles.
fn core_mesh(
    vertices: &[[f64; 2]],
    triangles: &[[usize; 3]],
) -> Result<Mesh, fem_core::mesh::MeshError> {
    Mesh::new(
        vertices.iter().map(|p| Vec2::new(p[0], p[1])).collect(),
        triangles.iter().map(|t| t.map(|i| i as u32)).collect(),
    )
}

/// When the mesh was valid before `mesh.rotate_deg` and `mesh.align_min` moved it and is not
/// after (a shift to 1e300 m leaves too few significant digits to tell a triangle's corners
/// apart), the error names the field that moved it, with its value.
fn placement_error(
    scene: &LoadedScene,
    placed: &Mesh2,
    unplaced: Option<Vec<[f64; 2]>>,
) -> Option<SceneError> {
    let spec = &scene.scene.mesh;
    let mut original = Mesh2 {
        vertices: unplaced?,
        triangles: placed.triangles.clone(),
        ..Default::default()
    };
    core_mesh(&original.vertices, &original.triangles).ok()?;
    let broken = core_mesh(&placed.vertices, &placed.triangles).err()?;
    // Rotated only: if that mesh is valid, the shift broke it.
    place(&mut original, spec.rotate_deg.unwrap_or(0.0), None);
    let (field, value) = match spec.align_min {
        Some(p) if core_mesh(&original.vertices, &original.triangles).is_ok() => {
            ("mesh.align_min", crate::scene::fmt_point(p))
        }
        _ => ("mesh.rotate_deg", readable(spec.rotate_deg.unwrap_or(0.0))),
    };
    Some(scene.error(
        field,
        value,
        &format!(
            "moves the mesh where floating-point round-off breaks it ({broken}); the mesh is valid where it was made, so choose a placement nearer the origin"
        ),
    ))
}

/// A refinement that stopped at its Steiner point cap before every triangle met
/// `mesh.max_area` leaves a partly refined mesh (tiny triangles beside large ones, on which
/// the solvers struggle): an error naming `mesh.max_area`, with the triangles it would need.
fn check_refined(
    scene: &LoadedScene,
    mesh: &Mesh2,
    report: &fem_mesh::triangulate::TriangulateReport,
    cap: usize,
) -> Result<(), SceneError> {
    let Some(max_area) = scene.scene.mesh.max_area else {
        return Ok(());
    };
    if report.refinement_complete || report.max_area_met {
        return Ok(());
    }
    let needed = mesh.area() / max_area;
    Err(scene.error(
        "mesh.max_area",
        readable(max_area),
        &format!(
            "the mesher stopped at its {cap} Steiner points ({} triangles, the largest {:.3e} m^2) before every triangle was this small; a body of {:.4} m^2 needs about {} triangles at this area; raise mesh.max_area (or lower mesh.min_angle if that is not the cause)",
            mesh.triangles.len(),
            report.max_area,
            mesh.area(),
            readable(needed.ceil())
        ),
    ))
}

/// The mesh pipeline's output (every stage, for Figure 1) for a scene whose mesh comes from a
/// 3D model or the built-in body, before the scene's rotation and alignment; `None` for the
/// other mesh kinds.
pub fn mesh_pipeline(
    scene: &LoadedScene,
    source: &dyn MeshSource,
) -> Result<Option<fem_mesh::pipeline::PipelineOutput>, SceneError> {
    let spec = &scene.scene.mesh;
    let mesh_err =
        |e: fem_mesh::MeshError| SceneError::Mesh(format!("{}: mesh: {e}", scene.origin));
    let kind = spec.kind.unwrap_or(MeshKind::Rectangle);
    let mut surface = match kind {
        MeshKind::Model => {
            let (name, bytes) = read_named(scene, source)?;
            let options = fem_mesh::load::LoadOptions {
                groups: spec.groups.clone().unwrap_or_default(),
            };
            fem_mesh::load::parse_model(&bytes, Path::new(&name), &options).map_err(mesh_err)?
        }
        MeshKind::Body => fem_mesh::body::human_body(),
        MeshKind::Rectangle | MeshKind::File | MeshKind::Shank => return Ok(None),
    };
    surface.scale(spec.scale.unwrap_or(1.0));
    let (lo, hi) = surface.bounds().ok_or_else(|| {
        SceneError::Mesh(format!("{}: mesh: the model has no vertex", scene.origin))
    })?;
    let params = PipelineParams {
        camera: preset_camera(spec.view.unwrap_or_default(), lo, hi),
        alpha: fem_mesh::alpha::AlphaParams {
            radius: spec.alpha,
            ..Default::default()
        },
        epsilon: spec.epsilon,
        triangulate: TriangulateParams {
            max_area: spec.max_area,
            min_angle_deg: spec.min_angle.unwrap_or(25.0),
            ..Default::default()
        },
        ..PipelineParams::default()
    };
    let out = if kind == MeshKind::Body && spec.skeleton.unwrap_or(true) {
        let mut skeleton = fem_mesh::body::human_skeleton();
        let factor = spec.scale.unwrap_or(1.0);
        if factor != 1.0 {
            for bone in &mut skeleton.bones {
                bone.parts.iter_mut().for_each(|p| p.scale(factor));
            }
        }
        fem_mesh::pipeline::mesh_surface_with_skeleton(surface, &skeleton, &params)
    } else {
        mesh_surface(surface, &params)
    };
    out.map(Some).map_err(mesh_err)
}

/// Rotate by `deg` degrees counter-clockwise about the origin, then translate the bounding
/// box's lower-left corner to `align_min` (when given).
fn place(mesh: &mut Mesh2, deg: f64, align_min: Option<[f64; 2]>) {
    if deg != 0.0 {
        let (s, c) = fem_core::math::sin_cos(deg.to_radians());
        for p in &mut mesh.vertices {
            *p = [c * p[0] - s * p[1], s * p[0] + c * p[1]];
        }
    }
    if let Some(target) = align_min {
        let mut lo = [f64::INFINITY; 2];
        for p in &mesh.vertices {
            lo[0] = lo[0].min(p[0]);
            lo[1] = lo[1].min(p[1]);
        }
        for p in &mut mesh.vertices {
            p[0] += target[0] - lo[0];
            p[1] += target[1] - lo[1];
        }
    }
}

/// The material's Lamé parameters (plane model from the scene).
pub fn lame(scene: &LoadedScene) -> Result<Lame, SceneError> {
    let m = &scene.scene.material;
    // The density passed here only matters for wave speeds; masses come from the model.
    let material = Material::new(m.youngs_modulus, m.poisson_ratio, 1.0)
        .map_err(|e| SceneError::Scene(format!("{}: {e}", scene.origin)))?;
    Ok(material.lame(m.plane))
}

/// The material of one region of the body (see [`material_regions`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RegionMaterial {
    /// The region's name (`material.name` for the base).
    pub name: String,
    /// Young's modulus, Pa.
    pub youngs_modulus: Real,
    /// Poisson ratio.
    pub poisson_ratio: Real,
    /// Density, kg/m^3 (a base material given by its total mass gets the density that
    /// makes the body weigh it).
    pub density: Real,
    /// Whether the region is rigid (`[[regions]]` `rigid = true`; the base never is).
    pub rigid: bool,
}

/// The body's materials: region 0 is `[material]`, region `k` the `k`-th `[[regions]]` entry.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialRegions {
    /// Each region's material.
    pub materials: Vec<RegionMaterial>,
    /// The region of each triangle.
    pub tags: Vec<u32>,
}

impl MaterialRegions {
    /// The density of each triangle, kg/m^3.
    pub fn element_densities(&self) -> Vec<Real> {
        let d: Vec<Real> = self.materials.iter().map(|m| m.density).collect();
        self.tags.iter().map(|&t| d[t as usize]).collect()
    }
}

/// The region of every triangle and every region's material. A `[[regions]]` entry claims
/// the triangles whose rest centroid lies inside its polygon (even-odd rule) or whose mesh
/// region is one of its `mesh_regions`; a later entry overrides an earlier one. Errors: an
/// entry that claims no triangle, a mesh region the mesh does not have, or a total mass
/// smaller than the regions with their own density already weigh.
pub fn material_regions(scene: &LoadedScene, mesh: &Mesh) -> Result<MaterialRegions, SceneError> {
    let s = &scene.scene;
    let m = &s.material;
    let n = mesh.n_triangles();
    let mut tags = vec![0u32; n];
    let centroids: Vec<Vec2> = (0..n)
        .map(|t| mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0)
        .collect();
    let names = mesh.region_names();
    let mesh_tags = mesh.region_tags();
    // Whether entry `r` claims triangle `t`.
    let claims = |r: &crate::scene::MaterialRegionSpec, t: usize| match &r.polygon {
        Some(poly) => fem_mesh::types::point_in_ring([centroids[t].x, centroids[t].y], poly),
        None => mesh_tags
            .get(t)
            .is_some_and(|&tag| r.mesh_regions.contains(&names[tag as usize])),
    };
    for (i, r) in s.regions.iter().enumerate() {
        let field = format!("regions.{i}");
        let k = i as u32 + 1;
        if let Some(want) = r.mesh_regions.iter().find(|w| !names.contains(w)) {
            return Err(scene.error(
                &format!("{field}.mesh_regions"),
                format!("{want:?}"),
                &format!(
                    "is not a region of the mesh (it has: {})",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            ));
        }
        let mut claimed = 0usize;
        for (t, tag) in tags.iter_mut().enumerate() {
            if claims(r, t) {
                *tag = k;
                claimed += 1;
            }
        }
        if claimed == 0 {
            return Err(scene.error(&field, &r.name, "contains no element (rest centroid)"));
        }
    }
    let mut area = vec![0.0; s.regions.len() + 1];
    let mut owned = vec![0usize; s.regions.len() + 1];
    for (t, el) in mesh.elements().iter().enumerate() {
        area[tags[t] as usize] += el.area;
        owned[tags[t] as usize] += 1;
    }
    // An entry whose every element a later entry claims again owns nothing: its material
    // would apply nowhere, as if it claimed no element.
    if let Some(i) = (0..s.regions.len()).find(|&i| owned[i + 1] == 0) {
        let r = &s.regions[i];
        let mut by: Vec<u32> = (0..n).filter(|&t| claims(r, t)).map(|t| tags[t]).collect();
        by.sort_unstable();
        by.dedup();
        let by: Vec<String> = by.iter().map(|k| format!("regions.{}", k - 1)).collect();
        let list = match by.split_last() {
            Some((last, [])) => last.clone(),
            Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
            None => String::new(),
        };
        return Err(scene.error(
            &format!("regions.{i}"),
            &r.name,
            &format!(
                "every element it claims is claimed again by {list} (later entries override earlier ones), so it applies nowhere"
            ),
        ));
    }
    let base_density = match (m.density, m.total_mass) {
        (Some(d), _) => d,
        (None, Some(total)) => {
            // Regions with their own density weigh what they weigh; the rest shares the
            // remaining mass uniformly.
            let own: Real = (s.regions.iter().zip(&area[1..]))
                .filter_map(|(r, a)| r.density.map(|d| d * a))
                .sum();
            let rest: Real = area[0]
                + (s.regions.iter().zip(&area[1..]))
                    .filter(|(r, _)| r.density.is_none())
                    .map(|(_, a)| a)
                    .sum::<Real>();
            if rest <= 0.0 {
                return Err(scene.error(
                    "material.total_mass",
                    readable(total),
                    &format!(
                        "every element belongs to a [[regions]] entry with its own density (together {} kg), so nothing is left for total_mass to weigh; give material.density instead",
                        kilograms(own)
                    ),
                ));
            }
            if own >= total {
                return Err(scene.error(
                    "material.total_mass",
                    readable(total),
                    &format!(
                        "must exceed the {} kg the regions with their own density weigh",
                        kilograms(own)
                    ),
                ));
            }
            (total - own) / rest
        }
        (None, None) => unreachable!("validated: one of total_mass and density is given"),
    };
    let mut materials = vec![RegionMaterial {
        name: m.name().to_string(),
        youngs_modulus: m.youngs_modulus,
        poisson_ratio: m.poisson_ratio,
        density: base_density,
        rigid: false,
    }];
    materials.extend(s.regions.iter().map(|r| RegionMaterial {
        name: r.name.clone(),
        youngs_modulus: r.youngs_modulus.unwrap_or(m.youngs_modulus),
        poisson_ratio: r.poisson_ratio.unwrap_or(m.poisson_ratio),
        density: r.density.unwrap_or(base_density),
        rigid: r.rigid,
    }));
    Ok(MaterialRegions { materials, tags })
}

/// The von Mises formula matching the scene's plane model.
pub fn von_mises_formula(scene: &LoadedScene) -> VonMisesFormula {
    VonMisesFormula::from(scene.scene.material.plane)
}

/// The scene's energy.
pub fn energy(scene: &LoadedScene) -> Result<AnyEnergy, SceneError> {
    let kind = scene.scene.energy;
    kind.build(lame(scene)?)
        .map_err(|e| SceneError::Scene(format!("{}: energy = {kind}: {e}", scene.origin)))
}

fn solver_err(scene: &LoadedScene) -> impl Fn(SolverError) -> SceneError + '_ {
    move |e| SceneError::Solver(format!("{}: {e}", scene.origin))
}

fn v2(p: [f64; 2]) -> Vec2 {
    Vec2::new(p[0], p[1])
}

/// The model of the scene with the given mesh and energy.
pub fn build_model<E: Energy>(
    scene: &LoadedScene,
    mesh: Mesh,
    energy: E,
) -> Result<Model<E>, SceneError> {
    let mut model = build_unloaded_model(scene, mesh, energy)?;
    add_loads(scene, &mut model)?;
    crate::scales::check_scales(scene, &model)?;
    Ok(model)
}

/// The model of the scene without its loads: no gravity and no traction (masses, boundary
/// conditions, ground, obstacles and contact parameters as in [`build_model`]).
fn build_unloaded_model<E: Energy>(
    scene: &LoadedScene,
    mesh: Mesh,
    energy: E,
) -> Result<Model<E>, SceneError> {
    let s = &scene.scene;
    let err = solver_err(scene);
    let mut model = if s.regions.is_empty() {
        let density = match (s.material.total_mass, s.material.density) {
            (_, Some(d)) => d,
            (Some(total), None) => total / mesh.area(),
            (None, None) => unreachable!("validated: one of total_mass and density is given"),
        };
        check_masses(scene, &mesh, &[], &[density])?;
        match (s.material.total_mass, s.material.density) {
            (Some(total), _) => Model::with_total_mass(mesh, energy, total),
            (None, Some(density)) => Model::with_density(mesh, energy, density),
            (None, None) => unreachable!("validated: one of total_mass and density is given"),
        }
        .map_err(&err)?
    } else {
        let regions = material_regions(scene, &mesh)?;
        let mut energies = vec![energy.clone()];
        for (k, r) in regions.materials.iter().enumerate().skip(1) {
            let field = format!("regions.{}", k - 1);
            let lame = Material::new(r.youngs_modulus, r.poisson_ratio, 1.0)
                .map_err(|e| scene.error(&field, &r.name, &e.to_string()))?
                .lame(s.material.plane);
            let e = energy.with_lame(lame);
            energies.push(e.map_err(|e| scene.error(&field, &r.name, &e.to_string()))?);
        }
        let per_region: Vec<Real> = regions.materials.iter().map(|m| m.density).collect();
        check_masses(scene, &mesh, &regions.tags, &per_region)?;
        let densities = regions.element_densities();
        let masses = mesh
            .lumped_masses_from_densities(&densities)
            .map_err(|e| SceneError::Scene(format!("{}: {e}", scene.origin)))?;
        let energies = ElementEnergies::new(energies, regions.tags)
            .map_err(|e| SceneError::Scene(format!("{}: regions: {e}", scene.origin)))?;
        let mut model = Model::with_regions(mesh, energies, masses).map_err(&err)?;
        for (k, r) in regions.materials.iter().enumerate().skip(1) {
            if r.rigid {
                model.make_rigid(k, r.density).map_err(|e| {
                    let rule = match e {
                        SolverError::InvalidParameter { rule, .. } => rule,
                        other => other.to_string(),
                    };
                    scene.error(&format!("regions.{}.rigid", k - 1), true, &rule)
                })?;
            }
        }
        model
    };
    if averaged_pressure(scene) {
        model.set_averaged_pressure(true).map_err(&err)?;
    }
    for (i, r) in s.pinned.iter().enumerate() {
        let region = Region::in_box(v2(r.min), v2(r.max));
        if region
            .select(model.mesh().vertices(), "pinned")
            .map_err(&err)?
            .is_empty()
        {
            return Err(scene.error(
                &format!("pinned.{i}"),
                format!("min {:?} max {:?}", r.min, r.max),
                "contains no mesh vertex",
            ));
        }
        model.pin(&region).map_err(&err)?;
    }
    let end_of_run = s.solver.dt * s.solver.steps as f64;
    // A load-stepping solver moves prescribed vertices by their whole schedule in proportion
    // to the load: the schedule is cut at the end of the run, as a dynamic run would see it.
    let cut_at_end = s.solver.kind.capabilities().clock == Clock::LoadFactor;
    for (i, p) in s.prescribed.iter().enumerate() {
        let region = Region::in_box(v2(p.min), v2(p.max));
        if region
            .select(model.mesh().vertices(), "prescribed")
            .map_err(&err)?
            .is_empty()
        {
            return Err(scene.error(
                &format!("prescribed.{i}"),
                format!("min {:?} max {:?}", p.min, p.max),
                "contains no mesh vertex",
            ));
        }
        model
            .add_prescribed_motion(PrescribedMotion {
                region,
                velocity: v2(p.velocity),
                start: p.start,
                end: match p.end {
                    Some(end) if cut_at_end => end.min(end_of_run).max(p.start),
                    Some(end) => end,
                    None => end_of_run.max(p.start),
                },
            })
            .map_err(&err)?;
    }
    if let Some(g) = &s.ground {
        let ground = match (g.height, g.point, g.normal) {
            (Some(h), _, _) => Ground::horizontal(h),
            (None, Some(p), Some(n)) => Ground {
                point: v2(p),
                normal: v2(n),
            },
            _ => unreachable!("validated ground"),
        };
        model.set_ground(Some(ground)).map_err(&err)?;
    }
    for o in &s.obstacles {
        let polygon: Vec<Vec2> = o.polygon.iter().map(|p| v2(*p)).collect();
        let motion = match o.motion {
            MotionName::Static => ObstacleMotion::Static,
            MotionName::Kinematic => ObstacleMotion::Kinematic {
                velocity: v2(o.velocity.unwrap_or([0.0, 0.0])),
                angular_velocity: o.angular_velocity.unwrap_or(0.0),
                start: o.start.unwrap_or(0.0),
                end: o.end.unwrap_or(Real::INFINITY),
            },
            MotionName::Dynamic => ObstacleMotion::Dynamic {
                mass: o.mass.unwrap_or(1.0),
                rotates: o.rotates.unwrap_or(true),
            },
        };
        let index = model.add_obstacle(&polygon, motion).map_err(&err)?;
        if !o.moves.is_empty() {
            let moves: Vec<ObstacleMove> = o
                .moves
                .iter()
                .map(|m| ObstacleMove {
                    velocity: v2(m.velocity),
                    angular_velocity: m.angular_velocity.unwrap_or(0.0),
                    start: m.start,
                    end: m.end.unwrap_or(Real::INFINITY),
                })
                .collect();
            model.set_obstacle_moves(index, &moves).map_err(&err)?;
        }
    }
    if let Some(c) = &s.contact {
        let d = ContactParams::default();
        model
            .set_contact_params(ContactParams {
                stiffness: c.stiffness.unwrap_or(d.stiffness),
                damping_ratio: c.damping_ratio.unwrap_or(d.damping_ratio),
                friction: c.friction.unwrap_or(d.friction),
                barrier_distance: c.barrier_distance.unwrap_or(d.barrier_distance),
                barrier_stiffness: c.barrier_stiffness.unwrap_or(d.barrier_stiffness),
                friction_velocity: c.friction_velocity.unwrap_or(d.friction_velocity),
            })
            .map_err(&err)?;
    }
    Ok(model)
}

/// Check that every vertex gets a usable lumped mass: each triangle's share (density x area /
/// 3) a normal floating-point number, each vertex's sum finite. A density (or total mass) so
/// small that the shares underflow, or so large that the sums overflow, is an error naming the
/// field that gave it (`regions.0.density`, `material.density`, `material.total_mass`) rather
/// than the vertex mass it broke. `tags` is the region of each triangle (empty: all region 0),
/// `densities` each region's density (region 0 is `[material]`, `k` is `regions.(k - 1)`).
fn check_masses(
    scene: &LoadedScene,
    mesh: &Mesh,
    tags: &[u32],
    densities: &[Real],
) -> Result<(), SceneError> {
    let s = &scene.scene;
    let region = |t: usize| tags.get(t).map_or(0, |&k| k as usize);
    // The field (and its value) that gave region k its density.
    let source = |k: usize| -> (String, Real) {
        if k > 0
            && let Some(d) = s.regions[k - 1].density
        {
            return (format!("regions.{}.density", k - 1), d);
        }
        match (s.material.density, s.material.total_mass) {
            (Some(d), _) => ("material.density".into(), d),
            (None, Some(total)) => ("material.total_mass".into(), total),
            (None, None) => ("material.density".into(), densities[0]),
        }
    };
    let mut masses = vec![0.0; mesh.n_vertices()];
    // The densest triangle around each vertex, to name when its sum overflows.
    let mut densest: Vec<Option<usize>> = vec![None; mesh.n_vertices()];
    for (t, (tri, el)) in mesh.triangles().iter().zip(mesh.elements()).enumerate() {
        let k = region(t);
        let third = densities[k] * el.area / 3.0;
        if !third.is_normal() {
            let (field, value) = source(k);
            let (size, flow) = if third.is_finite() {
                ("small", "underflow")
            } else {
                ("large", "overflow")
            };
            return Err(scene.error(
                &field,
                readable(value),
                &format!(
                    "too {size}: the lumped vertex masses {flow} (triangles[{t}], of {:.3e} m^2 at {} kg/m^3, would give each of its vertices {third:e} kg)",
                    el.area,
                    readable(densities[k])
                ),
            ));
        }
        for &v in tri {
            let v = v as usize;
            masses[v] += third;
            if densest[v].is_none_or(|d| densities[k] > densities[region(d)]) {
                densest[v] = Some(t);
            }
        }
    }
    if let Some(v) = masses.iter().position(|m| !m.is_finite()) {
        let (field, value) = source(densest[v].map_or(0, region));
        return Err(scene.error(
            &field,
            readable(value),
            &format!(
                "too large: the lumped vertex masses overflow (vertex {v} would weigh {:e} kg)",
                masses[v]
            ),
        ));
    }
    Ok(())
}

/// Add the scene's loads to `model`: gravity and the `[[traction]]` entries (consistent nodal
/// forces on the boundary edges whose two end vertices lie in each box).
fn add_loads<E: Energy>(scene: &LoadedScene, model: &mut Model<E>) -> Result<(), SceneError> {
    let s = &scene.scene;
    let err = solver_err(scene);
    model.set_gravity(v2(s.gravity)).map_err(&err)?;
    for (i, t) in s.traction.iter().enumerate() {
        let region = Region::in_box(v2(t.min), v2(t.max));
        match model.add_traction(&region, v2(t.traction)) {
            Ok(_) => {}
            Err(SolverError::InvalidParameter { value, .. }) => {
                // The only rule the validated scene can break: the box holds no boundary edge.
                return Err(scene.error(
                    &format!("traction.{i}"),
                    format!("min {:?} max {:?} ({value})", t.min, t.max),
                    "contains no boundary edge (an edge of the mesh boundary with both end vertices in the box)",
                ));
            }
            Err(e) => return Err(err(e)),
        }
    }
    Ok(())
}

/// A probe resolved to a vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct Probe {
    /// Name.
    pub name: String,
    /// The point asked for, m.
    pub point: [f64; 2],
    /// The nearest rest vertex.
    pub vertex: usize,
    /// Its rest position, m.
    pub rest: [f64; 2],
}

/// Each probe's nearest rest vertex (the lowest index on ties).
pub fn resolve_probes(scene: &LoadedScene, mesh: &Mesh) -> Vec<Probe> {
    scene
        .scene
        .probes
        .iter()
        .map(|p| {
            let target = v2(p.point);
            let (vertex, rest) = mesh
                .vertices()
                .iter()
                .enumerate()
                .min_by(|a, b| {
                    (a.1 - target)
                        .norm_squared()
                        .total_cmp(&(b.1 - target).norm_squared())
                })
                .map(|(i, x)| (i, [x.x, x.y]))
                .expect("a validated mesh has vertices");
            Probe {
                name: p.name.clone(),
                point: p.point,
                vertex,
                rest,
            }
        })
        .collect()
}

/// The scene's state at `t = 0`: at rest, in the rest shape or the `[initial]` deformation.
pub fn initial_state<E: Energy>(
    scene: &LoadedScene,
    model: &Model<E>,
) -> Result<State, SceneError> {
    match &scene.scene.initial {
        None => Ok(State::at_rest(model)),
        Some(init) => {
            let x = model
                .mesh()
                .vertices()
                .iter()
                .map(|p| {
                    let q = init.apply([p.x, p.y]);
                    Vec2::new(q[0], q[1])
                })
                .collect();
            let v = vec![Vec2::zeros(); model.mesh().n_vertices()];
            State::new(model, x, v)
                .map_err(|e| SceneError::Scene(format!("{}: initial: {e}", scene.origin)))
        }
    }
}

/// The scene's stepper for `model`: the chosen solver of the registry, built from its own
/// parameters (validated by their own rules).
pub fn build_stepper<E: Energy>(
    scene: &LoadedScene,
    model: &Model<E>,
) -> Result<AnyStepper, SceneError> {
    scene
        .scene
        .solver
        .params()
        .build(model)
        .map_err(solver_err(scene))
}

/// The model, the stepper and the initial state of `scene` on `mesh`, with the energy chosen
/// at run time ([`AnyEnergy`]): what a host that steps a scene itself needs (the interactive
/// app, the Python package). [`crate::run::run`] builds the same, monomorphised per energy.
pub fn build_simulation(
    scene: &LoadedScene,
    mesh: Mesh,
) -> Result<(Model<AnyEnergy>, AnyStepper, State), SceneError> {
    let model = build_model(scene, mesh, energy(scene)?)?;
    let stepper = build_stepper(scene, &model)?;
    let state = initial_state(scene, &model)?;
    Ok((model, stepper, state))
}

/// A mass for a message: four decimals without trailing zeros (`60`, `0.125`), scientific
/// notation beyond `[1e-3, 1e9)` (`1e300`, not three hundred digits).
fn kilograms(m: f64) -> String {
    if (1e-3..1e9).contains(&m) {
        let s = format!("{m:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        format!("{m:.4e}")
    }
}

/// Whether the scene's elements are averaged nodal pressure triangles: `material.formulation`
/// resolved (`auto`: plane strain, an elastic material with `nu >= Formulation::AUTO_POISSON`
/// and a solver that supports it).
pub fn averaged_pressure(scene: &LoadedScene) -> bool {
    let s = &scene.scene;
    match s.material.formulation {
        Formulation::Standard => false,
        Formulation::AveragedPressure => true,
        Formulation::Auto => {
            let nearly_incompressible = std::iter::once(s.material.poisson_ratio)
                .chain(
                    (s.regions.iter())
                        .filter(|r| !r.rigid)
                        .map(|r| r.poisson_ratio.unwrap_or(s.material.poisson_ratio)),
                )
                .any(|nu| nu >= Formulation::AUTO_POISSON);
            s.material.plane == PlaneModel::PlaneStrain
                && nearly_incompressible
                && s.solver.kind.capabilities().averaged_pressure
        }
    }
}
