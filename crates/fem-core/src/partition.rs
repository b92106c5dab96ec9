//! The deterministic parallel scatter plan: how triangles are split into fixed chunks and which
//! vertices each chunk may write directly.
//!
//! Triangles are cut into contiguous chunks of [`ELEMENT_CHUNK`] (a constant, so the split never
//! depends on the thread count). A vertex all of whose triangles lie in one chunk is *owned* by
//! that chunk, which adds the contributions straight into the output, in triangle order: exactly
//! the serial scatter's order. The owned vertices of chunk `k` must form a contiguous index
//! range `[start[k], start[k + 1])` so the output can be split into disjoint mutable slices
//! (safe Rust, no atomics); owned vertices that fall outside their chunk's range are demoted to
//! *shared*. A shared vertex (touched by several chunks, or demoted) receives its contributions
//! through a slot buffer and is summed afterwards, slot by slot in triangle order from zero.
//! Either way every vertex sums the same terms in the same order as the serial loop, so the
//! result is bit-identical to it.
//!
//! On a mesh numbered along a sweep (structured meshes, meshes sorted along an axis) almost
//! every vertex is owned; on a randomly numbered mesh most are shared and the plan degrades to a
//! gather, still correct and deterministic.

use std::ops::Add;

use crate::par::prelude::*;

use crate::mesh::VertexAdjacency;

/// Triangles per parallel chunk.
pub const ELEMENT_CHUNK: usize = 2048;

/// Marks a corner whose contribution goes to the slot buffer; the low bits are the slot.
const SHARED_BIT: u32 = 1 << 31;

/// Where each triangle corner's contribution goes in the parallel scatter.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScatterPlan {
    /// `start[k]..start[k + 1]`: the vertex range chunk `k` owns (length `n_chunks + 1`; the
    /// last entry is `n_vertices`, and vertices past the last chunk's owned ones are shared).
    own_start: Vec<u32>,
    /// Per triangle corner: the owned vertex's offset within its chunk's range, or
    /// `SHARED_BIT | slot`.
    targets: Vec<[u32; 3]>,
    /// `slot_start[k]..slot_start[k + 1]`: the slots chunk `k` writes.
    slot_start: Vec<u32>,
    /// Shared vertices, increasing.
    shared: Vec<u32>,
    /// `shared_offsets[i]..shared_offsets[i + 1]` indexes `shared_slots` for `shared[i]`.
    shared_offsets: Vec<u32>,
    /// Slots of each shared vertex, increasing (= triangle order).
    shared_slots: Vec<u32>,
}

/// Where one corner's contribution goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// Add into the chunk's owned slice at this offset.
    Owned(usize),
    /// Store into this slot.
    Shared(usize),
}

impl ScatterPlan {
    /// Build the plan for `triangles` over `n_vertices` vertices.
    pub fn new(n_vertices: usize, triangles: &[[u32; 3]], adjacency: &VertexAdjacency) -> Self {
        let n_chunks = triangles.len().div_ceil(ELEMENT_CHUNK);
        const NONE: u32 = u32::MAX;
        // Owner chunk of each vertex, or NONE when its triangles span several chunks.
        let mut owner: Vec<u32> = (0..n_vertices)
            .map(|v| {
                let adj = adjacency.of(v);
                let first = adj.first().map_or(0, |&(e, _)| e as usize / ELEMENT_CHUNK);
                let last = adj.last().map_or(0, |&(e, _)| e as usize / ELEMENT_CHUNK);
                if first == last { first as u32 } else { NONE }
            })
            .collect();
        // Owned ranges: chunk k starts at its first owned vertex, kept monotone.
        let mut own_start = vec![n_vertices as u32; n_chunks + 1];
        for (v, &o) in owner.iter().enumerate().rev() {
            if o != NONE {
                own_start[o as usize] = v as u32;
            }
        }
        for k in (0..n_chunks).rev() {
            own_start[k] = own_start[k].min(own_start[k + 1]);
        }
        // Enforce monotone starts going forward, then demote owned vertices outside their range.
        for k in 1..=n_chunks {
            own_start[k] = own_start[k].max(own_start[k - 1]);
        }
        for (v, o) in owner.iter_mut().enumerate() {
            if *o != NONE {
                let k = *o as usize;
                if !(own_start[k] as usize <= v && v < own_start[k + 1] as usize) {
                    *o = NONE;
                }
            }
        }
        // Slots, assigned in triangle order (so each chunk's slots are contiguous).
        let mut targets = Vec::with_capacity(triangles.len());
        let mut slot_start = Vec::with_capacity(n_chunks + 1);
        let mut slot_vertex: Vec<u32> = Vec::new();
        for (e, tri) in triangles.iter().enumerate() {
            let k = e / ELEMENT_CHUNK;
            if e % ELEMENT_CHUNK == 0 {
                slot_start.push(slot_vertex.len() as u32);
            }
            targets.push(tri.map(|v| {
                if owner[v as usize] == k as u32 {
                    v - own_start[k]
                } else {
                    slot_vertex.push(v);
                    SHARED_BIT | (slot_vertex.len() as u32 - 1)
                }
            }));
        }
        slot_start.push(slot_vertex.len() as u32);
        // Shared vertices and their slots (CSR), slots increasing.
        let mut counts = vec![0u32; n_vertices + 1];
        for &v in &slot_vertex {
            counts[v as usize + 1] += 1;
        }
        let shared: Vec<u32> = (0..n_vertices as u32)
            .filter(|&v| counts[v as usize + 1] > 0)
            .collect();
        let mut shared_offsets = Vec::with_capacity(shared.len() + 1);
        shared_offsets.push(0u32);
        for &v in &shared {
            shared_offsets.push(shared_offsets.last().unwrap() + counts[v as usize + 1]);
        }
        let mut index_of = vec![NONE; n_vertices];
        for (i, &v) in shared.iter().enumerate() {
            index_of[v as usize] = i as u32;
        }
        let mut next: Vec<u32> = shared_offsets[..shared.len()].to_vec();
        let mut shared_slots = vec![0u32; slot_vertex.len()];
        for (slot, &v) in slot_vertex.iter().enumerate() {
            let i = index_of[v as usize] as usize;
            shared_slots[next[i] as usize] = slot as u32;
            next[i] += 1;
        }
        ScatterPlan {
            own_start,
            targets,
            slot_start,
            shared,
            shared_offsets,
            shared_slots,
        }
    }

    /// Number of chunks.
    pub fn n_chunks(&self) -> usize {
        self.own_start.len() - 1
    }

    /// Vertex range owned by chunk `k`.
    #[inline]
    pub fn owned_range(&self, k: usize) -> std::ops::Range<usize> {
        self.own_start[k] as usize..self.own_start[k + 1] as usize
    }

    /// Slot range written by chunk `k`.
    #[inline]
    pub fn slot_range(&self, k: usize) -> std::ops::Range<usize> {
        self.slot_start[k] as usize..self.slot_start[k + 1] as usize
    }

    /// Total number of slots.
    pub fn n_slots(&self) -> usize {
        *self.slot_start.last().unwrap_or(&0) as usize
    }

    /// The targets of triangle `e`'s corners.
    #[inline]
    pub fn targets(&self, e: usize) -> [Target; 3] {
        self.targets[e].map(|t| {
            if t & SHARED_BIT == 0 {
                Target::Owned(t as usize)
            } else {
                Target::Shared((t & !SHARED_BIT) as usize)
            }
        })
    }

    /// Shared vertices (increasing) with their slots (increasing).
    pub fn shared(&self) -> impl Iterator<Item = (usize, &[u32])> + '_ {
        self.shared.iter().enumerate().map(|(i, &v)| {
            let r = self.shared_offsets[i] as usize..self.shared_offsets[i + 1] as usize;
            (v as usize, &self.shared_slots[r])
        })
    }

    /// Write every shared vertex's sum into `out`: `zero + slots[s_1] + slots[s_2] + ...` over
    /// its slots in increasing (= triangle) order, the serial scatter's order. In parallel over
    /// fixed vertex ranges on the current rayon pool (each range finds its shared vertices by
    /// bisection), so the bits do not depend on the thread count.
    pub fn sum_shared<T>(&self, out: &mut [T], slots: &[T], zero: T)
    where
        T: Copy + Send + Sync + Add<Output = T>,
    {
        const RANGE: usize = 4096;
        let sum = |i: usize| {
            let r = self.shared_offsets[i] as usize..self.shared_offsets[i + 1] as usize;
            self.shared_slots[r]
                .iter()
                .fold(zero, |acc, &s| acc + slots[s as usize])
        };
        out.par_chunks_mut(RANGE).enumerate().for_each(|(k, o)| {
            let lo = k * RANGE;
            let first = self.shared.partition_point(|&v| (v as usize) < lo);
            let last = self
                .shared
                .partition_point(|&v| (v as usize) < lo + o.len());
            for i in first..last {
                o[self.shared[i] as usize - lo] = sum(i);
            }
        });
    }

    /// Fraction of vertices that are shared (0 for a perfectly ordered mesh).
    pub fn shared_fraction(&self, n_vertices: usize) -> f64 {
        self.shared.len() as f64 / n_vertices.max(1) as f64
    }
}

/// Run `job(k, owned, slots)` for every chunk `k` on the current rayon pool, where `owned` is
/// `out[owned_range(k)]` and `slots` is `slots[slot_range(k)]`. The slices are disjoint, so
/// chunks run in parallel without synchronisation; the split is a recursive halving with
/// `rayon::join` and allocates nothing.
pub fn for_each_chunk<T: Send, S: Send>(
    plan: &ScatterPlan,
    out: &mut [T],
    slots: &mut [S],
    job: &(impl Fn(usize, &mut [T], &mut [S]) + Sync),
) {
    let n = plan.n_chunks();
    if n == 0 {
        return;
    }
    let owned = &mut out[plan.own_start[0] as usize..plan.own_start[n] as usize];
    assert_eq!(slots.len(), plan.n_slots(), "slot buffer sized by the plan");
    recurse(plan, 0, n, owned, slots, job);
}

fn recurse<T: Send, S: Send>(
    plan: &ScatterPlan,
    lo: usize,
    hi: usize,
    owned: &mut [T],
    slots: &mut [S],
    job: &(impl Fn(usize, &mut [T], &mut [S]) + Sync),
) {
    if hi - lo == 1 {
        job(lo, owned, slots);
        return;
    }
    let mid = (lo + hi) / 2;
    let (a, b) = owned.split_at_mut((plan.own_start[mid] - plan.own_start[lo]) as usize);
    let (sa, sb) = slots.split_at_mut((plan.slot_start[mid] - plan.slot_start[lo]) as usize);
    crate::par::join(
        || recurse(plan, lo, mid, a, sa, job),
        || recurse(plan, mid, hi, b, sb, job),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec2;
    use crate::mesh::Mesh;

    fn strip(nx: usize) -> Mesh {
        let mut v = Vec::new();
        for i in 0..=nx {
            v.push(Vec2::new(i as f64, 0.0));
            v.push(Vec2::new(i as f64, 1.0));
        }
        let mut t = Vec::new();
        for i in 0..nx as u32 {
            let (a, b, c, d) = (2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1);
            t.push([a, b, c]);
            t.push([a, c, d]);
        }
        Mesh::new(v, t).unwrap()
    }

    #[test]
    fn every_corner_targets_its_vertex_and_ordered_meshes_share_little() {
        let mesh = strip(5 * ELEMENT_CHUNK / 2); // 5 chunks
        let plan = mesh.scatter_plan();
        assert_eq!(plan.n_chunks(), 5);
        let mut slot_vertex = vec![usize::MAX; plan.n_slots()];
        for (e, tri) in mesh.triangles().iter().enumerate() {
            let k = e / ELEMENT_CHUNK;
            for (c, t) in plan.targets(e).into_iter().enumerate() {
                match t {
                    Target::Owned(i) => {
                        assert_eq!(plan.owned_range(k).start + i, tri[c] as usize);
                        assert!(plan.owned_range(k).contains(&(tri[c] as usize)));
                    }
                    Target::Shared(s) => {
                        assert!(plan.slot_range(k).contains(&s));
                        slot_vertex[s] = tri[c] as usize;
                    }
                }
            }
        }
        for (v, slots) in plan.shared() {
            assert!(slots.windows(2).all(|w| w[0] < w[1]));
            assert!(slots.iter().all(|&s| slot_vertex[s as usize] == v));
        }
        // Only the vertices on the 4 chunk boundaries (2 or so per boundary) are shared.
        assert!(plan.shared().count() <= 12, "{}", plan.shared().count());
    }

    /// A shuffled numbering (most vertices shared) over several vertex ranges: the parallel
    /// sum equals the serial fold over each shared vertex's slots, on 1, 2 and 3 threads.
    #[test]
    fn parallel_shared_sums_equal_the_serial_fold() {
        let nx = 8000;
        let base = strip(nx);
        // Reverse every other vertex pair so chunks cannot own contiguous ranges.
        let n = base.n_vertices();
        let perm: Vec<u32> = (0..n as u32)
            .map(|v| if v % 4 < 2 { v } else { n as u32 - 1 - v })
            .collect();
        let mut verts = vec![Vec2::zeros(); n];
        for (v, &p) in perm.iter().enumerate() {
            verts[p as usize] = base.vertices()[v];
        }
        let tris: Vec<[u32; 3]> = base
            .triangles()
            .iter()
            .map(|t| t.map(|v| perm[v as usize]))
            .collect();
        let mesh = Mesh::new(verts, tris).unwrap();
        let plan = mesh.scatter_plan();
        assert!(plan.shared_fraction(n) > 0.4 && n > 3 * 4096);
        let slots: Vec<Vec2> = (0..plan.n_slots())
            .map(|s| Vec2::new((s as f64 * 0.37).sin(), 1.0 / (1.0 + s as f64)))
            .collect();
        let mut want = vec![Vec2::new(7.0, 7.0); n];
        for (v, ss) in plan.shared() {
            want[v] = ss.iter().fold(Vec2::zeros(), |a, &s| a + slots[s as usize]);
        }
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut got = vec![Vec2::new(7.0, 7.0); n];
            pool.install(|| plan.sum_shared(&mut got, &slots, Vec2::zeros()));
            assert_eq!(got, want, "{threads} threads");
        }
    }
}
