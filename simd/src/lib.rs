//! # reactionless-simd
//!
//! The lane kernel of `reactionless` ([`reactionless::batch`]) built for the CPU it runs
//! on: on x86-64, the AVX2 build (four `f64` lanes per register) where the CPU has AVX2,
//! else the SSE2 baseline (two per register) that every x86-64 has, chosen at run time;
//! elsewhere the portable build.
//!
//! Every build runs the same source, [`Batch::kernel`], compiled with a different target
//! feature set: each lane performs the scalar rollout's IEEE operations in the scalar
//! order, so every build gives the same bits (`tests/dispatch.rs` forces each one and
//! compares it with the scalar rollout and the portable build). Only `avx2` is enabled,
//! not `fma`: nothing is contracted into a fused multiply-add.
//!
//! This crate holds the one `unsafe` call of the host side: entering the AVX2 build, after
//! `is_x86_feature_detected!("avx2")` has said the CPU runs it. The flight core stays
//! `forbid(unsafe_code)`.
//!
//! ```
//! use reactionless::batch::{Batch, Engine};
//! use reactionless::reference::{ETA_HAT, paper_task};
//! use reactionless_simd::{Isa, Native};
//! let task = paper_task().unwrap();
//! let mut b: Batch<7, 4, 4> = Batch::new(&task);
//! b.load(0, &task, &ETA_HAT, f64::INFINITY).unwrap();
//! while b.running() > 0 {
//!     Native::run(&mut b, &task, u32::MAX, [false; 4]);
//! }
//! println!("ran on {}", Isa::native().name());
//! ```

use reactionless::Task;
use reactionless::batch::{Batch, Engine};
use std::sync::OnceLock;

/// The environment variable that overrides the build [`Native`] runs: `auto` (the
/// default: the widest this CPU runs), `sse2` (the baseline) or `avx2`.
pub const ISA_VARIABLE: &str = "REACTIONLESS_ISA";

/// A build of the lane kernel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Isa {
    /// The target's baseline (SSE2 on x86-64): [`reactionless::batch::Portable`].
    Baseline,
    /// AVX2 (x86-64 only).
    Avx2,
}

impl Isa {
    /// The widest build this CPU runs.
    #[must_use]
    pub fn widest() -> Self {
        if Self::Avx2.available() {
            Self::Avx2
        } else {
            Self::Baseline
        }
    }

    /// The build [`Native`] runs: [`ISA_VARIABLE`] if it names one this CPU runs, else
    /// [`Isa::widest`]. Read once per process.
    #[must_use]
    pub fn native() -> Self {
        static CHOSEN: OnceLock<Isa> = OnceLock::new();
        *CHOSEN.get_or_init(|| match Self::from_env() {
            Ok(Some(isa)) if isa.available() => isa,
            _ => Self::widest(),
        })
    }

    /// The build [`ISA_VARIABLE`] asks for (`None`: unset or `auto`).
    ///
    /// # Errors
    /// A value other than `auto`, `sse2` or `avx2`, or `avx2` on a CPU without it: a
    /// message naming the variable and the value.
    pub fn from_env() -> Result<Option<Self>, String> {
        let Ok(v) = std::env::var(ISA_VARIABLE) else {
            return Ok(None);
        };
        let isa = match v.as_str() {
            "" | "auto" => return Ok(None),
            "sse2" | "baseline" => Self::Baseline,
            "avx2" => Self::Avx2,
            other => {
                return Err(format!(
                    "{ISA_VARIABLE}={other}: expected auto, sse2 or avx2"
                ));
            }
        };
        if isa.available() {
            Ok(Some(isa))
        } else {
            Err(format!(
                "{ISA_VARIABLE}={v}: this CPU does not run {}",
                isa.name()
            ))
        }
    }

    /// Whether this CPU (and OS) runs this build.
    #[must_use]
    pub fn available(self) -> bool {
        match self {
            Self::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(not(target_arch = "x86_64"))]
            Self::Avx2 => false,
        }
    }

    /// Its name in reports: `sse2`, `avx2` (or `baseline` off x86-64).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Baseline if cfg!(target_arch = "x86_64") => "sse2",
            Self::Baseline => "baseline",
            Self::Avx2 => "avx2",
        }
    }

    /// Runs [`Batch::kernel`] in this build (the baseline if this CPU does not run it).
    pub fn run<const N: usize, const K: usize, const L: usize>(
        self,
        batch: &mut Batch<N, K, L>,
        task: &Task<N, K>,
        lane_steps: u32,
        hold: [bool; L],
    ) -> u32 {
        match self {
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 if self.available() => x86::avx2(batch, task, lane_steps, hold),
            _ => baseline(batch, task, lane_steps, hold),
        }
    }
}

/// The kernel as the crate is built (the target's baseline).
#[inline(never)]
fn baseline<const N: usize, const K: usize, const L: usize>(
    batch: &mut Batch<N, K, L>,
    task: &Task<N, K>,
    lane_steps: u32,
    hold: [bool; L],
) -> u32 {
    batch.kernel(task, lane_steps, hold)
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{Batch, Task};

    /// [`Batch::kernel`] compiled with AVX2 (it is `#[inline(always)]` all the way down,
    /// so all of it is compiled here).
    #[target_feature(enable = "avx2")]
    fn avx2_build<const N: usize, const K: usize, const L: usize>(
        batch: &mut Batch<N, K, L>,
        task: &Task<N, K>,
        lane_steps: u32,
        hold: [bool; L],
    ) -> u32 {
        batch.kernel(task, lane_steps, hold)
    }

    /// The AVX2 build; the caller has checked that the CPU runs AVX2.
    pub(super) fn avx2<const N: usize, const K: usize, const L: usize>(
        batch: &mut Batch<N, K, L>,
        task: &Task<N, K>,
        lane_steps: u32,
        hold: [bool; L],
    ) -> u32 {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return super::baseline(batch, task, lane_steps, hold);
        }
        #[allow(unsafe_code)]
        // SAFETY: `avx2_build` requires only the `avx2` target feature, which the CPU was
        // found to have (and the OS to save) just above.
        unsafe {
            avx2_build(batch, task, lane_steps, hold)
        }
    }
}

/// The widest build this CPU runs, chosen at run time, or the one [`ISA_VARIABLE`] names
/// ([`Isa::native`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Native;

impl Engine for Native {
    fn run<const N: usize, const K: usize, const L: usize>(
        batch: &mut Batch<N, K, L>,
        task: &Task<N, K>,
        lane_steps: u32,
        hold: [bool; L],
    ) -> u32 {
        Isa::native().run(batch, task, lane_steps, hold)
    }
}

/// Always the baseline build (SSE2 on x86-64), for tests and comparisons.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ForceBaseline;

impl Engine for ForceBaseline {
    fn run<const N: usize, const K: usize, const L: usize>(
        batch: &mut Batch<N, K, L>,
        task: &Task<N, K>,
        lane_steps: u32,
        hold: [bool; L],
    ) -> u32 {
        Isa::Baseline.run(batch, task, lane_steps, hold)
    }
}

/// Always the AVX2 build (the baseline on a CPU without AVX2: check
/// `Isa::Avx2.available()`), for tests and comparisons.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ForceAvx2;

impl Engine for ForceAvx2 {
    fn run<const N: usize, const K: usize, const L: usize>(
        batch: &mut Batch<N, K, L>,
        task: &Task<N, K>,
        lane_steps: u32,
        hold: [bool; L],
    ) -> u32 {
        Isa::Avx2.run(batch, task, lane_steps, hold)
    }
}
