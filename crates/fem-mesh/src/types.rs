//! Plain geometric containers shared by the pipeline stages: a 3D triangle surface, a 2D point
//! set, polygons with holes and the 2D triangle mesh. They are deliberately simple (`Vec`s of
//! arrays) so that other crates can convert them without depending on any geometry library.

use serde::{Deserialize, Serialize};

/// A 3D triangle surface as loaded from a model file (model units, as in the file).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Surface3 {
    /// Vertex positions.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as 0-based vertex indices (winding as in the file).
    pub triangles: Vec<[usize; 3]>,
}

impl Surface3 {
    /// Multiplies every coordinate by `factor` (for example 0.1 for decimetres to metres).
    pub fn scale(&mut self, factor: f64) {
        for v in &mut self.vertices {
            for c in v.iter_mut() {
                *c *= factor;
            }
        }
    }

    /// Axis-aligned bounding box `(min, max)`, or `None` when there is no vertex.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let first = *self.vertices.first()?;
        let mut lo = first;
        let mut hi = first;
        for v in &self.vertices {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        Some((lo, hi))
    }
}

/// A simple polygon with holes. The outer ring is counter-clockwise, holes are clockwise; rings
/// are open (the first vertex is not repeated at the end).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PolygonWithHoles {
    /// The outer boundary, counter-clockwise.
    pub outer: Vec<[f64; 2]>,
    /// The holes, each clockwise.
    pub holes: Vec<Vec<[f64; 2]>>,
}

impl PolygonWithHoles {
    /// Enclosed area: outer area minus the hole areas (model units squared).
    pub fn area(&self) -> f64 {
        ring_signed_area(&self.outer).abs()
            - self
                .holes
                .iter()
                .map(|h| ring_signed_area(h).abs())
                .sum::<f64>()
    }

    /// Total vertex count over all rings.
    pub fn vertex_count(&self) -> usize {
        self.outer.len() + self.holes.iter().map(Vec::len).sum::<usize>()
    }

    /// Whether `p` lies inside the outer ring and outside every hole.
    pub fn contains(&self, p: [f64; 2]) -> bool {
        point_in_ring(p, &self.outer) && !self.holes.iter().any(|h| point_in_ring(p, h))
    }

    /// Every ring, outer first.
    pub fn rings(&self) -> impl Iterator<Item = &Vec<[f64; 2]>> {
        std::iter::once(&self.outer).chain(self.holes.iter())
    }
}

/// A named material region inside the meshed domain (a bone inside soft tissue): one or more
/// disjoint polygons, meshed by [`crate::triangulate::triangulate_regions`] with their edges as
/// constraints, so every triangle lies in exactly one region.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InnerRegion {
    /// The region's name (the mesh's `region_names` entry).
    pub name: String,
    /// Its polygons (outer rings counter-clockwise, holes clockwise), mutually disjoint.
    pub polygons: Vec<PolygonWithHoles>,
}

impl InnerRegion {
    /// Enclosed area of all the region's polygons (model units squared).
    pub fn area(&self) -> f64 {
        self.polygons.iter().map(PolygonWithHoles::area).sum()
    }

    /// Whether `p` lies in one of the region's polygons.
    pub fn contains(&self, p: [f64; 2]) -> bool {
        self.polygons.iter().any(|q| q.contains(p))
    }
}

/// A bone of a [`Skeleton`]: a name and its closed convex 3D parts (a femur's shaft and head,
/// or the left and right humerus under one name).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Bone {
    /// The bone's name, which becomes its region name in the mesh.
    pub name: String,
    /// Closed convex surfaces, in the same model units and frame as the skin.
    pub parts: Vec<Surface3>,
}

/// The bones inside a body surface, meshed as inner regions by
/// [`crate::pipeline::mesh_surface_with_skeleton`]. Each part must be convex (its outline in a
/// view is the convex hull of its projected vertices).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Skeleton {
    /// The bones; bone `k` becomes region `k + 1` (region 0 is the soft tissue).
    pub bones: Vec<Bone>,
}

/// Signed area of an open ring (shoelace formula): positive when counter-clockwise.
pub fn ring_signed_area(ring: &[[f64; 2]]) -> f64 {
    let n = ring.len();
    let mut twice = 0.0;
    for i in 0..n {
        let a = ring[i];
        let b = ring[(i + 1) % n];
        twice += a[0] * b[1] - b[0] * a[1];
    }
    0.5 * twice
}

/// Whether `p` lies inside the open ring (even-odd rule; points on the boundary are unspecified).
pub fn point_in_ring(p: [f64; 2], ring: &[[f64; 2]]) -> bool {
    let n = ring.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (a, b) = (ring[i], ring[j]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x {
                inside = !inside;
            }
        }
        j = i;
    }
    inside
}

/// A 2D triangle mesh: the interchange type of the crate (see the mesh JSON contract in
/// [`crate::io`]). Triangles are counter-clockwise, indices 0-based.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Mesh2 {
    /// Vertex positions (model units, metres once scaled).
    pub vertices: Vec<[f64; 2]>,
    /// Triangles as 0-based vertex indices, counter-clockwise.
    pub triangles: Vec<[usize; 3]>,
    /// Material region tag of each triangle (JSON key `"regions"`), or empty when the mesh is
    /// untagged (every triangle is then region 0). When present, one tag per triangle.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub regions: Vec<u32>,
    /// Name of each region tag: `region_names[k]` names tag `k` (JSON key `"region_names"`);
    /// empty when the regions are unnamed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub region_names: Vec<String>,
}

impl Mesh2 {
    /// The three corner positions of triangle `t`.
    pub fn corners(&self, t: usize) -> [[f64; 2]; 3] {
        let [a, b, c] = self.triangles[t];
        [self.vertices[a], self.vertices[b], self.vertices[c]]
    }

    /// Signed area of triangle `t` (positive when counter-clockwise).
    pub fn signed_area(&self, t: usize) -> f64 {
        triangle_signed_area(self.corners(t))
    }

    /// Sum of the triangle areas.
    pub fn area(&self) -> f64 {
        (0..self.triangles.len()).map(|t| self.signed_area(t)).sum()
    }

    /// Region tag of triangle `t` (0 when the mesh is untagged).
    pub fn region_of(&self, t: usize) -> u32 {
        self.regions.get(t).copied().unwrap_or(0)
    }

    /// Number of regions: the names' count, or one more than the largest tag (1 when untagged).
    pub fn region_count(&self) -> usize {
        let tags = self.regions.iter().max().map_or(1, |&k| k as usize + 1);
        tags.max(self.region_names.len())
    }

    /// The tag named `name`, if any.
    pub fn region_index(&self, name: &str) -> Option<u32> {
        self.region_names
            .iter()
            .position(|n| n == name)
            .map(|k| k as u32)
    }

    /// Sum of the areas of the triangles tagged `k` (model units squared).
    pub fn region_area(&self, k: u32) -> f64 {
        (0..self.triangles.len())
            .filter(|&t| self.region_of(t) == k)
            .map(|t| self.signed_area(t))
            .sum()
    }

    /// Number of edge-connected components of the triangles tagged `k` (0 when none is).
    pub fn region_components(&self, k: u32) -> usize {
        let picked: Vec<usize> = (0..self.triangles.len())
            .filter(|&t| self.region_of(t) == k)
            .collect();
        let sub = Mesh2 {
            vertices: Vec::new(),
            triangles: picked.iter().map(|&t| self.triangles[t]).collect(),
            ..Mesh2::default()
        };
        sub.edge_components()
    }

    /// Number of edge-connected components of the triangles (triangles that only share a vertex
    /// count as separate components).
    pub fn edge_components(&self) -> usize {
        let mut dsu = Dsu::new(self.triangles.len());
        let mut edge_owner = std::collections::HashMap::with_capacity(self.triangles.len() * 2);
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                if let Some(&other) = edge_owner.get(&key) {
                    dsu.union(t, other);
                } else {
                    edge_owner.insert(key, t);
                }
            }
        }
        dsu.count_roots()
    }

    /// Whether point `p` lies in some triangle of the mesh (closed triangles).
    pub fn contains_point(&self, p: [f64; 2]) -> bool {
        (0..self.triangles.len()).any(|t| {
            let [a, b, c] = self.corners(t);
            let d1 = orient(a, b, p);
            let d2 = orient(b, c, p);
            let d3 = orient(c, a, p);
            d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0
        })
    }
}

/// Signed area of a triangle (positive when counter-clockwise).
pub fn triangle_signed_area([a, b, c]: [[f64; 2]; 3]) -> f64 {
    0.5 * orient(a, b, c)
}

/// Twice the signed area of `(a, b, c)`: positive when `c` is left of `a -> b`.
pub fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Disjoint-set union with path halving, used for connected components.
#[derive(Debug, Clone)]
pub(crate) struct Dsu {
    parent: Vec<usize>,
}

impl Dsu {
    pub(crate) fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
        }
    }

    pub(crate) fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }

    /// Joins the sets of `a` and `b`; returns whether they were separate.
    pub(crate) fn union(&mut self, a: usize, b: usize) -> bool {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra == rb {
            return false;
        }
        // Smaller index becomes the root, which keeps results deterministic.
        let (lo, hi) = (ra.min(rb), ra.max(rb));
        self.parent[hi] = lo;
        true
    }

    pub(crate) fn count_roots(&mut self) -> usize {
        (0..self.parent.len())
            .filter(|&i| self.find(i) == i)
            .count()
    }
}
