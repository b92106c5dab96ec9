//! The broad phase of contact: a uniform grid of axis-aligned boxes (the soft body's boundary
//! edges, swept over a step when a motion is known), queried with an obstacle's box. What it
//! returns is a superset of the pairs whose boxes overlap, in increasing index order, so every
//! caller sees the same candidates in the same order on any thread count and in WebAssembly.
//!
//! A grid rather than a BVH: the boxes are edges of one mesh, of similar size, so a grid whose
//! cell is about the mean box size puts a few boxes in each cell, is rebuilt in linear time
//! (two counting passes, no allocation once the buffers have grown), and needs no balancing.
//! The cell count is capped (at 4 per box, at least 64 cells), so a stray huge box makes the
//! grid coarse, never large.

use fem_core::math::{Real, Vec2};

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Aabb {
    pub lo: Vec2,
    pub hi: Vec2,
}

impl Aabb {
    /// The empty box (the identity of [`Aabb::include`]).
    pub(crate) fn empty() -> Self {
        Aabb {
            lo: Vec2::repeat(Real::INFINITY),
            hi: Vec2::repeat(Real::NEG_INFINITY),
        }
    }

    /// The box of a set of points.
    pub(crate) fn of(points: &[Vec2]) -> Self {
        let mut b = Self::empty();
        for p in points {
            b.include(*p);
        }
        b
    }

    /// Grow to contain `p`.
    pub(crate) fn include(&mut self, p: Vec2) {
        self.lo = self.lo.inf(&p);
        self.hi = self.hi.sup(&p);
    }

    /// The box grown by `margin` on every side.
    pub(crate) fn inflated(self, margin: Real) -> Self {
        Aabb {
            lo: self.lo - Vec2::repeat(margin),
            hi: self.hi + Vec2::repeat(margin),
        }
    }

    /// Whether the two closed boxes share a point.
    pub(crate) fn overlaps(&self, o: &Aabb) -> bool {
        self.lo.x <= o.hi.x && o.lo.x <= self.hi.x && self.lo.y <= o.hi.y && o.lo.y <= self.hi.y
    }
}

/// A uniform grid over a set of boxes; [`Grid::query`] lists the boxes that may overlap a box.
#[derive(Clone, Debug, Default)]
pub(crate) struct Grid {
    origin: Vec2,
    inv_cell: Real,
    nx: usize,
    ny: usize,
    /// Compressed rows: the boxes of cell `c` are `items[start[c]..start[c + 1]]`, ascending.
    start: Vec<u32>,
    items: Vec<u32>,
    boxes: Vec<Aabb>,
    /// Build scratch: the next free slot of each cell.
    fill: Vec<u32>,
    /// Query scratch: the last query that saw each box (deduplication without sorting).
    seen: Vec<u32>,
    stamp: u32,
}

impl Grid {
    /// Rebuild the grid over `boxes` (reusing its buffers).
    pub(crate) fn build(&mut self, boxes: &[Aabb]) {
        self.boxes.clear();
        self.boxes.extend_from_slice(boxes);
        self.seen.clear();
        self.seen.resize(boxes.len(), 0);
        self.stamp = 0;
        let mut all = Aabb::empty();
        let mut mean = 0.0;
        for b in boxes {
            all.include(b.lo);
            all.include(b.hi);
            mean += (b.hi - b.lo).max();
        }
        if boxes.is_empty() || !all.lo.iter().chain(all.hi.iter()).all(|c| c.is_finite()) {
            self.nx = 0;
            self.ny = 0;
            self.start.clear();
            self.items.clear();
            return;
        }
        mean /= boxes.len() as Real;
        let extent = all.hi - all.lo;
        let max_cells = (4 * boxes.len()).max(64) as Real;
        // The cell is the mean box size, grown until the cell count is within the cap.
        let mut cell = mean.max(extent.max() * 1e-6).max(Real::MIN_POSITIVE);
        while ((extent.x / cell).floor() + 1.0) * ((extent.y / cell).floor() + 1.0) > max_cells {
            cell *= 1.5;
        }
        self.origin = all.lo;
        self.inv_cell = 1.0 / cell;
        self.nx = (extent.x * self.inv_cell) as usize + 1;
        self.ny = (extent.y * self.inv_cell) as usize + 1;
        let cells = self.nx * self.ny;
        self.start.clear();
        self.start.resize(cells + 1, 0);
        for b in boxes {
            let (i0, j0, i1, j1) = self.range(b);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    self.start[j * self.nx + i + 1] += 1;
                }
            }
        }
        for c in 0..cells {
            self.start[c + 1] += self.start[c];
        }
        self.items.clear();
        self.items.resize(self.start[cells] as usize, 0);
        // Fill in box order, so each cell lists its boxes in ascending order.
        self.fill.clear();
        self.fill.extend_from_slice(&self.start[..cells]);
        for (k, b) in boxes.iter().enumerate() {
            let (i0, j0, i1, j1) = self.range(b);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let c = j * self.nx + i;
                    self.items[self.fill[c] as usize] = k as u32;
                    self.fill[c] += 1;
                }
            }
        }
    }

    /// The cell range `(i0, j0, i1, j1)` a box covers, clamped to the grid.
    fn range(&self, b: &Aabb) -> (usize, usize, usize, usize) {
        let cell = |v: Real, o: Real, n: usize| -> usize {
            let c = ((v - o) * self.inv_cell).floor();
            if c <= 0.0 { 0 } else { (c as usize).min(n - 1) }
        };
        (
            cell(b.lo.x, self.origin.x, self.nx),
            cell(b.lo.y, self.origin.y, self.ny),
            cell(b.hi.x, self.origin.x, self.nx),
            cell(b.hi.y, self.origin.y, self.ny),
        )
    }

    /// Append to `out` (cleared first) the indices of the boxes that overlap `query`, in
    /// ascending order.
    pub(crate) fn query(&mut self, query: &Aabb, out: &mut Vec<u32>) {
        out.clear();
        if self.nx == 0 || !(query.lo.x.is_finite() && query.hi.y.is_finite()) {
            return;
        }
        let all_lo = self.origin;
        let all_hi = self.origin + Vec2::new(self.nx as Real, self.ny as Real) / self.inv_cell;
        if query.hi.x < all_lo.x
            || query.hi.y < all_lo.y
            || query.lo.x > all_hi.x
            || query.lo.y > all_hi.y
        {
            return;
        }
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.seen.fill(0);
            self.stamp = 1;
        }
        let (i0, j0, i1, j1) = self.range(query);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let c = j * self.nx + i;
                for &k in &self.items[self.start[c] as usize..self.start[c + 1] as usize] {
                    let seen = &mut self.seen[k as usize];
                    if *seen != self.stamp && self.boxes[k as usize].overlaps(query) {
                        *seen = self.stamp;
                        out.push(k);
                    }
                }
            }
        }
        out.sort_unstable();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (the crate has no rand dependency).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> Real {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as Real / (1u64 << 53) as Real
        }
    }

    #[test]
    fn grid_queries_equal_brute_force_overlaps() {
        let mut rng = Lcg(7);
        let mut grid = Grid::default();
        let mut out = Vec::new();
        for round in 0..20 {
            // Boxes of mixed sizes, a few of them huge, to exercise the cell-count cap.
            let n = 1 + round * 37;
            let boxes: Vec<Aabb> = (0..n)
                .map(|k| {
                    let c = Vec2::new(rng.next() * 10.0, rng.next() * 3.0);
                    let s = if k % 50 == 7 { 8.0 } else { 0.3 * rng.next() };
                    Aabb::of(&[c, c + Vec2::new(s * rng.next(), s * rng.next())])
                })
                .collect();
            grid.build(&boxes);
            for _ in 0..200 {
                let c = Vec2::new(rng.next() * 14.0 - 2.0, rng.next() * 7.0 - 2.0);
                let q = Aabb::of(&[c, c + Vec2::new(rng.next(), rng.next())]);
                grid.query(&q, &mut out);
                let expected: Vec<u32> = (0..n as u32)
                    .filter(|&k| boxes[k as usize].overlaps(&q))
                    .collect();
                assert_eq!(out, expected, "round {round}");
            }
        }
    }

    #[test]
    fn an_empty_grid_finds_nothing() {
        let mut grid = Grid::default();
        grid.build(&[]);
        let mut out = vec![3];
        grid.query(&Aabb::of(&[Vec2::zeros(), Vec2::new(1.0, 1.0)]), &mut out);
        assert!(out.is_empty());
    }
}
