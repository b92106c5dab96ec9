//! Boundary conditions: which vertices are kinematic (pinned or moved on a schedule).
//!
//! A **kinematic** vertex is not moved by forces or constraints (its inverse mass is zero in
//! every stepper). A pinned vertex is a kinematic vertex with zero velocity. A
//! [`PrescribedMotion`] moves its vertices with a constant velocity during a time window
//! `[start, end]` and holds them still outside it; over a step `[t, t + dt]` a vertex moves by
//! `velocity * |[t, t + dt] ∩ [start, end]|`, so the total displacement is exact for any `dt`
//! (case B's stretch). When a vertex is assigned twice, the later assignment wins.

use fem_core::math::{Real, Vec2};

use crate::error::{SolverError, check_finite_vec};
use crate::rigid::window_overlap;

/// A set of mesh vertices.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Region {
    /// Explicit vertex indices.
    Vertices(Vec<usize>),
    /// Every rest vertex inside the closed box `[min, max]` (metres), enlarged by `tolerance`
    /// (metres) on each side so vertices exactly on an edge are caught despite round-off.
    Box {
        /// Lower-left corner, m.
        min: Vec2,
        /// Upper-right corner, m.
        max: Vec2,
        /// Margin added on each side, m.
        tolerance: Real,
    },
}

impl Region {
    /// The box `[min, max]` with a margin of `1e-9` m.
    pub fn in_box(min: Vec2, max: Vec2) -> Self {
        Region::Box {
            min,
            max,
            tolerance: 1e-9,
        }
    }

    /// The vertices (rest positions `rest`) in the region, in increasing index order.
    pub fn select(&self, rest: &[Vec2], field: &str) -> Result<Vec<usize>, SolverError> {
        match self {
            Region::Vertices(list) => {
                if let Some(&index) = list.iter().find(|&&i| i >= rest.len()) {
                    return Err(SolverError::VertexOutOfRange {
                        field: field.to_owned(),
                        index,
                        n_vertices: rest.len(),
                    });
                }
                let mut out = list.clone();
                out.sort_unstable();
                out.dedup();
                Ok(out)
            }
            Region::Box {
                min,
                max,
                tolerance,
            } => {
                check_finite_vec(&format!("{field}.min"), *min)?;
                check_finite_vec(&format!("{field}.max"), *max)?;
                if !(tolerance.is_finite() && *tolerance >= 0.0) {
                    return Err(SolverError::invalid(
                        format!("{field}.tolerance"),
                        tolerance,
                        "must be a finite number >= 0",
                    ));
                }
                if min.x > max.x || min.y > max.y {
                    return Err(SolverError::invalid(
                        format!("{field}.min"),
                        format!("[{}, {}] (max = [{}, {}])", min.x, min.y, max.x, max.y),
                        "must not exceed max in either coordinate",
                    ));
                }
                let t = *tolerance;
                Ok(rest
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| {
                        p.x >= min.x - t && p.x <= max.x + t && p.y >= min.y - t && p.y <= max.y + t
                    })
                    .map(|(i, _)| i)
                    .collect())
            }
        }
    }
}

/// Vertices moved with a constant velocity during a time window (held still outside it).
#[derive(Clone, Debug, PartialEq)]
pub struct PrescribedMotion {
    /// The vertices that move.
    pub region: Region,
    /// Velocity during the window, m/s.
    pub velocity: Vec2,
    /// Window start, s (>= 0).
    pub start: Real,
    /// Window end, s (>= `start`; may be infinite).
    pub end: Real,
}

impl PrescribedMotion {
    pub(crate) fn validate(&self, field: &str) -> Result<(), SolverError> {
        check_finite_vec(&format!("{field}.velocity"), self.velocity)?;
        if !(self.start.is_finite() && self.start >= 0.0) {
            return Err(SolverError::invalid(
                format!("{field}.start"),
                self.start,
                "must be a finite number >= 0 (s)",
            ));
        }
        if self.end.is_nan() || self.end < self.start {
            return Err(SolverError::invalid(
                format!("{field}.end"),
                self.end,
                "must be >= start (s)",
            ));
        }
        Ok(())
    }

    /// The mean velocity over `[t, t + dt]`: `velocity` times the fraction of the step inside
    /// the window.
    #[inline]
    pub fn mean_velocity(&self, t: Real, dt: Real) -> Vec2 {
        self.velocity * (window_overlap(t, dt, self.start, self.end) / dt)
    }
}

/// How one kinematic vertex moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Motion {
    /// Held still.
    Pinned,
    /// On the schedule of the prescribed motion with this index.
    Scheduled(u32),
    /// Held by a pinning grab: carried to this goal position by the end of the step, along a
    /// straight line at constant speed (see [`crate::grab`]).
    Held(Vec2),
    /// Slaved to the free rigid body with this index: the stepper moves the body, and the
    /// step's end places the vertex on it ([`crate::rigid::body`]).
    Rigid(u32),
}

/// The kinematic vertices of a model, resolved to indices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Kinematics {
    /// Sorted kinematic vertex indices.
    pub(crate) vertices: Vec<u32>,
    /// For each entry of `vertices`, how it moves.
    pub(crate) motion: Vec<Motion>,
    /// The motions.
    pub(crate) motions: Vec<PrescribedMotion>,
}

impl Kinematics {
    /// Mark `list` with `motion` (later assignments win).
    pub(crate) fn assign(&mut self, list: &[usize], motion: Motion) {
        for &v in list {
            let v = v as u32;
            match self.vertices.binary_search(&v) {
                Ok(k) => self.motion[k] = motion,
                Err(k) => {
                    self.vertices.insert(k, v);
                    self.motion.insert(k, motion);
                }
            }
        }
    }

    /// The kinematic vertex indices, increasing.
    pub fn vertices(&self) -> impl Iterator<Item = usize> + '_ {
        self.vertices.iter().map(|&v| v as usize)
    }

    /// The velocity of kinematic entry `k` (at `x_old`) over the (sub)step `[t, t + dt]` of a
    /// step that ends at `until`: a schedule's mean velocity, or for a held vertex the speed
    /// that reaches its goal at `until` along a straight line.
    #[inline]
    pub(crate) fn velocity(&self, k: usize, x_old: Vec2, t: Real, dt: Real, until: Real) -> Vec2 {
        match self.motion[k] {
            // A slaved vertex's velocity is the body's, which the stepper knows.
            Motion::Pinned | Motion::Rigid(_) => Vec2::zeros(),
            Motion::Scheduled(m) => self.motions[m as usize].mean_velocity(t, dt),
            Motion::Held(goal) => {
                let left = until - t;
                // The last (sub)step lands on the goal exactly, whatever the rounding of t.
                if left <= dt * (1.0 + 1e-9) {
                    (goal - x_old) / dt
                } else {
                    (goal - x_old) / left
                }
            }
        }
    }

    /// Move the kinematic vertices over the (sub)step `[t, t + dt]` of a step that ends at
    /// `until`: `x_new = x_old + dt * v`, `v_new = v` (a held vertex lands on its goal exactly
    /// when `t + dt` reaches `until`).
    pub(crate) fn apply(
        &self,
        t: Real,
        dt: Real,
        until: Real,
        x_old: &[Vec2],
        x_new: &mut [Vec2],
        v_new: &mut [Vec2],
    ) {
        for (k, &v) in self.vertices.iter().enumerate() {
            let v = v as usize;
            if let Motion::Rigid(_) = self.motion[k] {
                // Placed on its body by the step's end.
                continue;
            }
            let vel = self.velocity(k, x_old[v], t, dt, until);
            x_new[v] = match self.motion[k] {
                Motion::Held(goal) if until - t <= dt * (1.0 + 1e-9) => goal,
                _ => x_old[v] + vel * dt,
            };
            v_new[v] = vel;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn later_assignment_wins_and_list_stays_sorted() {
        let mut k = Kinematics::default();
        use Motion::{Pinned, Scheduled};
        k.assign(&[5, 1, 3], Pinned);
        k.assign(&[3, 0], Scheduled(0));
        assert_eq!(k.vertices, vec![0, 1, 3, 5]);
        assert_eq!(k.motion, vec![Scheduled(0), Pinned, Scheduled(0), Pinned]);
    }

    #[test]
    fn region_errors_name_the_field() {
        let rest = [Vec2::zeros(), Vec2::new(1.0, 0.0)];
        let e = Region::Vertices(vec![0, 7])
            .select(&rest, "pinned")
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "pinned: vertex index 7 is out of range (mesh has 2 vertices)"
        );
        let bad = Region::in_box(Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0));
        assert!(
            bad.select(&rest, "pinned")
                .unwrap_err()
                .to_string()
                .starts_with("pinned.min = ")
        );
        let sel = Region::in_box(Vec2::new(-0.1, -0.1), Vec2::new(0.5, 0.1))
            .select(&rest, "pinned")
            .unwrap();
        assert_eq!(sel, vec![0]);
    }
}
