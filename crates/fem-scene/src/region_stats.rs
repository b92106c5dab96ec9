//! The numbers a medic reads, per material region of the body (soft tissue, bone): at every
//! recorded frame the peak and the area-weighted mean von Mises stress, the largest
//! compressive strain, and the fraction of the region's area whose von Mises stress exceeds a
//! threshold (`output.stress_threshold`, `fem2d run --stress-threshold`); over the run the
//! peaks and where they occurred. A body of one material has one region, named after
//! `material.name`.
//!
//! Definitions (per element, rest areas as weights):
//! - **mean von Mises** = `sum_e a_e vm_e / sum_e a_e` over the region;
//! - **compressive strain** = `1 - s_min`, with `s_min` the smaller principal stretch (singular
//!   value of `F`), when it is below one (0 otherwise): the nominal strain of the most
//!   compressed direction;
//! - **area above threshold** = the rest area of the elements with `vm_e > threshold`, over the
//!   region's rest area.

use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;
use fem_core::stress::ElementStress;
use serde::{Deserialize, Serialize};

use crate::build::MaterialRegions;

/// One region's numbers at one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RegionFrame {
    /// Largest element von Mises stress, Pa.
    pub peak_von_mises: f64,
    /// Area-weighted mean von Mises stress, Pa.
    pub mean_von_mises: f64,
    /// Largest compressive strain (`1 - s_min`), dimensionless.
    pub max_compressive_strain: f64,
    /// Fraction of the region's rest area above the stress threshold, in [0, 1].
    pub area_above_threshold: f64,
}

/// One region over a run, in `summary.json`'s `regions`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RegionSummary {
    /// The region's name (`material.name` or a `[[regions]]` name).
    pub name: String,
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson ratio.
    pub poisson_ratio: f64,
    /// Density, kg/m^3.
    pub density: f64,
    /// Whether the region is rigid (its elements carry no stress: every stress number reads
    /// 0, and the peak's place is `null`; its bodies' loads are in `rigid_bodies`).
    #[serde(default)]
    pub rigid: bool,
    /// Rest area, m^2 (per unit thickness).
    pub area: f64,
    /// Largest element von Mises stress over the recorded frames, Pa.
    pub peak_von_mises: f64,
    /// The step of that frame.
    pub peak_von_mises_step: u64,
    /// The deformed centroid of that element at that frame, m.
    pub peak_von_mises_at: [f64; 2],
    /// Largest compressive strain over the recorded frames.
    pub max_compressive_strain: f64,
    /// Largest fraction of the area above the threshold over the recorded frames.
    pub peak_area_above_threshold: f64,
    /// The region's numbers at the last recorded frame.
    #[serde(rename = "final")]
    pub last: RegionFrame,
}

/// Per-region statistics of a run, updated at every recorded frame.
#[derive(Clone, Debug)]
pub(crate) struct RegionTracker {
    tags: Vec<u32>,
    threshold: Real,
    summaries: Vec<RegionSummary>,
    /// Per region, per recorded frame.
    series: Vec<Vec<RegionFrame>>,
    /// Per region, this frame's accumulators.
    current: Vec<(RegionFrame, usize)>,
}

impl RegionTracker {
    pub(crate) fn new(regions: &MaterialRegions, mesh: &Mesh, threshold: Real) -> Self {
        let mut area = vec![0.0; regions.materials.len()];
        for (el, &t) in mesh.elements().iter().zip(&regions.tags) {
            area[t as usize] += el.area;
        }
        let summaries = (regions.materials.iter().zip(area))
            .map(|(m, area)| RegionSummary {
                name: m.name.clone(),
                youngs_modulus: m.youngs_modulus,
                poisson_ratio: m.poisson_ratio,
                density: m.density,
                rigid: m.rigid,
                area,
                peak_von_mises: 0.0,
                peak_von_mises_step: 0,
                peak_von_mises_at: [f64::NAN; 2],
                max_compressive_strain: 0.0,
                peak_area_above_threshold: 0.0,
                last: RegionFrame::default(),
            })
            .collect();
        let n = regions.materials.len();
        RegionTracker {
            tags: regions.tags.clone(),
            threshold,
            summaries,
            series: vec![Vec::new(); n],
            current: vec![(RegionFrame::default(), usize::MAX); n],
        }
    }

    /// Fold in the stress of one frame at positions `x`.
    pub(crate) fn record(&mut self, mesh: &Mesh, stress: &[ElementStress], x: &[Vec2], step: u64) {
        self.current
            .iter_mut()
            .for_each(|c| *c = (RegionFrame::default(), usize::MAX));
        for ((t, s), el) in stress.iter().enumerate().zip(mesh.elements()) {
            let (frame, peak_at) = &mut self.current[self.tags[t] as usize];
            let vm = s.von_mises;
            if !vm.is_finite() {
                continue;
            }
            if *peak_at == usize::MAX || vm > frame.peak_von_mises {
                frame.peak_von_mises = vm;
                *peak_at = t;
            }
            frame.mean_von_mises += el.area * vm;
            frame.max_compressive_strain = frame.max_compressive_strain.max(-s.strain.1);
            if vm > self.threshold {
                frame.area_above_threshold += el.area;
            }
        }
        for (k, (frame, peak_at)) in self.current.iter_mut().enumerate() {
            let sum = &mut self.summaries[k];
            if sum.area > 0.0 {
                frame.mean_von_mises /= sum.area;
                frame.area_above_threshold /= sum.area;
            }
            if *peak_at != usize::MAX && frame.peak_von_mises > sum.peak_von_mises {
                let [a, b, c] = mesh.gather(*peak_at, x);
                let centroid = (a + b + c) / 3.0;
                sum.peak_von_mises = frame.peak_von_mises;
                sum.peak_von_mises_step = step;
                sum.peak_von_mises_at = [centroid.x, centroid.y];
            }
            sum.max_compressive_strain =
                sum.max_compressive_strain.max(frame.max_compressive_strain);
            sum.peak_area_above_threshold = sum
                .peak_area_above_threshold
                .max(frame.area_above_threshold);
            sum.last = *frame;
            self.series[k].push(*frame);
        }
    }

    /// The threshold, Pa.
    pub(crate) fn threshold(&self) -> Real {
        self.threshold
    }

    /// The summaries and the per-frame series, per region.
    pub(crate) fn finish(self) -> (Vec<RegionSummary>, Vec<Vec<RegionFrame>>) {
        (self.summaries, self.series)
    }
}
