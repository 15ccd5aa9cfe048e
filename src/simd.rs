//! Run-time choice of the vector instruction set for the hot loops.
//!
//! The hot loops are written once, as plain loops over `f32` slices that the compiler
//! vectorises. Each is compiled three times on x86-64: for the baseline (SSE2, 4 lanes), for
//! AVX2 (8 lanes) and for AVX-512 (16 lanes), and [`isa`] picks the widest the CPU has. A wheel
//! built here therefore runs on any x86-64 machine and still uses what this one offers.
//!
//! The three builds give bitwise identical results: Rust never contracts `a * b + c` into a
//! fused multiply-add, and vectorising these loops does not reorder any sum, so every lane
//! performs the same correctly rounded operations as the scalar code.
//!
//! `RUSTCLOTH_SIMD=baseline|avx2|avx512` forces a choice (never beyond what the CPU has), for
//! tests and for measuring what the wide units buy.
//!
//! A loop can also be run on a narrower set than [`isa`] (`dispatch!(@isa isa, body)`, any set
//! the CPU has, [`has`]), so that a test compares every build in one process.

use std::sync::OnceLock;

/// The instruction sets, narrowest first: a CPU with one has every narrower one (the AVX-512
/// build is compiled with AVX2 enabled too).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Isa {
    Baseline,
    Avx2,
    Avx512,
}

/// The instruction set the hot loops use in this process.
pub fn isa() -> Isa {
    static CHOICE: OnceLock<Isa> = OnceLock::new();
    *CHOICE.get_or_init(|| {
        let best = detect();
        match std::env::var("RUSTCLOTH_SIMD").as_deref() {
            Ok("baseline") => Isa::Baseline,
            Ok("avx2") if best != Isa::Baseline => Isa::Avx2,
            _ => best,
        }
    })
}

impl Isa {
    /// Its name, as `RUSTCLOTH_SIMD` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }
}

/// The widest instruction set this CPU offers.
pub fn best() -> Isa {
    detect()
}

fn detect() -> Isa {
    #[cfg(target_arch = "x86_64")]
    {
        if is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512vl") {
            return Isa::Avx512;
        }
        if is_x86_feature_detected!("avx2") {
            return Isa::Avx2;
        }
    }
    Isa::Baseline
}

/// Calls `$body` (an expression using only `#[inline(always)]` code, so that it is compiled
/// inside the wrapper) from a function compiled for the chosen instruction set ([`isa`]), or
/// for the one given first (`dispatch!(@isa isa, body)`), which must be one the CPU has
/// ([`has`]).
macro_rules! dispatch {
    (@isa $isa:expr, $body:expr) => {{
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx512f,avx512vl,avx2")]
            unsafe fn avx512<R>(f: impl FnOnce() -> R) -> R {
                f()
            }
            #[target_feature(enable = "avx2")]
            unsafe fn avx2<R>(f: impl FnOnce() -> R) -> R {
                f()
            }
            let isa: $crate::simd::Isa = $isa;
            match isa {
                // SAFETY: the caller gives an instruction set the CPU has (above).
                $crate::simd::Isa::Avx512 => unsafe {
                    avx512(
                        #[inline(always)]
                        || $body,
                    )
                },
                $crate::simd::Isa::Avx2 => unsafe {
                    avx2(
                        #[inline(always)]
                        || $body,
                    )
                },
                $crate::simd::Isa::Baseline => $body,
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _: $crate::simd::Isa = $isa;
            $body
        }
    }};
    ($body:expr) => {
        $crate::simd::dispatch!(@isa $crate::simd::isa(), $body)
    };
}
pub(crate) use dispatch;

/// Whether this CPU has `isa` (whatever `RUSTCLOTH_SIMD` asks for).
pub fn has(isa: Isa) -> bool {
    isa <= detect()
}
