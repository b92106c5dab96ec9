//! From a validated scene to the pieces of a run: the mesh, the model (masses, boundary
//! conditions, gravity, tractions, ground, obstacles), the probes' vertices and the stepper (or,
//! for `static`, the quasi-static solver's parameters).

use fem_core::energy::{AnyEnergy, Energy};
use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;
use fem_core::stress::VonMisesFormula;
use fem_core::{Lame, Material};
use fem_mesh::Mesh2;
use fem_mesh::camera::{Camera, Projection};
use fem_mesh::pipeline::{PipelineParams, mesh_surface};
use fem_mesh::structured::{Diagonal, RectangleParams, rectangle};
use fem_mesh::triangulate::TriangulateParams;
use fem_solvers::{
    ContactParams, ExplicitParams, ExplicitScheme, ExplicitStepper, Ground, ImplicitParams,
    ImplicitStepper, Model, NewtonParams, ObstacleMotion, Ordering, PbdParams, PbdStepper,
    PrescribedMotion, Region, SolverError, State, StaticParams, StepReport, Stepper, XpbdForm,
    XpbdParams, XpbdStepper,
};

use crate::error::CaseError;
use crate::scene::{
    DiagonalName, LoadedScene, MeshKind, MotionName, OrderingName, PlaneName, SchemeName,
    SolverKind, ViewName, XpbdFormName,
};

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

/// The scene's mesh: generated, read or meshed from a 3D model, then rotated and placed.
pub fn build_mesh(scene: &LoadedScene) -> Result<Mesh, CaseError> {
    let spec = &scene.scene.mesh;
    let mesh_err = |e: fem_mesh::MeshError| CaseError::Mesh(format!("{}: mesh: {e}", scene.origin));
    let mut mesh2: Mesh2 = match spec.kind.unwrap_or(MeshKind::Rectangle) {
        MeshKind::Rectangle => rectangle(&RectangleParams {
            origin: spec.origin.unwrap_or([0.0, 0.0]),
            width: spec.width.unwrap_or(1.0),
            height: spec.height.unwrap_or(1.0),
            nx: spec.nx.unwrap_or(1),
            ny: spec.ny.unwrap_or(1),
            diagonal: match spec.diagonal.unwrap_or_default() {
                DiagonalName::Right => Diagonal::Right,
                DiagonalName::Left => Diagonal::Left,
                DiagonalName::Alternating => Diagonal::Alternating,
                DiagonalName::Crossed => Diagonal::Crossed,
            },
        })
        .map_err(mesh_err)?,
        MeshKind::File => {
            let path = scene.resolve(spec.path.as_deref().unwrap_or("".as_ref()));
            fem_mesh::io::read_mesh_json(&path).map_err(mesh_err)?
        }
        MeshKind::Model | MeshKind::Body => {
            mesh_pipeline(scene)?
                .expect("a model or body mesh goes through the pipeline")
                .mesh
        }
    };
    place(&mut mesh2, spec.rotate_deg.unwrap_or(0.0), spec.align_min);
    let vertices = mesh2
        .vertices
        .iter()
        .map(|p| Vec2::new(p[0], p[1]))
        .collect();
    let triangles = mesh2
        .triangles
        .iter()
        .map(|t| t.map(|i| i as u32))
        .collect();
    Mesh::new(vertices, triangles)
        .map_err(|e| CaseError::Mesh(format!("{}: mesh: {e}", scene.origin)))
}

/// The mesh pipeline's output (every stage, for Figure 1) for a scene whose mesh comes from a
/// 3D model or the built-in body, before the scene's rotation and alignment; `None` for the
/// other mesh kinds.
pub fn mesh_pipeline(
    scene: &LoadedScene,
) -> Result<Option<fem_mesh::pipeline::PipelineOutput>, CaseError> {
    let spec = &scene.scene.mesh;
    let mesh_err = |e: fem_mesh::MeshError| CaseError::Mesh(format!("{}: mesh: {e}", scene.origin));
    let kind = spec.kind.unwrap_or(MeshKind::Rectangle);
    let mut surface = match kind {
        MeshKind::Model => {
            let path = scene.resolve(spec.path.as_deref().unwrap_or("".as_ref()));
            let options = fem_mesh::load::LoadOptions {
                groups: spec.groups.clone().unwrap_or_default(),
            };
            fem_mesh::load::load_model(&path, &options).map_err(mesh_err)?
        }
        MeshKind::Body => fem_mesh::body::human_body(),
        MeshKind::Rectangle | MeshKind::File => return Ok(None),
    };
    surface.scale(spec.scale.unwrap_or(1.0));
    let (lo, hi) = surface.bounds().ok_or_else(|| {
        CaseError::Mesh(format!("{}: mesh: the model has no vertex", scene.origin))
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
    mesh_surface(surface, &params).map(Some).map_err(mesh_err)
}

/// Rotate by `deg` degrees counter-clockwise about the origin, then translate the bounding
/// box's lower-left corner to `align_min` (when given).
fn place(mesh: &mut Mesh2, deg: f64, align_min: Option<[f64; 2]>) {
    if deg != 0.0 {
        let (s, c) = deg.to_radians().sin_cos();
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
pub fn lame(scene: &LoadedScene) -> Result<Lame, CaseError> {
    let m = &scene.scene.material;
    // The density passed here only matters for wave speeds; masses come from the model.
    let material = Material::new(m.youngs_modulus, m.poisson_ratio, 1.0)
        .map_err(|e| CaseError::Scene(format!("{}: material: {e}", scene.origin)))?;
    Ok(material.lame(m.plane.model()))
}

/// The von Mises formula matching the scene's plane model.
pub fn von_mises_formula(scene: &LoadedScene) -> VonMisesFormula {
    match scene.scene.material.plane {
        PlaneName::PlaneStrain => VonMisesFormula::PlaneStrain {
            poisson_ratio: scene.scene.material.poisson_ratio,
        },
        PlaneName::PlaneStress => VonMisesFormula::PlaneStress,
    }
}

/// The scene's energy.
pub fn energy(scene: &LoadedScene) -> Result<AnyEnergy, CaseError> {
    let kind = scene.scene.energy.0;
    kind.build(lame(scene)?)
        .map_err(|e| CaseError::Scene(format!("{}: energy = {kind}: {e}", scene.origin)))
}

fn solver_err(scene: &LoadedScene) -> impl Fn(SolverError) -> CaseError + '_ {
    move |e| CaseError::Solver(format!("{}: {e}", scene.origin))
}

fn v2(p: [f64; 2]) -> Vec2 {
    Vec2::new(p[0], p[1])
}

/// The model of the scene with the given mesh and energy.
pub fn build_model<E: Energy>(
    scene: &LoadedScene,
    mesh: Mesh,
    energy: E,
) -> Result<Model<E>, CaseError> {
    let mut model = build_unloaded_model(scene, mesh, energy)?;
    add_loads(scene, &mut model)?;
    Ok(model)
}

/// The model of the scene without its loads: no gravity and no traction (masses, boundary
/// conditions, ground, obstacles and contact parameters as in [`build_model`]).
fn build_unloaded_model<E: Energy>(
    scene: &LoadedScene,
    mesh: Mesh,
    energy: E,
) -> Result<Model<E>, CaseError> {
    let s = &scene.scene;
    let err = solver_err(scene);
    let mut model = match (s.material.total_mass, s.material.density) {
        (Some(total), _) => Model::with_total_mass(mesh, energy, total),
        (None, Some(density)) => Model::with_density(mesh, energy, density),
        (None, None) => unreachable!("validated: one of total_mass and density is given"),
    }
    .map_err(&err)?;
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
                end: p.end.unwrap_or(end_of_run.max(p.start)),
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
        model.add_obstacle(&polygon, motion).map_err(&err)?;
    }
    if let Some(c) = &s.contact {
        let d = ContactParams::default();
        model
            .set_contact_params(ContactParams {
                stiffness: c.stiffness.unwrap_or(d.stiffness),
                damping_ratio: c.damping_ratio.unwrap_or(d.damping_ratio),
                friction: c.friction.unwrap_or(d.friction),
            })
            .map_err(&err)?;
    }
    Ok(model)
}

/// Add the scene's loads to `model`: gravity and the `[[traction]]` entries (consistent nodal
/// forces on the boundary edges whose two end vertices lie in each box).
fn add_loads<E: Energy>(scene: &LoadedScene, model: &mut Model<E>) -> Result<(), CaseError> {
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

/// The displacement each prescribed vertex has at the end of the run (`t = dt * steps`): its
/// schedule's velocity times the part of `[0, dt * steps]` inside its window, the later of two
/// regions holding a vertex winning (as in the model), as `(vertex, displacement)` in vertex
/// order. The static solver moves prescribed vertices to this displacement, in proportion to
/// the load factor.
pub fn prescribed_displacements(
    scene: &LoadedScene,
    rest: &[Vec2],
) -> Result<Vec<(usize, Vec2)>, CaseError> {
    let s = &scene.scene;
    let err = solver_err(scene);
    let end_of_run = s.solver.dt * s.solver.steps as f64;
    let mut out = vec![None; rest.len()];
    for (i, p) in s.prescribed.iter().enumerate() {
        let motion = PrescribedMotion {
            region: Region::in_box(v2(p.min), v2(p.max)),
            velocity: v2(p.velocity),
            start: p.start,
            end: p.end.unwrap_or(end_of_run.max(p.start)),
        };
        let u = motion.mean_velocity(0.0, end_of_run) * end_of_run;
        for v in motion
            .region
            .select(rest, &format!("prescribed.{i}"))
            .map_err(&err)?
        {
            out[v] = Some(u);
        }
    }
    Ok(out
        .into_iter()
        .enumerate()
        .filter_map(|(v, u)| u.map(|u| (v, u)))
        .collect())
}

/// The Newton settings of the scene (`solver.tolerance`, `solver.max_iterations`).
pub fn newton_params(scene: &LoadedScene) -> NewtonParams {
    let v = &scene.scene.solver;
    NewtonParams {
        tolerance: v.tolerance,
        max_iterations: v.max_iterations,
        ..NewtonParams::default()
    }
}

/// The quasi-static solver's parameters (`solver.load_steps`, the Newton settings).
pub fn static_params(scene: &LoadedScene) -> StaticParams {
    StaticParams {
        load_steps: scene.scene.solver.load_steps,
        newton: newton_params(scene),
        ..StaticParams::default()
    }
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

/// One of the available steppers, chosen by the scene.
#[derive(Debug)]
pub enum AnyStepper {
    /// Explicit FEM.
    Explicit(ExplicitStepper),
    /// PBD.
    Pbd(PbdStepper),
    /// XPBD.
    Xpbd(XpbdStepper),
    /// Implicit Euler (boxed: its Newton workspace makes it the largest variant by far).
    Implicit(Box<ImplicitStepper>),
}

impl AnyStepper {
    /// The explicit stability check, when the stepper is explicit and `dt` exceeds the limit.
    pub fn time_step_warning(&self) -> Option<String> {
        match self {
            AnyStepper::Explicit(s) => s.time_step_check().warning(),
            _ => None,
        }
    }
}

impl Stepper for AnyStepper {
    fn dt(&self) -> Real {
        match self {
            AnyStepper::Explicit(s) => s.dt(),
            AnyStepper::Pbd(s) => s.dt(),
            AnyStepper::Xpbd(s) => s.dt(),
            AnyStepper::Implicit(s) => s.dt(),
        }
    }

    fn step<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError> {
        match self {
            AnyStepper::Explicit(s) => s.step(model, state),
            AnyStepper::Pbd(s) => s.step(model, state),
            AnyStepper::Xpbd(s) => s.step(model, state),
            AnyStepper::Implicit(s) => s.step(model, state),
        }
    }
}

/// The scene's stepper for `model`. A `static` scene has no stepper (the run loop drives the
/// quasi-static solver with [`static_params`]): asking for one is an error.
pub fn build_stepper<E: Energy>(
    scene: &LoadedScene,
    model: &Model<E>,
) -> Result<AnyStepper, CaseError> {
    let v = &scene.scene.solver;
    let err = solver_err(scene);
    let ordering = match v.ordering {
        OrderingName::GaussSeidel => Ordering::GaussSeidel,
        OrderingName::Coloured => Ordering::Coloured,
        OrderingName::Jacobi => Ordering::Jacobi {
            relaxation: v.relaxation,
        },
    };
    Ok(match v.kind {
        SolverKind::Explicit => AnyStepper::Explicit(
            ExplicitStepper::new(
                model,
                ExplicitParams {
                    dt: v.dt,
                    damping: v.damping,
                    scheme: match v.scheme {
                        SchemeName::Symplectic => ExplicitScheme::SymplecticEuler,
                        SchemeName::ForwardEuler => ExplicitScheme::ForwardEuler,
                    },
                },
            )
            .map_err(&err)?,
        ),
        SolverKind::Pbd => AnyStepper::Pbd(
            PbdStepper::new(
                model,
                PbdParams {
                    dt: v.dt,
                    substeps: v.substeps,
                    iterations: v.iterations,
                    stiffness: v.stiffness,
                    damping: v.damping,
                    ordering,
                    ..PbdParams::default()
                },
            )
            .map_err(&err)?,
        ),
        SolverKind::Xpbd => AnyStepper::Xpbd(
            XpbdStepper::new(
                model,
                XpbdParams {
                    dt: v.dt,
                    substeps: v.substeps,
                    iterations: v.iterations,
                    compliance: v.compliance,
                    form: match v.xpbd_form {
                        XpbdFormName::Consistent => XpbdForm::Consistent,
                        XpbdFormName::Literal => XpbdForm::Literal,
                    },
                    damping: v.damping,
                    ordering,
                    ..XpbdParams::default()
                },
            )
            .map_err(&err)?,
        ),
        SolverKind::Implicit => AnyStepper::Implicit(Box::new(
            ImplicitStepper::new(
                model,
                ImplicitParams {
                    dt: v.dt,
                    damping: v.damping,
                    newton: newton_params(scene),
                },
            )
            .map_err(&err)?,
        )),
        SolverKind::Static => {
            return Err(scene.error(
                "solver.kind",
                v.kind,
                "has no time stepper: a static scene is run by `run_scene`, which drives the quasi-static solver",
            ));
        }
    })
}
