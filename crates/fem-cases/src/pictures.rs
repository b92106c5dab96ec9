//! Pictures of runs: a recorded frame as a PNG stress map, a run as an animated GIF, several
//! runs side by side with one colorbar, probe curves as charts. The drawing itself is
//! `fem-render`'s; this module turns a [`RunResult`] into what it draws. A picture of a run
//! with contact may carry the contact pressure along the boundary
//! ([`FramePicture::with_contact_pressure`]): a coloured thick line with a legend in kPa, over
//! the field (`fem_render::pressure`).

use std::borrow::Cow;
use std::path::Path;
use std::str::FromStr;

use fem_render::Image;
use fem_render::chart::{LineChart, Scale, Series};
use fem_render::colormap::Colormap;
use fem_render::frame::{
    FieldValues, FlatElements, FrameStyle, MeshView, Rendered, render, shown_values,
};
use fem_render::pressure::{PressureOverlay, draw_pressure};

use crate::run::{RunResult, Snapshot};
use fem_scene::SceneError;

/// The field a picture is coloured by.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FieldKind {
    /// Per-element von Mises stress, shown in kPa.
    #[default]
    VonMises,
    /// Per-vertex displacement magnitude `|x - X|`, shown in mm.
    Displacement,
    /// Per-element det F (area ratio), on a diverging colormap.
    DetF,
}

impl FieldKind {
    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::VonMises => "von-mises",
            Self::Displacement => "displacement",
            Self::DetF => "det-f",
        }
    }

    /// The colorbar label, unit, display scale and colormap.
    fn style(self) -> (&'static str, &'static str, f64, Colormap) {
        match self {
            Self::VonMises => ("von Mises stress", "kPa", 1e-3, Colormap::Viridis),
            Self::Displacement => ("displacement", "mm", 1e3, Colormap::Cividis),
            Self::DetF => ("det F", "-", 1.0, Colormap::Coolwarm),
        }
    }
}

impl FromStr for FieldKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "von-mises" => Ok(Self::VonMises),
            "displacement" => Ok(Self::Displacement),
            "det-f" => Ok(Self::DetF),
            other => Err(format!(
                "unknown field \"{other}\" (expected von-mises, displacement or det-f)"
            )),
        }
    }
}

/// One frame of a run, ready to be viewed by [`MeshView`]: positions, rest shape and
/// obstacles are borrowed from the run; only what is derived (the triangles as `usize`, a
/// displacement field, an added ground) is owned.
pub struct FramePicture<'a> {
    positions: &'a [[f64; 2]],
    rest: &'a [[f64; 2]],
    triangles: Vec<[usize; 3]>,
    values: Cow<'a, [f64]>,
    per_vertex: bool,
    obstacles: Cow<'a, [Vec<[f64; 2]>]>,
    /// The frame's contact pressure per vertex, Pa (empty when the run kept none).
    snapshot_pressure: &'a [f64],
    /// Whether [`FramePicture::with_contact_pressure`] asked for the pressure line.
    show_pressure: bool,
    /// Whether the run had any contact pressure.
    run_has_pressure: bool,
    /// Triangles drawn flat instead of by the field ([`FramePicture::with_flat_elements`]):
    /// mask, colour and legend label.
    flat: Option<(Vec<bool>, [u8; 3], String)>,
    /// Edges drawn as thin dark lines ([`FramePicture::with_outline_edges`]).
    outline_edges: Vec<[usize; 2]>,
    /// Caption drawn above the panel.
    pub caption: String,
    /// Time of the frame, s.
    pub time: f64,
}

impl<'a> FramePicture<'a> {
    /// The picture of `snapshot` of `run`, coloured by `field`.
    pub fn new(
        run: &'a RunResult,
        snapshot: &'a Snapshot,
        field: FieldKind,
        caption: &str,
    ) -> Self {
        let (values, per_vertex) = match field {
            FieldKind::VonMises => (Cow::Borrowed(snapshot.von_mises.as_slice()), false),
            FieldKind::DetF => (Cow::Borrowed(snapshot.det_f.as_slice()), false),
            FieldKind::Displacement => (
                Cow::Owned(
                    snapshot
                        .positions
                        .iter()
                        .zip(&run.rest)
                        .map(|(x, x0)| (x[0] - x0[0]).hypot(x[1] - x0[1]))
                        .collect(),
                ),
                true,
            ),
        };
        Self {
            positions: &snapshot.positions,
            rest: &run.rest,
            triangles: run
                .triangles
                .iter()
                .map(|t| t.map(|i| i as usize))
                .collect(),
            values,
            per_vertex,
            obstacles: Cow::Borrowed(&snapshot.obstacles),
            snapshot_pressure: &snapshot.contact_pressure,
            show_pressure: false,
            run_has_pressure: run.summary.contact_peak_pressure > 0.0,
            flat: None,
            outline_edges: Vec::new(),
            caption: caption.to_owned(),
            time: snapshot.time,
        }
    }

    /// The picture with no field (the mesh in a flat colour), e.g. to show a scene's set-up.
    pub fn plain(mut self) -> Self {
        self.values = Cow::Borrowed(&[]);
        self.show_pressure = false;
        self
    }

    /// The picture with the frame's contact pressure drawn along the boundary when the run
    /// had contact (nothing changes for a run without): see [`overlay_pressure`].
    pub fn with_contact_pressure(mut self) -> Self {
        self.show_pressure = true;
        self
    }

    /// The contact pressure to draw, per vertex (Pa), if this picture shows it.
    pub fn contact_pressure(&self) -> Option<&[f64]> {
        (self.show_pressure
            && self.run_has_pressure
            && self.snapshot_pressure.len() == self.positions.len())
        .then_some(self.snapshot_pressure)
    }

    /// The picture with the triangles of `mask` (one entry per triangle) drawn in the flat
    /// `color` instead of by the field, and left out of its colour range ([`Self::range`],
    /// hence [`shared_range`]); a non-empty `label` gets a legend row under the colorbar. For
    /// bone inside soft tissue: the soft tissue's stress keeps the whole scale.
    pub fn with_flat_elements(mut self, mask: Vec<bool>, color: [u8; 3], label: &str) -> Self {
        self.flat = Some((mask, color, label.to_owned()));
        self
    }

    /// The picture with `edges` (vertex index pairs) drawn as thin dark lines over the fill,
    /// e.g. the bones' outlines (`fem_render::frame::region_edges`).
    pub fn with_outline_edges(mut self, edges: Vec<[usize; 2]>) -> Self {
        self.outline_edges = edges;
        self
    }

    /// The picture's triangles as vertex index triples.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// Adds a horizontal ground at height `y` (m), drawn as a thin strip under the body (the
    /// strip spans the body's width and a margin); `None` adds nothing.
    pub fn with_ground(mut self, y: Option<f64>) -> Self {
        let Some(y) = y else {
            return self;
        };
        let (lo, hi) = self.bounds();
        let w = (hi[0] - lo[0]).max(1e-9);
        let (x0, x1, t) = (lo[0] - 0.03 * w, hi[0] + 0.03 * w, 0.015 * w);
        self.obstacles
            .to_mut()
            .push(vec![[x0, y - t], [x1, y - t], [x1, y], [x0, y]]);
        self
    }

    /// The view `fem-render` draws.
    pub fn view(&self) -> MeshView<'_> {
        MeshView {
            positions: self.positions,
            triangles: &self.triangles,
            field: if self.values.is_empty() {
                None
            } else if self.per_vertex {
                Some(FieldValues::PerVertex(&self.values))
            } else {
                Some(FieldValues::PerElement(&self.values))
            },
            rest_positions: Some(self.rest),
            obstacles: &self.obstacles,
            caption: &self.caption,
            flat: self.flat.as_ref().map(|(mask, color, label)| FlatElements {
                mask,
                color: *color,
                label,
            }),
            outline_edges: &self.outline_edges,
        }
    }

    /// Lowest and highest corner over the current and rest positions and the obstacles.
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        let points = self
            .positions
            .iter()
            .chain(self.rest)
            .chain(self.obstacles.iter().flatten());
        for p in points.filter(|p| p[0].is_finite() && p[1].is_finite()) {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// The finite range of the field, in the field's own units, over the triangles drawn by
    /// it (flat ones do not count; a per-vertex value counts when a triangle drawn by the
    /// field uses its vertex).
    pub fn range(&self) -> Option<(f64, f64)> {
        let field = if self.per_vertex {
            FieldValues::PerVertex(&self.values)
        } else {
            FieldValues::PerElement(&self.values)
        };
        let mask = self.flat.as_ref().map(|(mask, _, _)| mask.as_slice());
        finite_range(shown_values(field, &self.triangles, mask))
    }
}

/// The legend range of the contact pressure over `pictures`, kPa: 0 to the largest pressure
/// any of them shows; `None` when none shows one or nothing is loaded.
pub fn pressure_range(pictures: &[&FramePicture<'_>]) -> Option<(f64, f64)> {
    let hi = pictures
        .iter()
        .filter_map(|p| p.contact_pressure())
        .flatten()
        .filter(|p| p.is_finite())
        .fold(0.0, |m: f64, &p| m.max(p * 1e-3));
    (hi > 0.0).then_some((0.0, hi))
}

/// Draws the contact pressure of each picture that shows one over its panel of `rendered`
/// (the panels in the order of `pictures`), in kPa on one legend range (`range`, or
/// [`pressure_range`] over them, so colours compare across panels and frames).
pub fn overlay_pressure(
    rendered: &mut Rendered,
    pictures: &[&FramePicture<'_>],
    range: Option<(f64, f64)>,
) -> Result<(), SceneError> {
    let Some(range) = range.or_else(|| pressure_range(pictures)) else {
        return Ok(());
    };
    for (p, panel) in pictures.iter().zip(&rendered.panels) {
        if let Some(pressure) = p.contact_pressure() {
            let mut o = PressureOverlay::new(p.positions, &p.triangles, pressure);
            o.range = Some(range);
            draw_pressure(&mut rendered.image, panel, &o)
                .map_err(|e| SceneError::Io(format!("contact pressure: {e}")))?;
        }
    }
    Ok(())
}

fn finite_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    (lo <= hi).then_some((lo, hi))
}

fn union(a: ([f64; 2], [f64; 2]), b: ([f64; 2], [f64; 2])) -> ([f64; 2], [f64; 2]) {
    (
        [a.0[0].min(b.0[0]), a.0[1].min(b.0[1])],
        [a.1[0].max(b.1[0]), a.1[1].max(b.1[1])],
    )
}

/// A frame style for `field` with `title`, panels of `width` x `height` pixels.
pub fn style(field: FieldKind, title: &str, width: u32, height: u32) -> FrameStyle {
    let (label, unit, scale, colormap) = field.style();
    FrameStyle {
        panel_width: width,
        panel_height: height,
        title: title.to_owned(),
        colormap,
        field_label: label.to_owned(),
        unit: unit.to_owned(),
        scale,
        ..FrameStyle::default()
    }
}

/// The displayed colour range covering every picture (in display units), with det F centred
/// on 1 so that the diverging colormap's middle means "no area change".
pub fn shared_range(pictures: &[&FramePicture<'_>], field: FieldKind) -> Option<(f64, f64)> {
    let (_, _, scale, _) = field.style();
    let (lo, hi) = pictures
        .iter()
        .filter_map(|p| p.range())
        .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))?;
    let (mut lo, mut hi) = (lo * scale, hi * scale);
    match field {
        FieldKind::DetF => {
            let r = (hi - 1.0).abs().max((1.0 - lo).abs()).max(1e-6);
            lo = 1.0 - r;
            hi = 1.0 + r;
        }
        _ => {
            // Stress and displacement maps start at zero, so colours compare across panels.
            lo = lo.min(0.0);
            if hi <= lo {
                hi = lo + 1.0;
            }
        }
    }
    Some((lo, hi))
}

/// Draws `pictures` side by side with one colorbar and a common world window.
pub fn render_side_by_side(
    pictures: &[&FramePicture<'_>],
    field: FieldKind,
    title: &str,
    panel: (u32, u32),
    range: Option<(f64, f64)>,
) -> Result<Rendered, SceneError> {
    let mut st = style(field, title, panel.0, panel.1);
    st.range = range.or_else(|| shared_range(pictures, field));
    st.bounds = pictures.iter().map(|p| p.bounds()).reduce(union);
    let views: Vec<MeshView<'_>> = pictures.iter().map(|p| p.view()).collect();
    let mut rendered =
        render(&views, &st).map_err(|e| SceneError::Io(format!("rendering \"{title}\": {e}")))?;
    overlay_pressure(&mut rendered, pictures, None)?;
    Ok(rendered)
}

/// Options of a run's animation.
#[derive(Clone, Debug)]
pub struct GifOptions {
    /// The field the frames are coloured by.
    pub field: FieldKind,
    /// Delay between frames, in hundredths of a second.
    pub delay_centiseconds: u16,
    /// Panel size in pixels.
    pub panel: (u32, u32),
    /// Title above every frame.
    pub title: String,
    /// Height of a horizontal ground to draw, m.
    pub ground: Option<f64>,
    /// Animate every `every`-th kept snapshot (and always the last one).
    pub every: usize,
    /// Draw the triangles' edges over the colours.
    pub wireframe: bool,
    /// Draw the contact pressure along the boundary when the run had contact (one legend
    /// range for the whole animation); default true.
    pub contact_pressure: bool,
}

impl Default for GifOptions {
    fn default() -> Self {
        Self {
            field: FieldKind::VonMises,
            delay_centiseconds: 5,
            panel: (560, 300),
            title: String::new(),
            ground: None,
            every: 1,
            wireframe: false,
            contact_pressure: true,
        }
    }
}

/// Writes the run's snapshots as an animated GIF at `path` (one colour range and one world
/// window for the whole animation, so colours and positions compare across frames).
pub fn write_gif(run: &RunResult, path: &Path, options: &GifOptions) -> Result<usize, SceneError> {
    if run.snapshots.is_empty() {
        return Err(SceneError::Usage(format!(
            "{}: the run kept no frames to animate",
            path.display()
        )));
    }
    let last = run.snapshots.len() - 1;
    let pictures: Vec<FramePicture<'_>> = run
        .snapshots
        .iter()
        .enumerate()
        .filter(|(k, _)| k % options.every.max(1) == 0 || *k == last)
        .map(|(_, s)| {
            let p = FramePicture::new(run, s, options.field, "").with_ground(options.ground);
            if options.contact_pressure {
                p.with_contact_pressure()
            } else {
                p
            }
        })
        .collect();
    let refs: Vec<&FramePicture<'_>> = pictures.iter().collect();
    let mut st = style(
        options.field,
        &options.title,
        options.panel.0,
        options.panel.1,
    );
    st.range = shared_range(&refs, options.field);
    st.bounds = pictures.iter().map(|p| p.bounds()).reduce(union);
    st.wireframe = options.wireframe;
    let pressure = pressure_range(&refs);
    let io = |e: fem_render::RenderError| SceneError::Io(format!("{}: {e}", path.display()));
    let mut writer = None;
    for p in &pictures {
        st.time_label = Some(time_label(run, p.time));
        let mut rendered = render(&[p.view()], &st).map_err(io)?;
        if pressure.is_some() {
            overlay_pressure(&mut rendered, &[p], pressure)?;
        }
        let frame = rendered.image;
        let w = match &mut writer {
            Some(w) => w,
            None => writer.insert(
                fem_render::gif::GifWriter::new(
                    Vec::new(),
                    frame.width(),
                    frame.height(),
                    options.delay_centiseconds,
                )
                .map_err(io)?,
            ),
        };
        w.push(&frame).map_err(io)?;
    }
    let w = writer.expect("at least one frame");
    let frames = w.frames();
    let bytes = w.finish().map_err(io)?;
    crate::run::write_atomic(path, &bytes)?;
    Ok(frames)
}

/// "t = 0.120 s", or "load 0.40" for a load-stepping run (whose frames are load increments).
pub fn time_label(run: &RunResult, time: f64) -> String {
    if run.summary.solver.capabilities().clock == fem_solvers::Clock::LoadFactor {
        format!("load {time:.2}")
    } else {
        format!("t = {time:.3} s")
    }
}

/// The snapshot of `run` closest in time to `time`.
pub fn snapshot_at(run: &RunResult, time: f64) -> Option<&Snapshot> {
    run.snapshots
        .iter()
        .min_by(|a, b| (a.time - time).abs().total_cmp(&(b.time - time).abs()))
}

/// A chart of each run's probe `probe` (its vertical displacement, mm) against time (s).
pub fn probe_chart(runs: &[(&str, &RunResult)], probe: &str, title: &str) -> LineChart {
    let series = runs
        .iter()
        .filter_map(|(label, run)| {
            let values = run.probe(probe)?;
            Some(Series {
                label: (*label).to_owned(),
                points: run
                    .frame_times
                    .iter()
                    .zip(values)
                    .map(|(f, u)| (f.1, u[1] * 1e3))
                    .collect(),
            })
        })
        .collect();
    LineChart {
        title: title.to_owned(),
        x_label: "time [s]".into(),
        y_label: format!("{probe} vertical displacement [mm]"),
        x_scale: Scale::Linear,
        y_scale: Scale::Linear,
        series,
        ..LineChart::default()
    }
}

/// Writes `chart` as `<stem>.svg` and `<stem>.png` in `dir`.
pub fn write_chart(
    dir: &Path,
    stem: &str,
    svg: Result<String, fem_render::RenderError>,
    png: Result<Image, fem_render::RenderError>,
) -> Result<(), SceneError> {
    let io = |e: fem_render::RenderError| SceneError::Io(format!("{}/{stem}: {e}", dir.display()));
    crate::run::write_atomic(
        &dir.join(format!("{stem}.svg")),
        svg.map_err(io)?.as_bytes(),
    )?;
    png.map_err(io)?
        .write_png(&dir.join(format!("{stem}.png")))
        .map_err(io)
}
