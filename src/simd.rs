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
//! The widest is not always the fastest: a loop bound by its gathers can run faster on AVX2
//! than on AVX-512 (the mesh cloth's force pass did, by a fifth, on an Ice Lake Xeon;
//! docs/mesh_cloth.md). Such a loop times both ([`Timed`]) and keeps the faster; the bits are
//! the same either way.

use std::sync::OnceLock;
use std::time::Duration;

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

/// Calls a loop's first [`TRIALS`] calls each way before it chooses.
pub const TRIALS: u32 = 4;

/// The instruction set of one hot loop, chosen by timing it. Where [`isa`] is AVX-512 (and
/// `RUSTCLOTH_SIMD` forces nothing), the loop's first `2 TRIALS` calls alternate between
/// AVX-512 and AVX2, each timed by the caller ([`Timed::record`]); from then on it runs on the
/// one whose fastest call was faster (AVX-512 on a tie). Elsewhere it runs on [`isa`] from the
/// start. Every instruction set gives the same bits, so the choice moves only the time: a
/// loop that waits on its gathers may run faster on AVX2's narrower ones. The fastest call,
/// not the sum, so that a call the scheduler interrupted, or the first one's cold caches, do
/// not decide. Kept per loop and per simulation (a copy starts timing again).
#[derive(Clone, Debug)]
pub struct Timed {
    /// The instruction sets tried, in turn; one where there is no choice.
    candidates: &'static [Isa],
    /// Each candidate's fastest call so far.
    fastest: [Duration; 2],
    /// Calls recorded during the trials.
    calls: u32,
}

impl Default for Timed {
    fn default() -> Self {
        let forced = std::env::var_os("RUSTCLOTH_SIMD").is_some();
        Self::among(match isa() {
            Isa::Avx512 if !forced => &[Isa::Avx512, Isa::Avx2],
            Isa::Avx512 => &[Isa::Avx512],
            Isa::Avx2 => &[Isa::Avx2],
            Isa::Baseline => &[Isa::Baseline],
        })
    }
}

impl Timed {
    /// Tries `candidates` (one or two, each one the CPU has) in turn.
    fn among(candidates: &'static [Isa]) -> Self {
        assert!(matches!(candidates.len(), 1 | 2), "one or two candidates");
        Timed {
            candidates,
            fastest: [Duration::MAX; 2],
            calls: 0,
        }
    }

    /// The instruction set the next call runs on.
    pub fn next(&self) -> Isa {
        self.chosen()
            .unwrap_or(self.candidates[self.calls as usize % self.candidates.len()])
    }

    /// Books a call on `isa` (what [`Timed::next`] gave) that took `took`, until every
    /// candidate has had its [`TRIALS`].
    pub fn record(&mut self, isa: Isa, took: Duration) {
        if self.chosen().is_some() {
            return;
        }
        if let Some(k) = self.candidates.iter().position(|&c| c == isa) {
            self.fastest[k] = self.fastest[k].min(took);
            self.calls += 1;
        }
    }

    /// The instruction set chosen, once the trials are over (at once where there is no
    /// choice): the candidate whose fastest call was faster, the first on a tie.
    pub fn chosen(&self) -> Option<Isa> {
        match self.candidates {
            [only] => Some(*only),
            _ if self.calls < TRIALS * self.candidates.len() as u32 => None,
            _ => Some(self.candidates[usize::from(self.fastest[1] < self.fastest[0])]),
        }
    }
}

/// Whether this CPU has `isa` (whatever `RUSTCLOTH_SIMD` asks for).
pub fn has(isa: Isa) -> bool {
    isa <= detect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_timed_loop_alternates_through_its_trials_then_keeps_the_faster() {
        let ms = Duration::from_millis;
        let mut timed = Timed::among(&[Isa::Avx512, Isa::Avx2]);
        // AVX2's calls are faster but for one slow (interrupted) call; AVX-512's first is cold.
        let took = [
            (Isa::Avx512, 9),
            (Isa::Avx2, 30),
            (Isa::Avx512, 5),
            (Isa::Avx2, 4),
        ];
        for call in 0..2 * TRIALS as usize {
            let (isa, ms_taken) = took[call % 4];
            assert_eq!(timed.chosen(), None);
            assert_eq!(timed.next(), isa, "call {call}");
            timed.record(isa, ms(ms_taken));
        }
        assert_eq!(timed.chosen(), Some(Isa::Avx2));
        assert_eq!(timed.next(), Isa::Avx2);
        timed.record(Isa::Avx2, ms(100));
        assert_eq!(timed.next(), Isa::Avx2, "a choice is kept");
    }

    #[test]
    fn a_timed_loop_keeps_the_wider_instruction_set_on_a_tie() {
        let mut timed = Timed::among(&[Isa::Avx512, Isa::Avx2]);
        for _ in 0..2 * TRIALS {
            let isa = timed.next();
            timed.record(isa, Duration::from_micros(7));
        }
        assert_eq!(timed.chosen(), Some(Isa::Avx512));
    }

    #[test]
    fn a_timed_loop_with_one_candidate_runs_on_it_from_the_first_call() {
        let timed = Timed::among(&[Isa::Baseline]);
        assert_eq!(
            (timed.chosen(), timed.next()),
            (Some(Isa::Baseline), Isa::Baseline)
        );
        let default = Timed::default();
        assert!(default.candidates.contains(&isa()));
        if std::env::var_os("RUSTCLOTH_SIMD").is_some() {
            assert_eq!(
                default.chosen(),
                Some(isa()),
                "a forced choice is not timed"
            );
        }
    }
}
