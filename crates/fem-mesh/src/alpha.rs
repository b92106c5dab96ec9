//! Alpha shape of a 2D point set: the union of the Delaunay triangles whose circumradius is
//! below a radius `r`, and its boundary as polygons with holes.
//!
//! **Alpha convention.** The parameter is a *radius in model units* (metres once scaled): a
//! Delaunay triangle is kept when its circumradius is strictly below [`AlphaParams::radius`].
//! Some libraries (Python's `alphashape`) use α = 1/r instead. Larger radii fill more (r → ∞
//! gives the convex hull); too small a radius leaves nothing.
//!
//! **Semi-automatic radius.** Without a radius, [`suggest_radius`] proposes the smallest radius
//! at which the kept triangles form a single edge-connected component that touches every point,
//! times [`AlphaParams::auto_margin`]. It is found in one pass (triangles sorted by circumradius,
//! joined with a union-find), not by trial and error.
//!
//! **Small holes.** Enclosed holes made only of triangles with a circumradius below
//! [`AlphaParams::fill_holes_below`] times the radius are filled: on unevenly sampled surfaces
//! they are gaps between rows of vertices, not holes of the shape (counted in
//! [`AlphaShape::holes_filled`]).
//!
//! **Boundary.** Kept triangles that meet another part of the shape only at a vertex (a "pinch")
//! would make a self-touching boundary, which neither a polygon nor a mesher accepts. At each
//! such vertex the largest fan of triangles is kept and the smaller fans are dropped (counted in
//! [`AlphaShape::pinch_triangles_removed`]). The boundary is then a set of simple, vertex-disjoint
//! loops: one counter-clockwise outer loop per component and clockwise holes.

use spade::{DelaunayTriangulation, Point2, Triangulation};

use crate::error::{MeshError, Result};
use crate::types::{Dsu, PolygonWithHoles, orient};

/// Which connected components of the alpha shape to keep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Components {
    /// Keep only the component with the largest area. Default.
    #[default]
    Largest,
    /// Keep every component (largest first).
    All,
}

/// Parameters of [`alpha_shape`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlphaParams {
    /// Keep Delaunay triangles whose circumradius is below this radius (model units). `None`
    /// (default) uses the suggestion of [`suggest_radius`].
    pub radius: Option<f64>,
    /// Factor applied to the smallest single-component radius when suggesting one (dimensionless,
    /// at least 1). Default 1.1: a little slack so that the sparsest region is not held by a single
    /// triangle.
    pub auto_margin: f64,
    /// Which components to keep. Default [`Components::Largest`].
    pub components: Components,
    /// Fill every hole whose Delaunay triangles all have a circumradius below this multiple of
    /// the radius (dimensionless). Such holes are gaps in unevenly sampled surfaces (rows of
    /// vertices slightly farther apart than the radius), not features of the shape; real holes
    /// hold triangles far larger than the radius. Default 2; 1 disables filling.
    pub fill_holes_below: f64,
}

impl Default for AlphaParams {
    fn default() -> Self {
        Self {
            radius: None,
            auto_margin: 1.1,
            components: Components::Largest,
            fill_holes_below: 2.0,
        }
    }
}

/// Result of [`alpha_shape`].
#[derive(Debug, Clone, PartialEq)]
pub struct AlphaShape {
    /// The kept components as polygons with holes, largest area first.
    pub polygons: Vec<PolygonWithHoles>,
    /// The radius used (model units).
    pub radius: f64,
    /// Whether the radius was suggested (no radius given).
    pub radius_was_suggested: bool,
    /// The suggestion of [`suggest_radius`] (always computed, so it can be printed).
    pub suggestion: RadiusSuggestion,
    /// Number of components before [`AlphaParams::components`] was applied.
    pub component_count: usize,
    /// Area of all components before selection (model units squared).
    pub total_area: f64,
    /// Triangles dropped to remove pinch vertices.
    pub pinch_triangles_removed: usize,
    /// Holes filled by the [`AlphaParams::fill_holes_below`] rule.
    pub holes_filled: usize,
    /// The kept triangles (indices into [`AlphaShape::points`]), for previews and diagnostics.
    pub triangles: Vec<[usize; 3]>,
    /// The distinct input points in Delaunay order.
    pub points: Vec<[f64; 2]>,
}

/// A proposed alpha radius and the numbers behind it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadiusSuggestion {
    /// Suggested radius: `single_component_radius * auto_margin` (model units).
    pub radius: f64,
    /// Smallest radius at which the kept triangles form one component touching every point.
    pub single_component_radius: f64,
    /// Median over points of the distance to the nearest Delaunay neighbour (model units).
    pub median_spacing: f64,
}

/// Delaunay triangulation of the points in plain index form.
struct Delaunay {
    points: Vec<[f64; 2]>,
    triangles: Vec<[usize; 3]>,
    /// `neighbours[t][k]`: the triangle across edge `k` (from corner `k` to corner `k + 1`).
    neighbours: Vec<[Option<usize>; 3]>,
    circumradius: Vec<f64>,
}

fn delaunay(points: &[[f64; 2]]) -> Result<Delaunay> {
    crate::guard::guarded("alpha shape", || delaunay_unguarded(points))?
}

fn delaunay_unguarded(points: &[[f64; 2]]) -> Result<Delaunay> {
    if let Some((i, p)) = points
        .iter()
        .enumerate()
        .find(|(_, p)| !(p[0].is_finite() && p[1].is_finite()))
    {
        return Err(MeshError::invalid(
            "alpha shape",
            format!("point {i} is not finite: {p:?}"),
        ));
    }
    let vertices: Vec<Point2<f64>> = points.iter().map(|p| Point2::new(p[0], p[1])).collect();
    let dt: DelaunayTriangulation<Point2<f64>> = DelaunayTriangulation::bulk_load(vertices)
        .map_err(|e| MeshError::invalid("alpha shape", format!("Delaunay triangulation: {e}")))?;
    let n = dt.num_vertices();
    if dt.num_inner_faces() == 0 {
        let what = if n <= 1 {
            format!("all {} points coincide", points.len())
        } else {
            format!("all {} points ({n} distinct) are collinear", points.len())
        };
        return Err(MeshError::invalid(
            "alpha shape",
            format!("{what}: there is no area to mesh"),
        ));
    }
    let points: Vec<[f64; 2]> = dt
        .vertices()
        .map(|v| {
            let p = v.position();
            [p.x, p.y]
        })
        .collect();
    // Inner face indices start at 1 (0 is the outer face).
    let nf = dt.num_inner_faces();
    let mut triangles = Vec::with_capacity(nf);
    let mut neighbours = Vec::with_capacity(nf);
    let mut circumradius = Vec::with_capacity(nf);
    for face in dt.inner_faces() {
        debug_assert_eq!(face.fix().index(), triangles.len() + 1);
        let vs = face.vertices().map(|v| v.fix().index());
        triangles.push(vs);
        let edges = face.adjacent_edges();
        let mut nb = [None; 3];
        for (k, e) in edges.iter().enumerate() {
            debug_assert_eq!(e.from().fix().index(), vs[k]);
            nb[k] = e.rev().face().as_inner().map(|f| f.fix().index() - 1);
        }
        neighbours.push(nb);
        circumradius.push(circumradius_of(vs.map(|i| points[i])));
    }
    Ok(Delaunay {
        points,
        triangles,
        neighbours,
        circumradius,
    })
}

/// Circumradius `abc / (4 * area)` of a triangle; infinite for a degenerate one.
pub fn circumradius_of([a, b, c]: [[f64; 2]; 3]) -> f64 {
    let len = |p: [f64; 2], q: [f64; 2]| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
    let twice_area = orient(a, b, c).abs();
    if twice_area == 0.0 {
        return f64::INFINITY;
    }
    len(a, b) * len(b, c) * len(c, a) / (2.0 * twice_area)
}

/// Proposes an alpha radius for `points` (see the module docs).
pub fn suggest_radius(points: &[[f64; 2]], auto_margin: f64) -> Result<RadiusSuggestion> {
    Ok(suggest(&delaunay(points)?, auto_margin))
}

fn suggest(dt: &Delaunay, auto_margin: f64) -> RadiusSuggestion {
    let nt = dt.triangles.len();
    let mut order: Vec<usize> = (0..nt).collect();
    order.sort_unstable_by(|&a, &b| dt.circumradius[a].total_cmp(&dt.circumradius[b]));
    let mut added = vec![false; nt];
    let mut covered = vec![false; dt.points.len()];
    let mut n_covered = 0;
    let mut components = 0usize;
    let mut dsu = Dsu::new(nt);
    let mut single = dt.circumradius[order[nt - 1]];
    for &t in &order {
        added[t] = true;
        components += 1;
        for nb in dt.neighbours[t].iter().flatten() {
            if added[*nb] && dsu.union(t, *nb) {
                components -= 1;
            }
        }
        for &v in &dt.triangles[t] {
            if !covered[v] {
                covered[v] = true;
                n_covered += 1;
            }
        }
        if components == 1 && n_covered == dt.points.len() {
            single = dt.circumradius[t];
            break;
        }
    }
    let mut nearest = vec![f64::INFINITY; dt.points.len()];
    for tri in &dt.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let (p, q) = (dt.points[a], dt.points[b]);
            let d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
            nearest[a] = nearest[a].min(d);
            nearest[b] = nearest[b].min(d);
        }
    }
    let mid = nearest.len() / 2;
    let median_spacing = *nearest.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
    RadiusSuggestion {
        // Keeping triangles *below* the radius: scale up by at least a hair so the triangle that
        // joined the last component is kept.
        radius: single * auto_margin.max(1.0 + 1e-9),
        single_component_radius: single,
        median_spacing,
    }
}

/// Computes the alpha shape of `points` (which should be free of duplicates; exact duplicates are
/// tolerated).
pub fn alpha_shape(points: &[[f64; 2]], params: &AlphaParams) -> Result<AlphaShape> {
    if points.len() < 3 {
        return Err(MeshError::invalid(
            "alpha shape",
            format!("{} points given, at least 3 are needed", points.len()),
        ));
    }
    if !(params.fill_holes_below.is_finite() && params.fill_holes_below >= 1.0) {
        return Err(MeshError::invalid(
            "alpha shape",
            format!(
                "hole-fill factor must be >= 1, got {}",
                params.fill_holes_below
            ),
        ));
    }
    if !(params.auto_margin.is_finite() && params.auto_margin >= 1.0) {
        return Err(MeshError::invalid(
            "alpha shape",
            format!("auto margin must be >= 1, got {}", params.auto_margin),
        ));
    }
    let dt = delaunay(points)?;
    let suggestion = suggest(&dt, params.auto_margin);
    let radius = match params.radius {
        Some(r) if !(r.is_finite() && r > 0.0) => {
            return Err(MeshError::invalid(
                "alpha shape",
                format!("radius must be positive and finite, got {r}"),
            ));
        }
        Some(r) => r,
        None => suggestion.radius,
    };
    let mut kept: Vec<bool> = dt.circumradius.iter().map(|&r| r < radius).collect();
    if !kept.iter().any(|&k| k) {
        let smallest = dt
            .circumradius
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        return Err(MeshError::invalid(
            "alpha shape",
            format!(
                "radius {radius} keeps no triangle (empty shape; the smallest circumradius is {smallest:.4e}, the suggested radius {:.4e})",
                suggestion.radius
            ),
        ));
    }
    let holes_filled = fill_small_holes(&dt, &mut kept, params.fill_holes_below * radius);
    let pinch_triangles_removed = remove_pinches(&dt, &mut kept);

    // Components over kept triangles joined by an edge.
    let nt = dt.triangles.len();
    let mut dsu = Dsu::new(nt);
    for t in 0..nt {
        if kept[t] {
            for nb in dt.neighbours[t].iter().flatten() {
                if kept[*nb] {
                    dsu.union(t, *nb);
                }
            }
        }
    }
    let mut component_of = vec![usize::MAX; nt];
    let mut comp_area: Vec<f64> = Vec::new();
    let mut root_to_comp = vec![usize::MAX; nt];
    for t in 0..nt {
        if kept[t] {
            let r = dsu.find(t);
            if root_to_comp[r] == usize::MAX {
                root_to_comp[r] = comp_area.len();
                comp_area.push(0.0);
            }
            let c = root_to_comp[r];
            component_of[t] = c;
            comp_area[c] += 0.5 * orient_tri(&dt, t);
        }
    }
    let loops = trace_loops(&dt, &kept);
    let mut polygons: Vec<PolygonWithHoles> = vec![PolygonWithHoles::default(); comp_area.len()];
    for (t, ring) in loops {
        let c = component_of[t];
        if crate::types::ring_signed_area(&ring) > 0.0 {
            debug_assert!(polygons[c].outer.is_empty(), "one outer loop per component");
            polygons[c].outer = ring;
        } else {
            polygons[c].holes.push(ring);
        }
    }
    let mut order: Vec<usize> = (0..comp_area.len()).collect();
    order.sort_by(|&a, &b| comp_area[b].total_cmp(&comp_area[a]));
    let component_count = order.len();
    let total_area = comp_area.iter().sum();
    if params.components == Components::Largest {
        order.truncate(1);
    }
    let keep_comp: Vec<bool> = {
        let mut v = vec![false; comp_area.len()];
        for &c in &order {
            v[c] = true;
        }
        v
    };
    let triangles = (0..nt)
        .filter(|&t| kept[t] && keep_comp[component_of[t]])
        .map(|t| dt.triangles[t])
        .collect();
    let polygons = order
        .iter()
        .map(|&c| std::mem::take(&mut polygons[c]))
        .collect();
    Ok(AlphaShape {
        polygons,
        radius,
        radius_was_suggested: params.radius.is_none(),
        suggestion,
        component_count,
        total_area,
        pinch_triangles_removed,
        holes_filled,
        triangles,
        points: dt.points,
    })
}

fn orient_tri(dt: &Delaunay, t: usize) -> f64 {
    let [a, b, c] = dt.triangles[t].map(|i| dt.points[i]);
    orient(a, b, c)
}

fn is_boundary(dt: &Delaunay, kept: &[bool], t: usize, k: usize) -> bool {
    kept[t] && !dt.neighbours[t][k].is_some_and(|n| kept[n])
}

/// Corner index of vertex `v` in triangle `t`.
fn corner(dt: &Delaunay, t: usize, v: usize) -> usize {
    dt.triangles[t].iter().position(|&x| x == v).unwrap_or(0)
}

/// Marks as kept every region of dropped triangles that is enclosed by kept ones (touches
/// neither the convex hull nor the outside) and whose circumradii are all below `limit`; returns
/// the number of such regions.
fn fill_small_holes(dt: &Delaunay, kept: &mut [bool], limit: f64) -> usize {
    let nt = dt.triangles.len();
    let mut seen = vec![false; nt];
    let mut region = Vec::new();
    let mut stack = Vec::new();
    let mut filled = 0;
    for start in 0..nt {
        if kept[start] || seen[start] {
            continue;
        }
        region.clear();
        stack.push(start);
        seen[start] = true;
        let mut enclosed = true;
        let mut small = true;
        while let Some(t) = stack.pop() {
            region.push(t);
            small &= dt.circumradius[t] < limit;
            for nb in dt.neighbours[t] {
                match nb {
                    None => enclosed = false,
                    Some(n) if !kept[n] && !seen[n] => {
                        seen[n] = true;
                        stack.push(n);
                    }
                    Some(_) => {}
                }
            }
        }
        if enclosed && small {
            for &t in &region {
                kept[t] = true;
            }
            filled += 1;
        }
    }
    filled
}

/// Drops the smaller fans at every pinch vertex until none is left; returns the number of dropped
/// triangles.
fn remove_pinches(dt: &Delaunay, kept: &mut [bool]) -> usize {
    let nv = dt.points.len();
    let mut removed = 0;
    loop {
        // Outgoing boundary half-edges per vertex: (triangle, edge).
        let mut outgoing: Vec<Vec<(usize, usize)>> = vec![Vec::new(); nv];
        let mut any = false;
        for t in 0..dt.triangles.len() {
            for k in 0..3 {
                if is_boundary(dt, kept, t, k) {
                    let v = dt.triangles[t][k];
                    outgoing[v].push((t, k));
                    any |= outgoing[v].len() > 1;
                }
            }
        }
        if !any {
            return removed;
        }
        for (v, out) in outgoing.iter().enumerate() {
            if out.len() < 2 {
                continue;
            }
            // Fan of each outgoing boundary edge: rotate counter-clockwise around v.
            let fans: Vec<Vec<usize>> = out
                .iter()
                .map(|&(t0, _)| {
                    let mut fan = vec![t0];
                    let mut t = t0;
                    loop {
                        let c = corner(dt, t, v);
                        // Edge ending at v is (c + 2) % 3.
                        match dt.neighbours[t][(c + 2) % 3] {
                            Some(n) if kept[n] && n != t0 => {
                                fan.push(n);
                                t = n;
                            }
                            _ => break,
                        }
                    }
                    fan
                })
                .collect();
            if fans.iter().flatten().any(|&t| !kept[t]) {
                // A fan changed during this pass; re-scan.
                continue;
            }
            let area = |fan: &Vec<usize>| fan.iter().map(|&t| orient_tri(dt, t)).sum::<f64>();
            let best = (0..fans.len())
                .max_by(|&a, &b| area(&fans[a]).total_cmp(&area(&fans[b])))
                .unwrap_or(0);
            for (i, fan) in fans.iter().enumerate() {
                if i != best {
                    for &t in fan {
                        kept[t] = false;
                        removed += 1;
                    }
                }
            }
        }
    }
}

/// Traces every boundary loop (kept triangle on the left); returns `(a triangle of the loop, ring)`.
fn trace_loops(dt: &Delaunay, kept: &[bool]) -> Vec<(usize, Vec<[f64; 2]>)> {
    let nt = dt.triangles.len();
    let mut visited = vec![[false; 3]; nt];
    let mut loops = Vec::new();
    for t0 in 0..nt {
        for k0 in 0..3 {
            if visited[t0][k0] || !is_boundary(dt, kept, t0, k0) {
                continue;
            }
            let mut ring = Vec::new();
            let (mut t, mut k) = (t0, k0);
            loop {
                visited[t][k] = true;
                ring.push(dt.points[dt.triangles[t][k]]);
                // Next boundary edge starts at b = end of (t, k): rotate clockwise around b.
                let b = dt.triangles[t][(k + 1) % 3];
                let mut ct = t;
                let mut ck = (k + 1) % 3;
                let mut guard = 0;
                while !is_boundary(dt, kept, ct, ck) {
                    let n = dt.neighbours[ct][ck].unwrap_or(ct);
                    ct = n;
                    ck = corner(dt, ct, b);
                    guard += 1;
                    if guard > nt {
                        break;
                    }
                }
                t = ct;
                k = ck;
                if t == t0 && k == k0 || visited[t][k] {
                    break;
                }
            }
            loops.push((t0, ring));
        }
    }
    loops
}
