//! What a budget run records frame by frame ([`Trajectory`]), the phases it is judged over
//! ([`Windows`]) and its errors against the reference ([`Errors`]).
//!
//! Everything here is a pure function of the recorded trajectories and the [`Layout`], so the
//! written `trajectories.json` reproduces every number of the tables bit for bit.

use fem_scene::SceneError;
use fem_scene::run::{Frame, FrameSink};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// A cell of the mesh the errors are taken over: a triangle (`[u32; 3]`, 2D) or a tetrahedron
/// (`[u32; 4]`, 3D), with the point type of its dimension.
pub trait Cell:
    Copy + Default + PartialEq + std::fmt::Debug + Serialize + DeserializeOwned + Send + Sync + 'static
{
    /// A position: `[f64; 2]` or `[f64; 3]`.
    type Point: Copy
        + Default
        + PartialEq
        + std::fmt::Debug
        + Serialize
        + DeserializeOwned
        + AsRef<[f64]>
        + Send
        + Sync
        + 'static;
    /// What the cell is called in messages: `triangle`, `tetrahedron`.
    const NAME: &'static str;
    /// Its plural: `triangles`, `tetrahedra`.
    const PLURAL: &'static str;
    /// Its signed measure at positions `x` (area in m^2, volume in m^3); at most 0 when
    /// inverted or flat.
    fn measure(self, x: &[Self::Point]) -> f64;
}

impl Cell for [u32; 3] {
    type Point = [f64; 2];
    const NAME: &'static str = "triangle";
    const PLURAL: &'static str = "triangles";
    fn measure(self, x: &[[f64; 2]]) -> f64 {
        let (a, b, c) = (
            x[self[0] as usize],
            x[self[1] as usize],
            x[self[2] as usize],
        );
        0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    }
}

impl Cell for [u32; 4] {
    type Point = [f64; 3];
    const NAME: &'static str = "tetrahedron";
    const PLURAL: &'static str = "tetrahedra";
    fn measure(self, x: &[[f64; 3]]) -> f64 {
        let p = self.map(|i| x[i as usize]);
        let e = |k: usize| [0, 1, 2].map(|c| p[k][c] - p[0][c]);
        let (a, b, c) = (e(1), e(2), e(3));
        (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))
            / 6.0
    }
}

/// The mesh and the labels the errors are taken over (written to `trajectories.json`); `C`
/// is its cell: a triangle (2D, the default) or a tetrahedron (3D).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(bound(serialize = "", deserialize = ""))]
pub struct Layout<C: Cell = [u32; 3]> {
    /// Rest positions, m.
    pub rest: Vec<C::Point>,
    /// The cells: triangles in 2D, tetrahedra in 3D.
    #[serde(alias = "triangles")]
    pub cells: Vec<C>,
    /// The material region of each cell (0: the base material, `k`: the `k`-th
    /// `[[regions]]` entry).
    pub region_tags: Vec<u32>,
    /// Each material region: its name and whether it is rigid.
    pub regions: Vec<RegionInfo>,
    /// The material region of each rigid body, in the model's order.
    pub body_regions: Vec<u32>,
    /// The contact targets, in the order of [`Trajectory::contact`]: `ground` (when the scene
    /// has one), then each obstacle's name.
    pub contact_targets: Vec<String>,
    /// Whether the first contact target is the ground.
    pub has_ground: bool,
    /// Seconds per frame.
    pub frame_dt: f64,
}

/// A material region's name and kind.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RegionInfo {
    /// The region's name.
    pub name: String,
    /// Whether it is rigid (reports its wrench, not its stress).
    pub rigid: bool,
}

impl<C: Cell> Layout<C> {
    /// Rest measure of each cell (area in 2D, m^2; volume in 3D, m^3).
    pub fn areas(&self) -> Vec<f64> {
        self.cells.iter().map(|t| t.measure(&self.rest)).collect()
    }

    /// Whether cell `t` is soft tissue (in a deformable region).
    fn soft(&self, t: usize) -> bool {
        !self.regions[self.region_tags[t] as usize].rigid
    }
}

/// A run's record, one entry per frame (the first at t = 0); `P` is the point of its
/// dimension (`[f64; 2]`, the default, or `[f64; 3]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(bound(
    serialize = "P: Serialize",
    deserialize = "P: serde::de::DeserializeOwned"
))]
pub struct Trajectory<P = [f64; 2]> {
    /// Positions, m.
    pub frames: Vec<Vec<P>>,
    /// Per-cell von Mises stress, Pa (rigid cells 0; `null` in JSON where the stress
    /// is undefined, an inverted cell; such a cell counts as unstressed in the errors,
    /// so its whole reference stress is error).
    #[serde(with = "nan_null")]
    pub von_mises: Vec<Vec<f64>>,
    /// Per contact target ([`Layout::contact_targets`]): `[peak vertex pressure (Pa), total
    /// normal force (N per metre of thickness)]` of the contacts of the step that produced
    /// the frame (pressure as in [`fem_solvers::pressure`], the target's contacts alone).
    pub contact: Vec<Vec<[f64; 2]>>,
    /// Per rigid body: the tissue's force on it (x, y; N per metre) and torque about its
    /// centroid (N m per metre).
    pub rigid: Vec<Vec<[f64; 3]>>,
    /// The body's kinetic energy (soft and rigid triangles, lumped masses), J per metre.
    pub kinetic_energy: Vec<f64>,
}

/// A number written as `null` when NaN (serde_json's way) and read back as NaN.
pub(crate) fn nan_or_number<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// `null` for NaN, both ways (JSON has no NaN).
mod nan_null {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &[Vec<f64>], s: S) -> Result<S::Ok, S::Error> {
        let opt: Vec<Vec<Option<f64>>> = v
            .iter()
            .map(|f| f.iter().map(|x| x.is_finite().then_some(*x)).collect())
            .collect();
        opt.serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec<f64>>, D::Error> {
        let opt: Vec<Vec<Option<f64>>> = Vec::deserialize(d)?;
        Ok(opt
            .into_iter()
            .map(|f| f.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect())
            .collect())
    }
}

/// The budget's cost cap as a recorder applies it: the run is stopped (an error from the
/// sink) at the first frame after `cap` seconds have passed since its first frame.
pub(crate) struct CostCap {
    cap: Option<f64>,
    started: Option<std::time::Instant>,
    /// The run was stopped by the cap.
    pub over: bool,
}

impl CostCap {
    fn new(cap: Option<f64>) -> Self {
        CostCap {
            cap,
            started: None,
            over: false,
        }
    }

    /// Start the clock at the first frame; an error once the cap has passed.
    fn check(&mut self) -> Result<(), SceneError> {
        match (self.started, self.cap) {
            (None, _) => self.started = Some(std::time::Instant::now()),
            (Some(t0), Some(cap)) if t0.elapsed().as_secs_f64() > cap => {
                self.over = true;
                return Err(SceneError::Usage("over the budget's cost cap".into()));
            }
            _ => {}
        }
        Ok(())
    }
}

/// A [`FrameSink`] filling a [`Trajectory`].
pub(crate) struct Recorder {
    pub trajectory: Trajectory,
    /// The mesh and its regions, from the first frame (targets and frame step left empty).
    pub layout: Layout,
    /// Stops the run once it passed the budget's cost cap.
    pub cap: CostCap,
    /// Lumped vertex masses, kg per metre (sized on the first frame).
    masses: Vec<f64>,
    edges: Vec<[u32; 2]>,
    /// Scratch: one target's contacts.
    mine: Vec<fem_solvers::Contact>,
    pressure: fem_solvers::ContactPressure,
    has_ground: bool,
    obstacles: usize,
}

impl Recorder {
    pub(crate) fn new(has_ground: bool, obstacles: usize, cap: Option<f64>) -> Self {
        Recorder {
            trajectory: Trajectory::default(),
            layout: Layout::default(),
            cap: CostCap::new(cap),
            masses: Vec::new(),
            edges: Vec::new(),
            mine: Vec::new(),
            pressure: fem_solvers::ContactPressure::new(),
            has_ground,
            obstacles,
        }
    }
}

impl FrameSink for Recorder {
    fn frame(&mut self, f: &Frame<'_>) -> Result<(), SceneError> {
        use fem_solvers::ContactKind;
        self.cap.check()?;
        if self.masses.is_empty() {
            let tags = &f.regions.tags;
            let mut body_regions = vec![0u32; f.rigid.len()];
            for (t, &b) in f.rigid_tags.iter().enumerate() {
                if b > 0 {
                    body_regions[b as usize - 1] = tags[t];
                }
            }
            self.layout = Layout {
                rest: f.mesh.vertices().iter().map(|p| [p.x, p.y]).collect(),
                cells: f.mesh.triangles().to_vec(),
                region_tags: tags.clone(),
                regions: f
                    .regions
                    .materials
                    .iter()
                    .map(|m| RegionInfo {
                        name: m.name.clone(),
                        rigid: m.rigid,
                    })
                    .collect(),
                body_regions,
                contact_targets: Vec::new(),
                has_ground: false,
                frame_dt: 0.0,
            };
            self.masses = f
                .mesh
                .lumped_masses_from_densities(&f.regions.element_densities())
                .map_err(|e| SceneError::Scene(format!("budget: lumped masses: {e}")))?;
            self.edges = fem_solvers::model::boundary_edges(f.mesh.triangles());
        }
        let t = &mut self.trajectory;
        t.frames
            .push(f.positions.iter().map(|p| [p.x, p.y]).collect());
        t.von_mises.push(f.von_mises.to_vec());
        let kinetic: f64 = f
            .velocities
            .iter()
            .zip(&self.masses)
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum();
        t.kinetic_energy.push(kinetic);
        t.rigid.push(
            f.rigid
                .iter()
                .map(|b| [b.force[0], b.force[1], b.torque])
                .collect(),
        );
        // Targets: the ground (when there is one), then each obstacle.
        let targets = usize::from(self.has_ground) + self.obstacles;
        let mut row = Vec::with_capacity(targets);
        for k in 0..targets {
            let ground = self.has_ground && k == 0;
            let obstacle = k.saturating_sub(usize::from(self.has_ground)) as u32;
            self.mine.clear();
            self.mine
                .extend(f.contacts.iter().copied().filter(|c| match c.kind {
                    ContactKind::VertexGround { .. } => ground,
                    ContactKind::VertexObstacle { obstacle: o, .. }
                    | ContactKind::CornerEdge { obstacle: o, .. } => !ground && o == obstacle,
                    _ => false,
                }));
            self.pressure
                .update_parts(&self.edges, f.positions, &self.mine);
            row.push([
                self.pressure.peak().map_or(0.0, |p| p.pressure),
                self.pressure.total_force(),
            ]);
        }
        t.contact.push(row);
        Ok(())
    }
}

/// A [`FrameSink3`](fem_scene::solid::FrameSink3) filling a 3D [`Trajectory`]: positions,
/// per-tetrahedron von Mises stress and the kinetic energy (a 3D scene has no regions, contact
/// or rigid bodies: their rows stay empty).
pub(crate) struct Recorder3 {
    pub trajectory: Trajectory<[f64; 3]>,
    /// The mesh, from the first frame (the rest state).
    pub layout: Layout<[u32; 4]>,
    /// Stops the run once it passed the budget's cost cap.
    pub cap: CostCap,
}

impl Recorder3 {
    pub(crate) fn new(cap: Option<f64>) -> Self {
        Recorder3 {
            trajectory: Trajectory::default(),
            layout: Layout::default(),
            cap: CostCap::new(cap),
        }
    }
}

impl fem_scene::solid::FrameSink3 for Recorder3 {
    fn frame(&mut self, f: &fem_scene::solid::FrameView3<'_>) -> Result<(), SceneError> {
        self.cap.check()?;
        let points = |x: &[fem_core::dim::Vec3]| x.iter().map(|p| [p.x, p.y, p.z]).collect();
        if self.layout.cells.is_empty() {
            self.layout = Layout {
                rest: points(f.x),
                cells: f.tetrahedra.to_vec(),
                region_tags: vec![0; f.tetrahedra.len()],
                regions: vec![RegionInfo {
                    name: "body".into(),
                    rigid: false,
                }],
                ..Layout::default()
            };
        }
        let t = &mut self.trajectory;
        t.frames.push(points(f.x));
        t.von_mises.push(f.von_mises.to_vec());
        t.kinetic_energy.push(
            f.v.iter()
                .zip(f.masses)
                .map(|(v, m)| 0.5 * m * v.norm_squared())
                .sum(),
        );
        t.contact.push(Vec::new());
        t.rigid.push(Vec::new());
        Ok(())
    }
}

/// A half-open range of frame indices `[start, end)`.
pub type Span = [usize; 2];

/// The phases a run is judged over, found on the reference.
///
/// - **whole**: every frame.
/// - **impact**: from the first frame with contact in the reference (with an obstacle; with
///   the ground when the scene has no obstacle) until its kinetic energy has fallen for good
///   below `settle` times its peak (the peak taken from the first contact on): it ends after
///   the last frame at or above that threshold.
/// - **sustained**: the frames after the impact window, to the end of the run.
///
/// Without contact in the reference there are no phases (both `None`). A reference that
/// does not settle within the run has an impact window to the end and no sustained window.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Windows {
    /// Every frame.
    pub whole: Span,
    /// The impact window.
    pub impact: Option<Span>,
    /// The sustained window.
    pub sustained: Option<Span>,
    /// The kinetic-energy fraction that ends the impact.
    pub settle: f64,
}

impl Windows {
    /// The windows of `reference` on `layout` (see the type's docs).
    pub fn find<C: Cell>(
        layout: &Layout<C>,
        reference: &Trajectory<C::Point>,
        settle: f64,
    ) -> Windows {
        let n = reference.frames.len();
        // The obstacles' targets, or the ground alone.
        let from = usize::from(layout.has_ground && layout.contact_targets.len() > 1);
        let contact_at = |f: usize| {
            reference
                .contact
                .get(f)
                .is_some_and(|row| row.iter().skip(from).any(|c| c[1] > 0.0))
        };
        let mut w = Windows {
            whole: [0, n],
            impact: None,
            sustained: None,
            settle,
        };
        let Some(first) = (0..n).find(|&f| contact_at(f)) else {
            return w;
        };
        let ke = &reference.kinetic_energy;
        let peak = ke[first..].iter().copied().fold(0.0, f64::max);
        let threshold = settle * peak;
        let end = (first..n)
            .rev()
            .find(|&f| ke[f] >= threshold)
            .map_or(first + 1, |f| f + 1);
        w.impact = Some([first, end]);
        if end < n {
            w.sustained = Some([end, n]);
        }
        w
    }

    /// The window named `phase`.
    pub fn get(&self, phase: Phase) -> Option<Span> {
        match phase {
            Phase::Whole => Some(self.whole),
            Phase::Impact => self.impact,
            Phase::Sustained => self.sustained,
        }
    }
}

/// A phase of the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Phase {
    /// Every frame.
    Whole,
    /// From the first contact until the reference settles.
    Impact,
    /// After the reference settled.
    Sustained,
}

impl Phase {
    /// Its name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Whole => "whole run",
            Phase::Impact => "impact",
            Phase::Sustained => "sustained",
        }
    }
}

/// A relative error `|a - b| / |b|`; `None` when the reference `b` is 0 (undefined).
fn relative(a: f64, b: f64) -> Option<f64> {
    (b != 0.0).then(|| (a - b).abs() / b.abs())
}

/// A run's errors against the reference in one window.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct WindowErrors {
    /// RMS over all vertices and the window's frames of the distance to the reference, m (NaN
    /// for a window without frames).
    #[serde(deserialize_with = "nan_or_number")]
    pub position_rms: f64,
    /// Largest distance to the reference, m.
    pub position_max: f64,
    /// The soft tissue (every triangle of a deformable region): relative L2 error of the von
    /// Mises field, `sqrt(sum_f sum_e a_e (s_e - s_e,ref)^2 / sum_f sum_e a_e s_e,ref^2)` (`a_e`
    /// the rest area); `None` when the reference is unstressed.
    pub stress_l2: Option<f64>,
    /// The soft tissue's peak von Mises stress over the window, relative to the reference's.
    pub stress_peak: Option<f64>,
    /// The largest relative error of a contact target's peak pressure (over the targets the
    /// reference touches in the window); `None` without contact.
    pub pressure_peak: Option<f64>,
    /// Per material region: stress (deformable) or wrench (rigid) errors.
    pub regions: Vec<RegionErrors>,
    /// Per contact target: its peak pressure and impulse errors.
    pub contact: Vec<ContactErrors>,
    /// Largest over frames of `sum_e |a_e - a_e,ref| / A`: the absolute area error (volume
    /// in 3D).
    pub area: f64,
    /// Most cells (triangles, tetrahedra) with `det F <= 0` in one frame.
    pub inverted: usize,
}

/// One material region's errors in a window.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RegionErrors {
    /// The region's name.
    pub region: String,
    /// Deformable: the relative L2 error of its von Mises field (as
    /// [`WindowErrors::stress_l2`]).
    pub stress_l2: Option<f64>,
    /// Deformable: the relative error of its peak von Mises stress.
    pub stress_peak: Option<f64>,
    /// Rigid: the relative L2 error of the tissue's force on its bodies,
    /// `sqrt(sum |F - F_ref|^2 / sum |F_ref|^2)` over its bodies and the window's frames.
    pub force: Option<f64>,
    /// Rigid: the same for the torque.
    pub torque: Option<f64>,
}

/// One contact target's errors in a window.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactErrors {
    /// `ground` or the obstacle's name.
    pub target: String,
    /// The reference's peak pressure over the window, Pa.
    pub reference_peak_pressure: f64,
    /// The relative error of the peak pressure; `None` when the reference has no contact.
    pub peak_pressure: Option<f64>,
    /// The reference's impulse over the window (total normal force at each frame times the
    /// frame's duration, summed), N s per metre.
    pub reference_impulse: f64,
    /// The relative error of the impulse.
    pub impulse: Option<f64>,
}

/// A run's errors against the reference: per window.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Errors {
    /// Over every frame.
    pub whole: WindowErrors,
    /// Over the impact window.
    pub impact: Option<WindowErrors>,
    /// Over the sustained window.
    pub sustained: Option<WindowErrors>,
}

impl Errors {
    /// The errors of `phase`, when the phase exists.
    pub fn get(&self, phase: Phase) -> Option<&WindowErrors> {
        match phase {
            Phase::Whole => Some(&self.whole),
            Phase::Impact => self.impact.as_ref(),
            Phase::Sustained => self.sustained.as_ref(),
        }
    }
}

/// The errors of `run` against `reference` over `windows`; frames beyond the shorter of the
/// two are not compared.
pub fn errors<C: Cell>(
    layout: &Layout<C>,
    windows: &Windows,
    run: &Trajectory<C::Point>,
    reference: &Trajectory<C::Point>,
) -> Errors {
    let n = run.frames.len().min(reference.frames.len());
    let clip = |s: Span| [s[0].min(n), s[1].min(n)];
    let areas = layout.areas();
    Errors {
        whole: window(layout, &areas, clip(windows.whole), run, reference),
        impact: windows
            .impact
            .map(|s| window(layout, &areas, clip(s), run, reference)),
        sustained: windows
            .sustained
            .map(|s| window(layout, &areas, clip(s), run, reference)),
    }
}

/// Sums of a stress field's error over a set of triangles.
#[derive(Default)]
struct StressSums {
    diff2: f64,
    ref2: f64,
    peak: f64,
    ref_peak: f64,
}

impl StressSums {
    fn add(&mut self, a: f64, s: f64, r: f64) {
        let s = if s.is_finite() { s } else { 0.0 };
        let r = if r.is_finite() { r } else { 0.0 };
        self.diff2 += a * (s - r) * (s - r);
        self.ref2 += a * r * r;
        self.peak = self.peak.max(s);
        self.ref_peak = self.ref_peak.max(r);
    }

    fn l2(&self) -> Option<f64> {
        (self.ref2 > 0.0).then(|| (self.diff2 / self.ref2).sqrt())
    }

    fn peak(&self) -> Option<f64> {
        relative(self.peak, self.ref_peak)
    }
}

fn window<C: Cell>(
    layout: &Layout<C>,
    areas: &[f64],
    span: Span,
    run: &Trajectory<C::Point>,
    reference: &Trajectory<C::Point>,
) -> WindowErrors {
    let total: f64 = areas.iter().sum();
    let mut e = WindowErrors::default();
    let (mut sum, mut count) = (0.0, 0usize);
    let mut tissue = StressSums::default();
    let mut regions: Vec<StressSums> = layout
        .regions
        .iter()
        .map(|_| StressSums::default())
        .collect();
    // Rigid regions: [force diff^2, force ref^2, torque diff^2, torque ref^2].
    let mut wrench = vec![[0.0f64; 4]; layout.regions.len()];
    let targets = layout.contact_targets.len();
    // Per target: [peak, reference peak, impulse, reference impulse].
    let mut contact = vec![[0.0f64; 4]; targets];
    for f in span[0]..span[1] {
        let (x, r) = (&run.frames[f], &reference.frames[f]);
        for (p, q) in x.iter().zip(r) {
            let d2: f64 = p
                .as_ref()
                .iter()
                .zip(q.as_ref())
                .map(|(a, b)| (a - b) * (a - b))
                .sum();
            sum += d2;
            count += 1;
            e.position_max = e.position_max.max(d2.sqrt());
        }
        let mut frame_area = 0.0;
        let mut inverted = 0;
        for t in &layout.cells {
            let a = t.measure(x);
            frame_area += (a - t.measure(r)).abs();
            inverted += usize::from(a <= 0.0);
        }
        e.area = e.area.max(frame_area / total);
        e.inverted = e.inverted.max(inverted);
        if let (Some(s), Some(sr)) = (run.von_mises.get(f), reference.von_mises.get(f)) {
            for (t, (&a, (&v, &vr))) in areas.iter().zip(s.iter().zip(sr)).enumerate() {
                if layout.soft(t) {
                    tissue.add(a, v, vr);
                    regions[layout.region_tags[t] as usize].add(a, v, vr);
                }
            }
        }
        if let (Some(b), Some(br)) = (run.rigid.get(f), reference.rigid.get(f)) {
            for ((w, wr), &region) in b.iter().zip(br).zip(&layout.body_regions) {
                let acc = &mut wrench[region as usize];
                acc[0] += (w[0] - wr[0]).powi(2) + (w[1] - wr[1]).powi(2);
                acc[1] += wr[0].powi(2) + wr[1].powi(2);
                acc[2] += (w[2] - wr[2]).powi(2);
                acc[3] += wr[2].powi(2);
            }
        }
        if let (Some(c), Some(cr)) = (run.contact.get(f), reference.contact.get(f)) {
            for (acc, (c, cr)) in contact.iter_mut().zip(c.iter().zip(cr)) {
                acc[0] = acc[0].max(c[0]);
                acc[1] = acc[1].max(cr[0]);
                acc[2] += c[1] * layout.frame_dt;
                acc[3] += cr[1] * layout.frame_dt;
            }
        }
    }
    e.position_rms = if count > 0 {
        (sum / count as f64).sqrt()
    } else {
        f64::NAN
    };
    e.stress_l2 = tissue.l2();
    e.stress_peak = tissue.peak();
    e.regions = layout
        .regions
        .iter()
        .enumerate()
        .map(|(k, info)| {
            let w = wrench[k];
            let ratio = |d: f64, r: f64| (r > 0.0).then(|| (d / r).sqrt());
            if info.rigid {
                RegionErrors {
                    region: info.name.clone(),
                    force: ratio(w[0], w[1]),
                    torque: ratio(w[2], w[3]),
                    ..RegionErrors::default()
                }
            } else {
                RegionErrors {
                    region: info.name.clone(),
                    stress_l2: regions[k].l2(),
                    stress_peak: regions[k].peak(),
                    ..RegionErrors::default()
                }
            }
        })
        .collect();
    e.contact = layout
        .contact_targets
        .iter()
        .zip(&contact)
        .map(|(name, acc)| ContactErrors {
            target: name.clone(),
            reference_peak_pressure: acc[1],
            peak_pressure: relative(acc[0], acc[1]),
            reference_impulse: acc[3],
            impulse: relative(acc[2], acc[3]),
        })
        .collect();
    e.pressure_peak = e
        .contact
        .iter()
        .filter_map(|c| c.peak_pressure)
        .reduce(f64::max);
    e
}

/// Why the errors of a run recorded as `t` cannot be measured (`position is not finite in 3
/// places (first at frame 7, vertex 12)`): the first kind of recorded
/// value the errors read that is not finite (a position; a soft triangle's von Mises stress
/// where the triangle is not inverted, an inverted one counting as unstressed; a contact
/// target's pressure or force; a rigid body's wrench; the kinetic energy), with how many and
/// where the first is. `None` when every such value is finite.
pub fn non_finite<C: Cell>(layout: &Layout<C>, t: &Trajectory<C::Point>) -> Option<String> {
    let first = |what: &str, count: usize, at: Option<(usize, String)>| {
        at.map(|(f, place)| {
            format!("{what} is not finite in {count} places (first at frame {f}, {place})")
        })
    };
    // Positions.
    let mut count = 0;
    let mut at = None;
    for (f, x) in t.frames.iter().enumerate() {
        for (v, p) in x.iter().enumerate() {
            if !p.as_ref().iter().all(|c| c.is_finite()) {
                count += 1;
                at = at.or(Some((f, format!("vertex {v}"))));
            }
        }
    }
    if let Some(s) = first("position", count, at) {
        return Some(s);
    }
    // Soft tissue stress, where the triangle is not inverted.
    let (mut count, mut at) = (0, None);
    for (f, s) in t.von_mises.iter().enumerate() {
        let Some(x) = t.frames.get(f) else { continue };
        for (k, (v, cell)) in s.iter().zip(&layout.cells).enumerate() {
            if !v.is_finite() && layout.soft(k) && cell.measure(x) > 0.0 {
                count += 1;
                at = at.or(Some((f, format!("{} {k}, not inverted", C::NAME))));
            }
        }
    }
    if let Some(s) = first("von Mises stress", count, at) {
        return Some(s);
    }
    let (mut count, mut at) = (0, None);
    for (f, row) in t.contact.iter().enumerate() {
        for (k, c) in row.iter().enumerate() {
            if !(c[0].is_finite() && c[1].is_finite()) {
                count += 1;
                let name = layout.contact_targets.get(k).map_or("?", String::as_str);
                at = at.or(Some((f, format!("target {name}"))));
            }
        }
    }
    if let Some(s) = first("contact pressure or force", count, at) {
        return Some(s);
    }
    let (mut count, mut at) = (0, None);
    for (f, row) in t.rigid.iter().enumerate() {
        for (b, w) in row.iter().enumerate() {
            if !w.iter().all(|x| x.is_finite()) {
                count += 1;
                at = at.or(Some((f, format!("rigid body {b}"))));
            }
        }
    }
    if let Some(s) = first("force or torque on a rigid body", count, at) {
        return Some(s);
    }
    let (mut count, mut at) = (0, None);
    for (f, k) in t.kinetic_energy.iter().enumerate() {
        if !k.is_finite() {
            count += 1;
            at = at.or(Some((f, "the whole body".to_owned())));
        }
    }
    first("kinetic energy", count, at)
}

impl WindowErrors {
    /// Every number in it is finite (an overflow, `inf` or `NaN`, makes the errors
    /// unmeasured).
    pub fn is_finite(&self) -> bool {
        let opt = |x: Option<f64>| x.is_none_or(f64::is_finite);
        self.position_rms.is_finite()
            && self.position_max.is_finite()
            && self.area.is_finite()
            && opt(self.stress_l2)
            && opt(self.stress_peak)
            && opt(self.pressure_peak)
            && self
                .regions
                .iter()
                .all(|r| opt(r.stress_l2) && opt(r.stress_peak) && opt(r.force) && opt(r.torque))
            && self.contact.iter().all(|c| {
                c.reference_peak_pressure.is_finite()
                    && c.reference_impulse.is_finite()
                    && opt(c.peak_pressure)
                    && opt(c.impulse)
            })
    }
}

impl Errors {
    /// Every number of every window is finite.
    pub fn is_finite(&self) -> bool {
        self.whole.is_finite()
            && self.impact.as_ref().is_none_or(WindowErrors::is_finite)
            && self.sustained.as_ref().is_none_or(WindowErrors::is_finite)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> (Layout, Trajectory) {
        let rest = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let layout = Layout {
            rest: rest.clone(),
            cells: vec![[0, 1, 2], [0, 2, 3]],
            region_tags: vec![0, 0],
            regions: vec![RegionInfo {
                name: "body".into(),
                rigid: false,
            }],
            frame_dt: 0.1,
            ..Layout::default()
        };
        let t = Trajectory {
            frames: vec![rest.clone(), rest],
            von_mises: vec![vec![1.0, 2.0], vec![1.0, 2.0]],
            contact: vec![Vec::new(), Vec::new()],
            rigid: vec![Vec::new(), Vec::new()],
            kinetic_energy: vec![0.0, 0.0],
        };
        (layout, t)
    }

    /// A stress that is not finite on a triangle that is not inverted makes the run
    /// unmeasured (the stress of a collapsed solver, an overflow); on an inverted triangle it
    /// counts as unstressed, as the errors' definition says.
    #[test]
    fn non_finite_stress_is_unmeasurable_unless_the_triangle_is_inverted() {
        let (layout, mut t) = square();
        assert_eq!(non_finite(&layout, &t), None);
        t.von_mises[1][0] = f64::NAN;
        let why = non_finite(&layout, &t).expect("NaN stress");
        assert!(
            why.contains("von Mises stress") && why.contains("frame 1, triangle 0"),
            "{why}"
        );
        // Invert triangle 0 in frame 1 (vertex 1 across the diagonal): its NaN is allowed.
        t.frames[1][1] = [0.0, 1.0];
        assert_eq!(non_finite(&layout, &t), None);
        t.kinetic_energy[0] = f64::INFINITY;
        assert!(non_finite(&layout, &t).unwrap().contains("kinetic energy"));
        t.frames[0][2] = [f64::NAN, 0.0];
        assert!(non_finite(&layout, &t).unwrap().contains("position"));
    }

    /// An error that overflowed is not finite, and the errors say so.
    #[test]
    fn errors_with_an_overflow_are_not_finite() {
        let (layout, reference) = square();
        let windows = Windows::find(&layout, &reference, 0.01);
        let mut run = reference.clone();
        run.von_mises[1][1] = 3.0;
        let e = errors(&layout, &windows, &run, &reference);
        assert!(e.is_finite(), "{e:?}");
        // The square of a von Mises stress of 1e300 Pa overflows.
        run.von_mises[1][1] = 1e300;
        let e = errors(&layout, &windows, &run, &reference);
        assert!(!e.is_finite(), "{e:?}");
    }
}
