//! Axis ranges and ticks: 1-2-5 steps on linear axes, decades on log axes, and labels without
//! floating-point noise (`0.3`, not `0.30000000000000004`).

use super::Scale;
use crate::{RenderError, Result};

/// One labelled tick of an axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Tick {
    /// The value, in data units.
    pub value: f64,
    /// The label as drawn (`"0.5"`, `"−1.5"`, `"2e−5"`, `"10⁻³"`; negative numbers use the
    /// minus sign U+2212).
    pub label: String,
}

/// The labelled ticks the charts put on an axis showing the data range `[lo, hi]` (in either
/// order). The axis spans from the first to the last tick, so the ticks cover the data:
/// on a linear axis 4 to 8 ticks 1, 2 or 5 x 10^k apart,
/// labelled with the decimals of that step (`−1.5`, `−1.0`, ..., `0.5`); on a log axis the enclosing powers of
/// ten (every n-th one for wide ranges, and 2 and 5 x 10^k when the data spans one decade).
///
/// Errors ([`RenderError::Input`]) when a bound is not finite, or not positive on a log axis.
pub fn axis_ticks(scale: Scale, lo: f64, hi: f64) -> Result<Vec<Tick>> {
    Ok(Axis::new(scale, lo, hi, 8)?.major)
}

/// An axis: its range, labelled ticks and unlabelled minor ticks.
#[derive(Debug, Clone)]
pub(crate) struct Axis {
    pub scale: Scale,
    pub lo: f64,
    pub hi: f64,
    pub major: Vec<Tick>,
    pub minor: Vec<f64>,
}

impl Axis {
    /// The axis for data in `[lo, hi]` with at most `max_ticks` labelled ticks (at least 2).
    pub(crate) fn new(scale: Scale, lo: f64, hi: f64, max_ticks: usize) -> Result<Axis> {
        if !lo.is_finite() || !hi.is_finite() {
            return Err(RenderError::Input(format!(
                "an axis range must be finite, got [{lo}, {hi}]"
            )));
        }
        let (lo, hi) = if lo <= hi { (lo, hi) } else { (hi, lo) };
        let max_ticks = max_ticks.clamp(2, 12);
        match scale {
            Scale::Linear => linear(lo, hi, max_ticks),
            Scale::Log => log(lo, hi, max_ticks),
        }
    }

    /// Where `v` falls along the axis, 0 at `lo` and 1 at `hi`.
    pub(crate) fn frac(&self, v: f64) -> f64 {
        match self.scale {
            Scale::Linear => (v - self.lo) / (self.hi - self.lo),
            Scale::Log => {
                let l = self.lo.log10();
                (v.log10() - l) / (self.hi.log10() - l)
            }
        }
    }
}

/// `m x 10^e` as the nearest double (correctly rounded, so it prints as the short decimal).
fn decimal(m: i64, e: i32) -> f64 {
    format!("{m}e{e}").parse().unwrap_or(f64::NAN)
}

/// Labels for values on one axis: plain decimals with `decimals` digits after the point (the
/// shortest exact ones when `None`), or `2e−5` style when `scientific`. The value is the double nearest a short decimal, so the
/// shortest representation that reads back exactly is that decimal.
fn label(v: f64, scientific: bool, decimals: Option<usize>) -> String {
    let s = if v == 0.0 {
        match decimals {
            Some(d) if !scientific => format!("{:.d$}", 0.0),
            _ => "0".to_string(),
        }
    } else if scientific {
        format!("{v:e}")
    } else if let Some(decimals) = decimals {
        format!("{v:.decimals$}")
    } else {
        format!("{v}")
    };
    s.replace('-', "\u{2212}")
}

fn scientific(values: impl Iterator<Item = f64>) -> bool {
    let max = values.fold(0.0f64, |m, v| m.max(v.abs()));
    max >= 1e6 || (max > 0.0 && max < 1e-3)
}

fn linear(mut lo: f64, mut hi: f64, max_ticks: usize) -> Result<Axis> {
    if hi - lo <= hi.abs().max(lo.abs()) * 1e-9 {
        let d = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        lo -= d;
        hi += d;
    }
    let span = hi - lo;
    if !span.is_finite() {
        return Err(RenderError::Input(format!(
            "the axis range [{lo:e}, {hi:e}] is too wide to draw"
        )));
    }
    let min_ticks = max_ticks.min(4);
    let k0 = span.log10().floor() as i32;
    // (score, m, k, first index, last index); ticks are i * m * 10^k.
    let mut best: Option<(f64, i64, i32, f64, f64)> = None;
    let mut fallback: Option<(i64, i32, f64, f64)> = None;
    for k in (k0 - 3)..=(k0 + 1) {
        for m in [1i64, 2, 5] {
            let step = decimal(m, k);
            let first = (lo / step + 1e-9).floor();
            let last = (hi / step - 1e-9).ceil();
            let n = (last - first) as usize + 1;
            if n < 2 || n > max_ticks {
                continue;
            }
            if fallback.is_none() {
                fallback = Some((m, k, first, last));
            }
            let coverage = span / ((last - first) * step);
            let score = coverage - if n < min_ticks { 0.3 } else { 0.0 };
            if best.is_none_or(|b| score > b.0 + 1e-12) {
                best = Some((score, m, k, first, last));
            }
        }
    }
    let (m, k, first, last) = match (best, fallback) {
        (Some((_, m, k, f, l)), _) => (m, k, f, l),
        (None, Some(f)) => f,
        (None, None) => {
            // Not reached (a step of 10^(k0+1) gives 2 or 3 ticks), but stay sane.
            let step = decimal(1, k0 + 1);
            let first = (lo / step).floor();
            (1, k0 + 1, first, (hi / step).ceil().max(first + 1.0))
        }
    };
    let values: Vec<f64> = ((first as i64)..=(last as i64))
        .map(|i| decimal(i * m, k))
        .collect();
    let sci = scientific(values.iter().copied());
    // The same number of decimals on every label: those of the step.
    let decimals = Some(usize::try_from(-k).unwrap_or(0));
    let major: Vec<Tick> = values
        .iter()
        .map(|&value| Tick {
            value,
            label: label(value, sci, decimals),
        })
        .collect();
    Ok(Axis {
        scale: Scale::Linear,
        lo: values[0],
        hi: values[values.len() - 1],
        major,
        minor: Vec::new(),
    })
}

/// `10⁻³` for `e = -3`.
fn power_of_ten(e: i32) -> String {
    let sup = |c: char| match c {
        '-' => '⁻',
        '0' => '⁰',
        '1' => '¹',
        '2' => '²',
        '3' => '³',
        '4' => '⁴',
        '5' => '⁵',
        '6' => '⁶',
        '7' => '⁷',
        '8' => '⁸',
        _ => '⁹',
    };
    let mut s = String::from("10");
    s.extend(e.to_string().chars().map(sup));
    s
}

fn log(lo: f64, hi: f64, max_ticks: usize) -> Result<Axis> {
    if lo <= 0.0 {
        return Err(RenderError::Input(format!(
            "a log axis needs positive values, got the range [{lo}, {hi}]"
        )));
    }
    let mut e_lo = (lo.log10() + 1e-9).floor() as i32;
    let mut e_hi = (hi.log10() - 1e-9).ceil() as i32;
    if e_hi <= e_lo {
        e_lo = e_lo.min(e_hi) - 1;
        e_hi = e_lo + 2;
    }
    let decades = e_hi - e_lo;
    if decades == 1 {
        // One decade: label 1, 2 and 5 x 10^k, with 3, 4, 6, 7, 8, 9 x 10^k as minor ticks.
        let values = [
            decimal(1, e_lo),
            decimal(2, e_lo),
            decimal(5, e_lo),
            decimal(1, e_hi),
        ];
        let sci = scientific(values.iter().copied());
        return Ok(Axis {
            scale: Scale::Log,
            lo: values[0],
            hi: values[3],
            major: values
                .iter()
                .map(|&value| Tick {
                    value,
                    label: label(value, sci, None),
                })
                .collect(),
            minor: [3, 4, 6, 7, 8, 9].map(|m| decimal(m, e_lo)).to_vec(),
        });
    }
    let stride = (decades + max_ticks as i32 - 2) / (max_ticks as i32 - 1);
    let (e_lo, e_hi) = if stride > 1 {
        (
            e_lo.div_euclid(stride) * stride,
            -((-e_hi).div_euclid(stride)) * stride,
        )
    } else {
        (e_lo, e_hi)
    };
    let major = (e_lo..=e_hi)
        .step_by(stride as usize)
        .map(|e| Tick {
            value: decimal(1, e),
            label: power_of_ten(e),
        })
        .collect();
    let minor = if stride > 1 {
        (e_lo..=e_hi)
            .filter(|e| (e - e_lo) % stride != 0)
            .map(|e| decimal(1, e))
            .collect()
    } else if decades <= 8 {
        (e_lo..e_hi)
            .flat_map(|e| (2..10).map(move |m| decimal(m, e)))
            .collect()
    } else {
        Vec::new()
    };
    Ok(Axis {
        scale: Scale::Log,
        lo: decimal(1, e_lo),
        hi: decimal(1, e_hi),
        major,
        minor,
    })
}
