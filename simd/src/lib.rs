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
//! [`Threaded`] cuts a wide batch into chunks of [`CHUNK`] lanes and integrates them on
//! rayon's threads, so that a single plan uses every core; each lane keeps its bits (lanes
//! never mix), so the plan keeps its bits too.
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

use rayon::prelude::*;
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

/// Lanes in one chunk of [`Threaded`]: the width the AVX2 build runs best at (8 lanes in
/// one batch were measured no faster than 4 per lane: docs/lanes.md).
pub const CHUNK: usize = 4;

/// [`Native`] on chunks of [`CHUNK`] lanes, integrated on rayon's threads (the current
/// pool's, else the global one: one per core), each chunk's lanes copied out of the batch
/// and back into it in lane order ([`Batch::copy_lane`]). Lanes never mix, so every lane
/// has the bits it has in [`Native`] and in the scalar rollout.
///
/// **Work.** Each chunk does at most `lane_steps` lane-steps and stops after the lane-step
/// in which one of *its* lanes ended (another chunk may go on), so the integration steps
/// done, summed over the chunks and returned, are at most `lane_steps` times the moving
/// lanes, as [`Batch::kernel`] promises. A batch of at most [`CHUNK`] lanes, or of a lane
/// count that is not a multiple of it, runs whole on the calling thread.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Threaded;

impl Engine for Threaded {
    fn run<const N: usize, const K: usize, const L: usize>(
        batch: &mut Batch<N, K, L>,
        task: &Task<N, K>,
        lane_steps: u32,
        hold: [bool; L],
    ) -> u32 {
        if L <= CHUNK || L % CHUNK != 0 {
            return Native::run(batch, task, lane_steps, hold);
        }
        let isa = Isa::native();
        let mut chunks: Vec<(Batch<N, K, CHUNK>, [bool; CHUNK])> = (0..L / CHUNK)
            .map(|c| {
                let mut b = Batch::IDLE;
                let mut h = [false; CHUNK];
                for (j, hj) in h.iter_mut().enumerate() {
                    batch.copy_lane(c * CHUNK + j, &mut b, j);
                    *hj = hold.get(c * CHUNK + j).copied().unwrap_or(true);
                }
                (b, h)
            })
            .collect();
        let moving = chunks.iter().filter(|(b, h)| b.moves(*h)).count();
        let work = if moving > 1 {
            chunks
                .par_iter_mut()
                .map(|(b, h)| isa.run(b, task, lane_steps, *h))
                .sum()
        } else {
            // One chunk at most has a lane to move: no thread is worth waking (a chunk with
            // nothing to move returns at once).
            chunks
                .iter_mut()
                .map(|(b, h)| isa.run(b, task, lane_steps, *h))
                .sum()
        };
        for (c, (b, _)) in chunks.iter().enumerate() {
            for j in 0..CHUNK {
                b.copy_lane(j, batch, c * CHUNK + j);
            }
        }
        work
    }
}
