//! Building blocks of barrier contact in the manner of Incremental Potential Contact (Li et
//! al., "Incremental Potential Contact", ACM TOG 2020): the log barrier on a squared distance,
//! the point-segment squared distance with its gradient and Hessian, their product (the
//! contact energy of one point-segment pair), and a conservative continuous collision
//! detection (additive CCD, Li et al., "Codimensional Incremental Potential Contact", 2021)
//! for a point and a segment moving linearly over a step.
//!
//! Everything here is checked against an oracle in the tests below: finite differences for
//! every derivative, brute-force closest points for the distance, and brute-force sampling of
//! 10,000 random motions for the CCD. The solvers do not call these functions yet.
//!
//! Degrees of freedom of a pair are ordered `[p, a, b]` (the point, then the segment's two
//! ends), six in all.

use fem_core::math::{Real, Vec2, ln};
use nalgebra::{Matrix2, SMatrix, SVector};

/// Gradient with respect to `[p, a, b]`.
pub type Grad6 = SVector<Real, 6>;
/// Hessian with respect to `[p, a, b]`.
pub type Hess6 = SMatrix<Real, 6, 6>;

/// IPC's barrier on a squared distance `s` with activation `s_hat` (the squared activation
/// distance): `b(s) = -(s - s_hat)^2 ln(s / s_hat)` for `0 < s < s_hat`, 0 beyond. It is
/// twice continuously differentiable at `s_hat` (value, slope and curvature vanish there) and
/// grows without bound as `s -> 0`. Returns `(b, db/ds, d2b/ds2)`; `s <= 0` gives infinities.
/// The logarithm is fem-core's ([`fem_core::math::ln`]), so the barrier has the same bits
/// natively and in WebAssembly.
pub fn barrier(s: Real, s_hat: Real) -> (Real, Real, Real) {
    if s >= s_hat {
        return (0.0, 0.0, 0.0);
    }
    if s <= 0.0 {
        return (Real::INFINITY, Real::NEG_INFINITY, Real::INFINITY);
    }
    let (d, l) = (s - s_hat, ln(s / s_hat));
    let b = -d * d * l;
    let db = -2.0 * d * l - d * d / s;
    let d2b = -2.0 * l - 4.0 * d / s + d * d / (s * s);
    (b, db, d2b)
}

/// Which feature of the segment is closest to the point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Closest {
    /// The end `a`.
    A,
    /// The end `b`.
    B,
    /// A point inside the segment.
    Interior,
}

/// The squared distance from `p` to the segment `[a, b]`, its gradient and Hessian with
/// respect to `[p, a, b]`, and the closest feature. Within each feature's region the squared
/// distance is smooth (`|p - a|^2`, `|p - b|^2`, or `cross(b - a, p - a)^2 / |b - a|^2`); a
/// segment of zero length counts as the point `a`.
pub fn point_segment_distance2(p: Vec2, a: Vec2, b: Vec2) -> (Real, Grad6, Hess6, Closest) {
    let e = b - a;
    let l2 = e.norm_squared();
    let t = if l2 > 0.0 { (p - a).dot(&e) / l2 } else { 0.0 };
    let mut g = Grad6::zeros();
    let mut h = Hess6::zeros();
    let i2 = Matrix2::identity() * 2.0;
    if t <= 0.0 || t >= 1.0 {
        // Point-point: s = |p - q|^2 with q the nearer end (slot 2 for a, 4 for b).
        let (q, slot, feature) = if t <= 0.0 {
            (a, 2, Closest::A)
        } else {
            (b, 4, Closest::B)
        };
        let r = p - q;
        g.fixed_rows_mut::<2>(0).copy_from(&(2.0 * r));
        g.fixed_rows_mut::<2>(slot).copy_from(&(-2.0 * r));
        h.fixed_view_mut::<2, 2>(0, 0).copy_from(&i2);
        h.fixed_view_mut::<2, 2>(slot, slot).copy_from(&i2);
        h.fixed_view_mut::<2, 2>(0, slot).copy_from(&(-i2));
        h.fixed_view_mut::<2, 2>(slot, 0).copy_from(&(-i2));
        return (r.norm_squared(), g, h, feature);
    }
    // Interior: s = c^2 / l2 with c = cross(e, q), q = p - a.
    let q = p - a;
    let c = e.x * q.y - e.y * q.x;
    let perp = |v: Vec2| Vec2::new(-v.y, v.x);
    let mut dc = Grad6::zeros();
    dc.fixed_rows_mut::<2>(0).copy_from(&perp(e));
    dc.fixed_rows_mut::<2>(2).copy_from(&(perp(q) - perp(e)));
    dc.fixed_rows_mut::<2>(4).copy_from(&(-perp(q)));
    let mut dl = Grad6::zeros();
    dl.fixed_rows_mut::<2>(2).copy_from(&(-2.0 * e));
    dl.fixed_rows_mut::<2>(4).copy_from(&(2.0 * e));
    // c = b x p - b x a - a x p; the Hessian of u x v has the block K at (u, v), K^T at (v, u).
    let k = Matrix2::new(0.0, 1.0, -1.0, 0.0);
    let mut d2c = Hess6::zeros();
    for (u, v, sign) in [(4, 0, 1.0), (4, 2, -1.0), (2, 0, -1.0)] {
        d2c.fixed_view_mut::<2, 2>(u, v).copy_from(&(k * sign));
        d2c.fixed_view_mut::<2, 2>(v, u)
            .copy_from(&(k.transpose() * sign));
    }
    let mut d2l = Hess6::zeros();
    d2l.fixed_view_mut::<2, 2>(2, 2).copy_from(&i2);
    d2l.fixed_view_mut::<2, 2>(4, 4).copy_from(&i2);
    d2l.fixed_view_mut::<2, 2>(2, 4).copy_from(&(-i2));
    d2l.fixed_view_mut::<2, 2>(4, 2).copy_from(&(-i2));
    let s = c * c / l2;
    g = dc * (2.0 * c / l2) - dl * (c * c / (l2 * l2));
    h = dc * dc.transpose() * (2.0 / l2) + d2c * (2.0 * c / l2)
        - (dc * dl.transpose() + dl * dc.transpose()) * (2.0 * c / (l2 * l2))
        + dl * dl.transpose() * (2.0 * c * c / (l2 * l2 * l2))
        - d2l * (c * c / (l2 * l2));
    (s, g, h, Closest::Interior)
}

/// The squared distance from `p` to the segment `[a, b]` alone (the value of
/// [`point_segment_distance2`]).
pub fn distance2(p: Vec2, a: Vec2, b: Vec2) -> Real {
    let e = b - a;
    let l2 = e.norm_squared();
    let t = if l2 > 0.0 { (p - a).dot(&e) / l2 } else { 0.0 };
    if t <= 0.0 {
        (p - a).norm_squared()
    } else if t >= 1.0 {
        (p - b).norm_squared()
    } else {
        let q = p - a;
        let c = e.x * q.y - e.y * q.x;
        c * c / l2
    }
}

/// The barrier energy `kappa b(s(p, a, b))` of one point-segment pair with activation
/// distance `d_hat`, and its gradient and Hessian with respect to `[p, a, b]` (the Hessian is
/// not projected to positive semi-definite).
pub fn point_segment_barrier(
    p: Vec2,
    a: Vec2,
    b: Vec2,
    d_hat: Real,
    kappa: Real,
) -> (Real, Grad6, Hess6) {
    let (s, ds, d2s, _) = point_segment_distance2(p, a, b);
    let (e, de, d2e) = barrier(s, d_hat * d_hat);
    if e == 0.0 && de == 0.0 {
        return (0.0, Grad6::zeros(), Hess6::zeros());
    }
    (
        kappa * e,
        ds * (kappa * de),
        (ds * ds.transpose() * d2e + d2s * de) * kappa,
    )
}

/// Conservative time of impact of a point and a segment moving linearly over `[0, 1]`
/// (start positions and displacements): the additive CCD of Li et al. 2021. Returns `None`
/// when they stay apart over the whole step, otherwise a time `t` in `[0, 1)` at which they
/// are still apart, their distance having fallen to at most `separation` times its initial
/// value (`separation` in `(0, 1)`; 0.1 is usual): advancing a step by any fraction up to `t`
/// never makes them touch. A pair that starts in contact returns `Some(0.0)`.
///
/// Each iteration advances by 90 % of the time the distance needs to close at the largest
/// relative speed (the point's displacement plus the larger of the ends',
/// after removing the pair's mean displacement).
pub fn point_segment_toi(
    start: [Vec2; 3],
    displacement: [Vec2; 3],
    separation: Real,
) -> Option<Real> {
    let mean = (displacement[0] + displacement[1] + displacement[2]) / 3.0;
    let dx = displacement.map(|d| d - mean);
    let lp = dx[0].norm() + dx[1].norm().max(dx[2].norm());
    if lp == 0.0 {
        return None;
    }
    let at = |t: Real| -> Real {
        let [p, a, b] = [0, 1, 2].map(|k| start[k] + dx[k] * t);
        distance2(p, a, b).sqrt()
    };
    let d0 = at(0.0);
    if d0 <= 0.0 {
        return Some(0.0);
    }
    let target = separation * d0;
    let mut t = 0.0;
    let mut step = (1.0 - separation) * d0 / lp;
    // Each step is short enough that the distance keeps at least a tenth of its value (the
    // first, `separation`), so it stays positive; it shrinks geometrically while they close,
    // so few steps reach the target. The cap only guards against round-off.
    for _ in 0..10_000 {
        let next = t + step;
        if next >= 1.0 {
            // The rest of the step is within the safe window: no contact in it.
            return None;
        }
        let d = at(next);
        if d <= target {
            return Some(next);
        }
        t = next;
        step = 0.9 * d / lp;
    }
    Some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift), so the random cases are the same each run.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> Real {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as Real / (1u64 << 53) as Real
        }
        fn vec(&mut self, r: Real) -> Vec2 {
            Vec2::new(r * (2.0 * self.next() - 1.0), r * (2.0 * self.next() - 1.0))
        }
    }

    fn dofs(x: &Grad6) -> (Vec2, Vec2, Vec2) {
        (
            Vec2::new(x[0], x[1]),
            Vec2::new(x[2], x[3]),
            Vec2::new(x[4], x[5]),
        )
    }

    #[test]
    fn barrier_derivatives_match_finite_differences_and_vanish_at_the_activation() {
        let s_hat = 1e-2;
        for &s in &[1e-6, 1e-4, 3e-3, 9.9e-3] {
            let (b, db, d2b) = barrier(s, s_hat);
            let h = 1e-7 * s;
            let (bp, dbp, _) = barrier(s + h, s_hat);
            let (bm, dbm, _) = barrier(s - h, s_hat);
            // Central differences: relative error O(h^2) plus round-off; 1e-6 is loose for both.
            assert!(
                ((bp - bm) / (2.0 * h) - db).abs() <= 1e-6 * db.abs(),
                "s = {s}"
            );
            assert!(
                ((dbp - dbm) / (2.0 * h) - d2b).abs() <= 1e-6 * d2b.abs(),
                "s = {s}"
            );
            assert!(b > 0.0 && db < 0.0 && d2b > 0.0);
        }
        // C2 at the activation distance, zero beyond, unbounded at contact.
        let (b, db, d2b) = barrier(s_hat * (1.0 - 1e-9), s_hat);
        assert!(b.abs() < 1e-20 && db.abs() < 1e-12 && d2b.abs() < 1e-6);
        assert_eq!(barrier(2.0 * s_hat, s_hat), (0.0, 0.0, 0.0));
        assert!(barrier(1e-300, s_hat).0 > 1e-3);
        assert_eq!(barrier(0.0, s_hat).0, Real::INFINITY);
    }

    /// Finite-difference gradient and Hessian of `f` at `x`.
    fn fd(f: &dyn Fn(&Grad6) -> (Real, Grad6), x: &Grad6, h: Real) -> (Grad6, Hess6) {
        let mut g = Grad6::zeros();
        let mut hess = Hess6::zeros();
        for k in 0..6 {
            let mut xp = *x;
            let mut xm = *x;
            xp[k] += h;
            xm[k] -= h;
            let ((fp, gp), (fm, gm)) = (f(&xp), f(&xm));
            g[k] = (fp - fm) / (2.0 * h);
            hess.set_column(k, &((gp - gm) / (2.0 * h)));
        }
        (g, hess)
    }

    #[test]
    fn squared_distance_is_the_closest_point_s_and_its_derivatives_match_finite_differences() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut seen = [0usize; 3];
        for _ in 0..3000 {
            let x = Grad6::from_fn(|_, _| 2.0 * rng.next() - 1.0);
            let (p, a, b) = dofs(&x);
            let (s, g, h, feature) = point_segment_distance2(p, a, b);
            assert_eq!(s, distance2(p, a, b));
            // Oracle: the closest of 2001 points along the segment (plus the exact projection
            // clamped, which sampling approaches from above).
            let sampled = (0..=2000)
                .map(|k| (p - (a + (b - a) * (k as Real / 2000.0))).norm_squared())
                .fold(Real::INFINITY, Real::min);
            assert!(
                s <= sampled + 1e-15 && sampled - s <= 1e-5,
                "{s} vs {sampled}"
            );
            // Skip configurations within 1e-4 of a region boundary, where the derivatives jump.
            let t = (p - a).dot(&(b - a)) / (b - a).norm_squared();
            if t.abs() < 1e-4 || (t - 1.0).abs() < 1e-4 {
                continue;
            }
            seen[feature as usize] += 1;
            let f = |y: &Grad6| {
                let (p, a, b) = dofs(y);
                let (s, g, _, _) = point_segment_distance2(p, a, b);
                (s, g)
            };
            let (fg, fh) = fd(&f, &x, 1e-6);
            // Central differences of a polynomial (or a rational function far from its pole):
            // errors of 1e-8 relative to the derivatives' size.
            assert!((fg - g).norm() <= 1e-7 * (1.0 + g.norm()), "{feature:?}");
            assert!(
                (fh - h).norm() <= 1e-6 * (1.0 + h.norm()),
                "{feature:?}: {}",
                (fh - h).norm()
            );
        }
        assert!(
            seen.iter().all(|&n| n > 200),
            "every feature tested: {seen:?}"
        );
    }

    #[test]
    fn pair_barrier_derivatives_match_finite_differences() {
        let mut rng = Rng(42);
        let (d_hat, kappa) = (0.2, 3.0);
        let mut active = 0;
        for _ in 0..2000 {
            // A segment and a point near it.
            let a = rng.vec(1.0);
            let b = a + rng.vec(1.0);
            let p = a + (b - a) * (1.4 * rng.next() - 0.2) + rng.vec(0.25);
            let x = Grad6::from_column_slice(&[p.x, p.y, a.x, a.y, b.x, b.y]);
            let (e, g, h) = point_segment_barrier(p, a, b, d_hat, kappa);
            let (s, _, _, _) = point_segment_distance2(p, a, b);
            if !(s > 1e-4 && s < 0.95 * d_hat * d_hat) {
                continue;
            }
            let t = (p - a).dot(&(b - a)) / (b - a).norm_squared();
            if t.abs() < 1e-3 || (t - 1.0).abs() < 1e-3 {
                continue;
            }
            active += 1;
            assert!(e > 0.0);
            let f = |y: &Grad6| {
                let (p, a, b) = dofs(y);
                let (e, g, _) = point_segment_barrier(p, a, b, d_hat, kappa);
                (e, g)
            };
            let (fg, fh) = fd(&f, &x, 1e-7);
            assert!(
                (fg - g).norm() <= 1e-5 * (1.0 + g.norm()),
                "{}",
                (fg - g).norm()
            );
            assert!(
                (fh - h).norm() <= 1e-4 * (1.0 + h.norm()),
                "{}",
                (fh - h).norm()
            );
        }
        assert!(active > 300, "{active} active pairs");
    }

    /// Brute-force first contact over `[0, 1]`: 4000 samples; contact is a sign change of the
    /// side of the line with the projection inside the segment, or a distance below 1e-12.
    fn sampled_contact(start: [Vec2; 3], disp: [Vec2; 3]) -> Option<Real> {
        let n = 4000;
        let at = |t: Real| [0, 1, 2].map(|k| start[k] + disp[k] * t);
        let side = |x: [Vec2; 3]| {
            let e = x[2] - x[1];
            let q = x[0] - x[1];
            (e.x * q.y - e.y * q.x, q.dot(&e) / e.norm_squared())
        };
        let (mut prev, _) = side(at(0.0));
        for k in 1..=n {
            let t = k as Real / n as Real;
            let x = at(t);
            let (c, u) = side(x);
            let close = distance2(x[0], x[1], x[2]) < 1e-24;
            if close || (c.signum() != prev.signum() && (-1e-9..=1.0 + 1e-9).contains(&u)) {
                return Some(t);
            }
            prev = c;
        }
        None
    }

    #[test]
    fn ccd_misses_no_crossing_in_10000_random_motions() {
        let mut rng = Rng(7);
        let (mut crossings, mut calls_apart) = (0, 0);
        for case in 0..10_000 {
            let a = rng.vec(1.0);
            let b = a + rng.vec(1.0);
            let p = rng.vec(1.5);
            // Half the cases aim the point through a random point of the moving segment at a
            // random time, so that many of them cross.
            let da = rng.vec(0.5);
            let db = rng.vec(0.5);
            let dp = if case % 2 == 0 {
                let (t, u) = (rng.next(), rng.next());
                let hit = (a + da * t) + ((b + db * t) - (a + da * t)) * u;
                (hit - p) / t.max(1e-3)
            } else {
                rng.vec(2.0)
            };
            let (start, disp) = ([p, a, b], [dp, da, db]);
            if distance2(p, a, b) < 1e-6 {
                continue;
            }
            let toi = point_segment_toi(start, disp, 0.1);
            if let Some(t_hit) = sampled_contact(start, disp) {
                crossings += 1;
                let t = toi.unwrap_or_else(|| panic!("case {case}: missed contact at {t_hit}"));
                assert!(
                    t < t_hit,
                    "case {case}: toi {t} after the contact at {t_hit}"
                );
            }
            if let Some(t) = toi {
                // Conservative: still apart at the returned time.
                let x = [0, 1, 2].map(|k| start[k] + disp[k] * t);
                assert!(distance2(x[0], x[1], x[2]) > 0.0, "case {case}");
            } else {
                calls_apart += 1;
            }
        }
        assert!(crossings > 3000, "{crossings} crossings sampled");
        assert!(calls_apart > 1000, "{calls_apart} motions found apart");
    }

    #[test]
    fn ccd_of_a_point_falling_onto_a_segment_stops_short_of_it() {
        // A point 1 m above a horizontal segment moves 2 m down: contact at t = 0.5.
        let start = [
            Vec2::new(0.0, 1.0),
            Vec2::new(-1.0, 0.0),
            Vec2::new(1.0, 0.0),
        ];
        let disp = [Vec2::new(0.0, -2.0), Vec2::zeros(), Vec2::zeros()];
        let t = point_segment_toi(start, disp, 0.1).unwrap();
        // It stops with at most 10 % of the gap left, and never past contact.
        assert!((0.45..0.5).contains(&t), "{t}");
        // Moving away: no contact.
        let up = [Vec2::new(0.0, 2.0), Vec2::zeros(), Vec2::zeros()];
        assert_eq!(point_segment_toi(start, up, 0.1), None);
        // Passing beside the segment's end: no contact.
        let beside = [
            Vec2::new(3.0, 1.0),
            Vec2::new(-1.0, 0.0),
            Vec2::new(1.0, 0.0),
        ];
        assert_eq!(point_segment_toi(beside, disp, 0.1), None);
    }
}
