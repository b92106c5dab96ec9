//! Colormaps: scalar in `[0, 1]` to an sRGB colour.
//!
//! The three sequential maps (viridis, inferno, cividis) are perceptually uniform and come from
//! `colorous`; `coolwarm` is Kenneth Moreland's smooth diverging map (blue, light grey at the
//! middle, red), meant for quantities around a reference value such as det F around 1.

use std::fmt;
use std::str::FromStr;
use std::sync::OnceLock;

use crate::RenderError;

/// The colour of "no data" (NaN or infinite values): a neutral mid grey, distinct from the
/// light grey at the middle of [`Colormap::Coolwarm`].
pub const NO_DATA: [u8; 3] = [160, 160, 160];

/// Number of entries of the lookup tables behind [`Colormap::lut`].
pub(crate) const LUT_SIZE: usize = 1024;

/// A colormap for scalar fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
#[non_exhaustive]
pub enum Colormap {
    /// Perceptually uniform blue-green-yellow (matplotlib's default).
    #[default]
    Viridis,
    /// Perceptually uniform black-purple-orange-light yellow.
    Inferno,
    /// Perceptually uniform blue-grey-yellow, readable with colour-vision deficiencies.
    Cividis,
    /// Moreland's diverging blue-grey-red map, for values around a reference (det F around 1).
    Coolwarm,
}

/// Moreland's "smooth cool warm" map at 33 evenly spaced points (from his published table);
/// linear interpolation in between.
const COOLWARM: [[u8; 3]; 33] = [
    [59, 76, 192],
    [68, 90, 204],
    [77, 104, 215],
    [87, 117, 225],
    [98, 130, 234],
    [108, 142, 241],
    [119, 154, 247],
    [130, 165, 251],
    [141, 176, 254],
    [152, 185, 255],
    [163, 194, 255],
    [174, 201, 253],
    [184, 208, 249],
    [194, 213, 244],
    [204, 217, 238],
    [213, 219, 230],
    [221, 221, 221],
    [229, 216, 209],
    [236, 211, 197],
    [241, 204, 185],
    [245, 196, 173],
    [247, 187, 160],
    [247, 177, 148],
    [247, 166, 135],
    [244, 154, 123],
    [241, 141, 111],
    [236, 127, 99],
    [229, 112, 88],
    [222, 96, 77],
    [213, 80, 66],
    [203, 62, 56],
    [192, 40, 47],
    [180, 4, 38],
];

impl Colormap {
    /// All colormaps, in the order of their names in error messages.
    pub const ALL: [Colormap; 4] = [
        Colormap::Viridis,
        Colormap::Inferno,
        Colormap::Cividis,
        Colormap::Coolwarm,
    ];

    /// The colour at `t`, clamped to `[0, 1]` (0 is the low end). NaN gives [`NO_DATA`].
    pub fn sample(self, t: f64) -> [u8; 3] {
        if t.is_nan() {
            return NO_DATA;
        }
        let t = t.clamp(0.0, 1.0);
        let gradient = match self {
            Colormap::Viridis => colorous::VIRIDIS,
            Colormap::Inferno => colorous::INFERNO,
            Colormap::Cividis => colorous::CIVIDIS,
            Colormap::Coolwarm => return coolwarm(t),
        };
        gradient.eval_continuous(t).into_array()
    }

    /// The lower-case name, as accepted by [`str::parse`].
    pub fn name(self) -> &'static str {
        match self {
            Colormap::Viridis => "viridis",
            Colormap::Inferno => "inferno",
            Colormap::Cividis => "cividis",
            Colormap::Coolwarm => "coolwarm",
        }
    }

    /// A [`LUT_SIZE`]-entry table: entry `i` is `sample(i / (LUT_SIZE - 1))`, built once.
    pub(crate) fn lut(self) -> &'static [[u8; 3]; LUT_SIZE] {
        static LUTS: [OnceLock<Box<[[u8; 3]; LUT_SIZE]>>; 4] = [
            OnceLock::new(),
            OnceLock::new(),
            OnceLock::new(),
            OnceLock::new(),
        ];
        let slot = match self {
            Colormap::Viridis => 0,
            Colormap::Inferno => 1,
            Colormap::Cividis => 2,
            Colormap::Coolwarm => 3,
        };
        LUTS[slot].get_or_init(|| {
            let mut lut = Box::new([[0u8; 3]; LUT_SIZE]);
            for (i, c) in lut.iter_mut().enumerate() {
                *c = self.sample(i as f64 / (LUT_SIZE - 1) as f64);
            }
            lut
        })
    }
}

fn coolwarm(t: f64) -> [u8; 3] {
    let x = t * (COOLWARM.len() - 1) as f64;
    let i = (x.floor() as usize).min(COOLWARM.len() - 2);
    let f = x - i as f64;
    let (a, b) = (COOLWARM[i], COOLWARM[i + 1]);
    std::array::from_fn(|k| (a[k] as f64 + (b[k] as f64 - a[k] as f64) * f).round() as u8)
}

impl fmt::Display for Colormap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Colormap {
    type Err = RenderError;

    /// Parses a name case-insensitively: `viridis`, `inferno`, `cividis` or `coolwarm`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let wanted = s.trim();
        Colormap::ALL
            .into_iter()
            .find(|c| c.name().eq_ignore_ascii_case(wanted))
            .ok_or_else(|| {
                let names: Vec<&str> = Colormap::ALL.iter().map(|c| c.name()).collect();
                RenderError::Input(format!(
                    "unknown colormap {s:?}: expected one of {}",
                    names.join(", ")
                ))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_errors_list_names() {
        for c in Colormap::ALL {
            assert_eq!(c.name().parse::<Colormap>().unwrap(), c);
            assert_eq!(c.name().to_uppercase().parse::<Colormap>().unwrap(), c);
        }
        let msg = "jet".parse::<Colormap>().unwrap_err().to_string();
        for c in Colormap::ALL {
            assert!(msg.contains(c.name()), "{msg}");
        }
        assert!(msg.contains("jet"), "{msg}");
    }

    #[test]
    fn sample_clamps_and_handles_nan() {
        for c in Colormap::ALL {
            assert_eq!(c.sample(-3.0), c.sample(0.0));
            assert_eq!(c.sample(7.0), c.sample(1.0));
            assert_eq!(c.sample(f64::NAN), NO_DATA);
            assert_ne!(c.sample(0.0), c.sample(1.0));
            assert_eq!(c.lut()[0], c.sample(0.0));
            assert_eq!(c.lut()[LUT_SIZE - 1], c.sample(1.0));
        }
        assert_eq!(Colormap::Viridis.sample(0.0), [68, 1, 84]);
        assert_eq!(Colormap::Coolwarm.sample(0.5), [221, 221, 221]);
        assert_eq!(Colormap::Coolwarm.sample(1.0), [180, 4, 38]);
    }

    #[test]
    fn sequential_maps_get_brighter() {
        let luma = |c: [u8; 3]| 0.3 * c[0] as f64 + 0.59 * c[1] as f64 + 0.11 * c[2] as f64;
        for c in [Colormap::Viridis, Colormap::Inferno, Colormap::Cividis] {
            let mut last = -1.0;
            for i in 0..=20 {
                let l = luma(c.sample(i as f64 / 20.0));
                assert!(l > last - 1.0, "{c} not monotone at {i}");
                last = l;
            }
        }
    }
}
