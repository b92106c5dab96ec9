//! Runtime selection of the instruction set the batched kernels are compiled for.
//!
//! The default build targets baseline x86-64 (SSE2), so code that is only compiled once never
//! uses the AVX2 or AVX-512 units of the machine it runs on. [`Isa::run`] runs a closure
//! compiled (through `pulp`'s `vectorize`, which wraps it in a `#[target_feature]` function)
//! for the instruction set picked at run time; everything the closure inlines (the batched
//! [`Lanes`](crate::math::Lanes) arithmetic is `#[inline(always)]`) is vectorised for that set.
//!
//! **The results do not depend on the instruction set.** The batched arithmetic is lane-wise
//! IEEE addition, subtraction, multiplication, division and square root, which every set
//! rounds identically; Rust never contracts a multiply and an add into a fused multiply-add
//! unless asked to, so enabling FMA changes nothing; and the one transcendental function of
//! the kernels, the logarithm, is the crate's own ([`math::ln`](crate::math::ln)), written in
//! those operations instead of calling the C library (whose `log` differs between machines
//! and between native and WebAssembly builds). Tests run the kernels under every set the
//! machine has and compare the bits.
//!
//! Selection: [`Isa::detected`] is the widest set the CPU supports (AVX-512 > AVX2 + FMA >
//! baseline on x86-64; baseline elsewhere), capped by the environment variable `FEM2D_SIMD`
//! (`baseline`, `avx2` or `avx512`) when it is set, so a benchmark can compare the sets on one
//! machine.

use std::sync::OnceLock;

/// An instruction set the batched kernels can be compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[non_exhaustive]
pub enum Isa {
    /// What the build targets (SSE2 on x86-64; every other architecture).
    Baseline,
    /// x86-64-v3: AVX, AVX2, FMA, BMI1/2, F16C, LZCNT, MOVBE.
    Avx2,
    /// x86-64-v4: x86-64-v3 plus AVX-512 F, BW, CD, DQ and VL.
    Avx512,
}

impl Isa {
    /// Every instruction set, narrowest first.
    pub const ALL: [Isa; 3] = [Isa::Baseline, Isa::Avx2, Isa::Avx512];

    /// The name used by `FEM2D_SIMD` and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// Whether this machine can run code compiled for this set.
    pub fn is_supported(self) -> bool {
        match self {
            Isa::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => pulp::x86::V3::try_new().is_some(),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => pulp::x86::V4::try_new().is_some(),
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// Every set this machine supports, narrowest first.
    pub fn supported() -> Vec<Isa> {
        Isa::ALL.into_iter().filter(|i| i.is_supported()).collect()
    }

    /// The widest supported set, capped by `FEM2D_SIMD` when that names a set (an unknown
    /// value is ignored here and reported by [`Isa::from_env`]). Detected once per process.
    pub fn detected() -> Isa {
        static DETECTED: OnceLock<Isa> = OnceLock::new();
        *DETECTED.get_or_init(|| {
            let widest = Isa::supported().into_iter().max().unwrap_or(Isa::Baseline);
            match Isa::from_env() {
                Ok(Some(cap)) => widest.min(cap),
                _ => widest,
            }
        })
    }

    /// The cap named by `FEM2D_SIMD`: `Ok(None)` when unset, an error naming the variable and
    /// the value when it names no set.
    pub fn from_env() -> Result<Option<Isa>, String> {
        match std::env::var("FEM2D_SIMD") {
            Ok(v) => v.parse().map(Some),
            Err(_) => Ok(None),
        }
    }

    /// Run `f` compiled for this set, or for the widest supported set below it. `f` must be
    /// `#[inline(always)]` all the way down for the vectorisation to reach its loops.
    #[inline(always)]
    pub fn run<R>(self, f: impl FnOnce() -> R) -> R {
        #[cfg(target_arch = "x86_64")]
        {
            if self >= Isa::Avx512
                && let Some(simd) = pulp::x86::V4::try_new()
            {
                return simd.vectorize(f);
            }
            if self >= Isa::Avx2
                && let Some(simd) = pulp::x86::V3::try_new()
            {
                return simd.vectorize(f);
            }
        }
        f()
    }
}

impl std::fmt::Display for Isa {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Isa {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Isa::ALL.into_iter().find(|i| i.name() == s).ok_or_else(|| {
            format!("FEM2D_SIMD = `{s}` names no instruction set (baseline, avx2, avx512)")
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_baseline_is_always_supported() {
        for i in Isa::ALL {
            assert_eq!(i.name().parse::<Isa>().unwrap(), i);
        }
        assert!("sse9".parse::<Isa>().unwrap_err().contains("`sse9`"));
        assert!(Isa::Baseline.is_supported());
        assert!(Isa::supported().contains(&Isa::detected()));
        // Running under a set returns the closure's value whatever the machine has.
        for i in Isa::ALL {
            assert_eq!(i.run(|| 6 * 7), 42);
        }
    }
}
