//! A finite-difference oracle for derivatives: central differences over a sweep of step sizes,
//! judged on the best step.
//!
//! Central differences have truncation error `O(h^2)` and round-off error `O(eps / h)`, so no
//! single `h` suits every function; sweeping `h` over several decades and keeping the smallest
//! error finds the sweet spot (near `h = 1e-5` relative for smooth f64 functions, where the
//! error is around `1e-10` relative). Tests compare that best error with a tolerance they state.
//! The oracle is public so users who add an energy can check it the same way.

use crate::math::Real;

/// Step sizes and error floor of a finite-difference check.
#[derive(Clone, Debug, PartialEq)]
pub struct FdOptions {
    /// Steps tried, relative to `max(1, |x|_inf)`. Default: `1e-2, 1e-3, ..., 1e-8`.
    pub steps: Vec<Real>,
    /// Absolute floor of the error's denominator, so derivatives that should be zero are
    /// judged on an absolute scale. Default `1e-8`.
    pub floor: Real,
}

impl Default for FdOptions {
    fn default() -> Self {
        FdOptions {
            steps: (2..=8).map(|k| 10f64.powi(-k)).collect(),
            floor: 1e-8,
        }
    }
}

/// The outcome of a check: the best relative error and the step that gave it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FdReport {
    /// `|analytic - fd| / max(|analytic|, |fd|, floor)` at the best step (Euclidean norms).
    pub relative_error: Real,
    /// The step that gave it (absolute).
    pub step: Real,
}

fn relative(a: &[Real], b: &[Real], floor: Real) -> Real {
    let diff = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<Real>()
        .sqrt();
    let na = a.iter().map(|x| x * x).sum::<Real>().sqrt();
    let nb = b.iter().map(|x| x * x).sum::<Real>().sqrt();
    let e = diff / na.max(nb).max(floor);
    if e.is_nan() { Real::INFINITY } else { e }
}

/// Compare `analytic` (the Jacobian of `f` at `x`, row-major, `m x n` with `m = f(x).len()`)
/// with central differences of `f`.
pub fn check_jacobian(
    f: impl Fn(&[Real]) -> Vec<Real>,
    x: &[Real],
    analytic: &[Real],
    opts: &FdOptions,
) -> FdReport {
    let n = x.len();
    let m = f(x).len();
    assert_eq!(analytic.len(), m * n, "analytic Jacobian must be m x n");
    let scale = x.iter().fold(1.0_f64, |s, v| s.max(v.abs()));
    let mut best = FdReport {
        relative_error: Real::INFINITY,
        step: Real::NAN,
    };
    let mut xp = x.to_vec();
    let mut fd = vec![0.0; m * n];
    for &rel in &opts.steps {
        let h = rel * scale;
        for c in 0..n {
            xp[c] = x[c] + h;
            let fp = f(&xp);
            xp[c] = x[c] - h;
            let fm = f(&xp);
            xp[c] = x[c];
            for r in 0..m {
                fd[r * n + c] = (fp[r] - fm[r]) / (2.0 * h);
            }
        }
        let e = relative(analytic, &fd, opts.floor);
        if e < best.relative_error {
            best = FdReport {
                relative_error: e,
                step: h,
            };
        }
    }
    best
}

/// Compare `analytic` (the gradient of the scalar `f` at `x`) with central differences.
pub fn check_gradient(
    f: impl Fn(&[Real]) -> Real,
    x: &[Real],
    analytic: &[Real],
    opts: &FdOptions,
) -> FdReport {
    check_jacobian(|y| vec![f(y)], x, analytic, opts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_a_right_gradient_and_rejects_a_wrong_one() {
        let f = |x: &[Real]| x[0].sin() * x[1] * x[1];
        let x = [0.7, 1.3];
        let g = [0.7f64.cos() * 1.69, 2.0 * 0.7f64.sin() * 1.3];
        let ok = check_gradient(f, &x, &g, &FdOptions::default());
        assert!(ok.relative_error < 1e-9, "{ok:?}");
        let bad = check_gradient(f, &x, &[g[0], g[1] * 1.001], &FdOptions::default());
        assert!(bad.relative_error > 1e-4, "{bad:?}");
    }
}
