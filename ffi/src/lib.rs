//! # reactionless-ffi
//!
//! The C ABI of the reactionless planner, for flight software written in C or C++ (cFS
//! apps, F Prime components, RTEMS or FreeRTOS tasks). One monomorphised planner, the
//! flight image's: `N = 7` joints, `K = 4`, a swarm capacity of `P = 64`.
//!
//! Owns the exported `rl_*` functions, the C types they take ([`rl_planner`],
//! [`rl_setpoints`], [`rl_plan`], [`rl_setpoint`]), the status codes, and the checkpoint
//! format ([`checkpoint`], also the Rust API for checkpoint and restore); the two-phase
//! search's type and functions are in [`two_phase`] ([`rl_two_phase`]), the closed-loop
//! flight of a finished plan in [`closed_loop`] ([`rl_loop`]). The header
//! `ffi/include/reactionless.h` is generated from these files by cbindgen and checked in
//! (`scripts/check-header.sh`; `BLESS=1` to accept a change).
//!
//! The contract, as zlib's `deflateInit_`: the caller passes its header's
//! [`RL_ABI_VERSION`] and `sizeof(rl_planner)` to [`rl_planner_init`], so a header that does
//! not match the library fails loudly. Storage is the caller's (static app data): the
//! planner and the setpoint stream are complete C types, nothing is allocated. Every
//! function checks its pointers for NULL and its objects for the right state (a planner
//! not initialised, stepped with no task, streamed before a plan) and returns a negative
//! [`rl_status`] naming what was wrong; none panics or aborts. On the thumb target the
//! staticlib's panic handler calls a symbol that exists nowhere, so an archive with a
//! panic path left shows it in `nm -u` and does not link (`scripts/c-abi-m7.sh`).
//!
//! `unsafe` is denied crate-wide and allowed only on the exports (raw pointers from C),
//! the two storage accessors of [`rl_planner`] and [`rl_setpoints`], and the byte copies
//! of [`checkpoint`]; each unsafe block says why it holds. The core stays
//! `unsafe_code = "forbid"`.
//!
//! Not thread-safe: one planner, one caller at a time (as every cFS app's static data).
//!
//! Verifies RL-FFI-001.
//!
//! ```
//! use reactionless_ffi::*;
//! let mut p = Box::new(rl_planner::ZEROED);
//! // SAFETY: `p` is a valid, exclusive rl_planner.
//! let s = unsafe { rl_planner_init(&mut *p, RL_ABI_VERSION, core::mem::size_of::<rl_planner>()) };
//! assert_eq!(s, RL_OK);
//! let mut plan = rl_plan::ZEROED;
//! assert_eq!(unsafe { rl_planner_step(&mut *p, 100, &mut plan) }, RL_E_NO_TASK);
//! assert_eq!(unsafe { rl_planner_step(core::ptr::null_mut(), 100, &mut plan) }, RL_E_NULL);
//! ```
#![no_std]
#![allow(non_camel_case_types)]

// The host staticlib and the tests take std's panic handler (and nothing else from std).
#[cfg(not(target_os = "none"))]
extern crate std;

pub mod checkpoint;
pub mod closed_loop;
pub mod two_phase;

pub use closed_loop::{
    FlightLoop, RL_E_LOOP_SETTING, RL_LOOP_WORDS, rl_loop, rl_loop_command, rl_loop_config,
    rl_loop_config_default, rl_loop_fault_str, rl_loop_init, rl_loop_step, rl_measurement,
};

pub use two_phase::{
    FlightTwoPhase, RL_TWO_PHASE_CHECKPOINT_CAPACITY, RL_TWO_PHASE_WORDS, rl_two_phase,
    rl_two_phase_checkpoint, rl_two_phase_checkpoint_size, rl_two_phase_init,
    rl_two_phase_load_block, rl_two_phase_plan, rl_two_phase_restore, rl_two_phase_setpoints_init,
    rl_two_phase_setpoints_next, rl_two_phase_step,
};

use core::ffi::c_char;
use core::mem::{align_of, size_of};
use reactionless::block::decode;
use reactionless::{BlockFault, Error, Plan, Planner, Setpoints, Status, Stop, eta_flat};

/// The flight planner: 7 joints, null-space dimension 4, swarm capacity 64.
pub type FlightPlanner = Planner<7, 4, 64>;
/// The flight setpoint stream.
pub type FlightSetpoints = Setpoints<7, 4>;

/// Version of this ABI: the layout of every `rl_*` type and the meaning of every function.
pub const RL_ABI_VERSION: u32 = 8;
/// Joints of the flight robot (N).
pub const RL_JOINTS: usize = 7;
/// Entries of one segment's η: 2K with K = N − 3, as `a1, b1, a2, b2, …`.
pub const RL_ETA_LEN: usize = 8;
/// Most segments of a motion (`[motion] segments`).
pub const RL_MAX_SEGMENTS: usize = 4;
/// Entries of a plan's η ([`rl_plan`]): `RL_ETA_LEN * RL_MAX_SEGMENTS`, one segment's after
/// the other.
pub const RL_PLAN_ETA_LEN: usize = 32;
/// Words (u64) of planner storage inside [`rl_planner`]: room for the planner on every
/// target, with headroom so that a small growth of the core keeps the ABI.
pub const RL_PLANNER_WORDS: usize = 5120;
/// Words (u64) of stream storage inside [`rl_setpoints`].
pub const RL_SETPOINTS_WORDS: usize = 384;
/// Bytes that always hold a checkpoint of this ABI version (`rl_checkpoint_size()` is at
/// most this), for sizing a static buffer or a CDS block at compile time.
pub const RL_CHECKPOINT_CAPACITY: usize = RL_PLANNER_WORDS * 8 + 64;

/// A status: `RL_OK`, `RL_RUNNING`, `RL_CONVERGED`, `RL_EXHAUSTED`, `RL_STALLED`, `RL_DONE`,
/// `RL_BEYOND_REACH`, `RL_PRESHAPE_BOUNDS`, or an error (every error is negative).
/// [`rl_status_str`] names each.
pub type rl_status = i32;

/// Success.
pub const RL_OK: rl_status = 0;
/// The planner spent its budget and has more to do.
pub const RL_RUNNING: rl_status = 1;
/// Planning is over and the plan meets what the block asks for (Φ = 0, f ≤ σ_e and, when
/// the block sets a refinement tolerance, f or `truth_f` within it).
pub const RL_CONVERGED: rl_status = 2;
/// Planning is over, not converged: a budget was spent first. The plan is the best found.
pub const RL_EXHAUSTED: rl_status = 3;
/// The stream has produced its last setpoint.
pub const RL_DONE: rl_status = 4;
/// Planning is over, not converged: the search or its refinement could get no closer (a
/// floor above the asked tolerance). The plan is the best found.
pub const RL_STALLED: rl_status = 5;
/// Two-phase planning is over, not converged: no configuration within the joint limits puts
/// the end effector on the target (decided before any rollout).
pub const RL_BEYOND_REACH: rl_status = 6;
/// Two-phase planning is over, not converged: plans reached the target, but none whose
/// phase 1 the attitude control can serve within the longest phase 1.
pub const RL_PRESHAPE_BOUNDS: rl_status = 7;

/// A pointer argument is NULL.
pub const RL_E_NULL: rl_status = -1;
/// `rl_planner_init` was given another ABI version than the library's.
pub const RL_E_ABI_VERSION: rl_status = -2;
/// `rl_planner_init` was given another `sizeof(rl_planner)` than the library's.
pub const RL_E_SIZE: rl_status = -3;
/// The object was not initialised (`rl_planner_init`, `rl_setpoints_init`).
pub const RL_E_UNINITIALIZED: rl_status = -4;
/// The planner has no task: load a block first.
pub const RL_E_NO_TASK: rl_status = -5;
/// The planner has no finished plan to stream yet.
pub const RL_E_NO_PLAN: rl_status = -6;
/// Task block: wrong magic bytes.
pub const RL_E_BLOCK_MAGIC: rl_status = -7;
/// Task block: built for another joint count.
pub const RL_E_BLOCK_JOINTS: rl_status = -8;
/// Task block: wrong or short length.
pub const RL_E_BLOCK_LENGTH: rl_status = -9;
/// Task block: CRC-32 mismatch.
pub const RL_E_BLOCK_CRC: rl_status = -10;
/// Task block: a field outside its encoding.
pub const RL_E_BLOCK_FIELD: rl_status = -11;
/// Task block: a value the planner rejects (robot, start, target, motion or settings).
pub const RL_E_INVALID_TASK: rl_status = -12;
/// Planning failed: no rollout at all could be evaluated.
pub const RL_E_PLANNING: rl_status = -13;
/// An output buffer is too small.
pub const RL_E_BUFFER: rl_status = -14;
/// Checkpoint: wrong length.
pub const RL_E_CKPT_LENGTH: rl_status = -15;
/// Checkpoint: wrong magic bytes.
pub const RL_E_CKPT_MAGIC: rl_status = -16;
/// Checkpoint: another format or ABI version.
pub const RL_E_CKPT_VERSION: rl_status = -17;
/// Checkpoint: written by another build.
pub const RL_E_CKPT_LAYOUT: rl_status = -18;
/// Checkpoint: CRC-32 mismatch.
pub const RL_E_CKPT_CRC: rl_status = -19;
/// Checkpoint: of another task than the one loaded.
pub const RL_E_CKPT_TASK: rl_status = -20;
/// The setpoint stream belongs to another task than the planner's.
pub const RL_E_MISMATCH: rl_status = -21;
/// Streaming failed (the rollout lost rank or went non-finite).
pub const RL_E_STREAM: rl_status = -22;
/// The block asks for a two-phase plan (magic `RLTASK04` or `RLTASK05`, a task with
/// `[preshape]`): `rl_planner` plans single-phase tasks only; load it into an
/// `rl_two_phase`.
pub const RL_E_TWO_PHASE: rl_status = -23;
/// The block is single-phase: `rl_two_phase` plans two-phase blocks only; load it into an
/// `rl_planner`.
pub const RL_E_ONE_PHASE: rl_status = -24;
/// A phase number other than 1 or 2 (`rl_two_phase_setpoints_init`).
pub const RL_E_PHASE: rl_status = -25;

const PLANNER_MAGIC: u32 = 0x524c_504e; // "RLPN"
const SETPOINTS_MAGIC: u32 = 0x524c_5350; // "RLSP"

// The storage holds the state on every target, aligned (u64 words: 8 on x86-64 and on the
// Cortex-M7's AAPCS).
const _: () = assert!(size_of::<FlightPlanner>() <= RL_PLANNER_WORDS * 8);
const _: () = assert!(align_of::<FlightPlanner>() <= align_of::<u64>());
const _: () = assert!(size_of::<FlightSetpoints>() <= RL_SETPOINTS_WORDS * 8);
const _: () = assert!(align_of::<FlightSetpoints>() <= align_of::<u64>());
const _: () = assert!(RL_ETA_LEN == 2 * (RL_JOINTS - 3));
const _: () = assert!(RL_PLAN_ETA_LEN == RL_ETA_LEN * RL_MAX_SEGMENTS);
const _: () = assert!(RL_MAX_SEGMENTS == reactionless::MAX_SEGMENTS);
const _: () = assert!(checkpoint::LEN <= RL_CHECKPOINT_CAPACITY);

/// A planner in caller-owned storage (static app data). Initialise with
/// `rl_planner_init`; the members are private to the library.
#[repr(C)]
pub struct rl_planner {
    /// Set by `rl_planner_init`.
    magic: u32,
    /// 1 once a task is loaded (`rl_planner_load_block`, `rl_planner_restore`).
    loaded: u32,
    /// Digest of the loaded task block (FNV-1a-64).
    task: u64,
    /// The planner itself.
    storage: [u64; RL_PLANNER_WORDS],
}

/// A setpoint stream in caller-owned storage. Initialise with `rl_setpoints_init`; the
/// members are private to the library.
#[repr(C)]
pub struct rl_setpoints {
    /// Set by `rl_setpoints_init`.
    magic: u32,
    /// 1 once the last setpoint was produced.
    done: u32,
    /// Digest of the task block of the planner it streams.
    task: u64,
    /// The stream itself.
    storage: [u64; RL_SETPOINTS_WORDS],
}

/// A finished plan (filled by `rl_planner_step` on `RL_CONVERGED`, `RL_EXHAUSTED` or `RL_STALLED`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct rl_plan {
    /// η: `a1, b1, a2, b2, …` of each segment in turn (`RL_ETA_LEN * segments` entries;
    /// the rest are 0).
    pub eta: [f64; RL_PLAN_ETA_LEN],
    /// Segments of the motion (1 unless the task block asks for more).
    pub segments: u32,
    /// Pose error norm `f` of the plan's rollout (m and rad mixed, as in the paper).
    pub f: f64,
    /// Constraint violation Φ (rad); 0 when every joint limit holds.
    pub phi: f64,
    /// Multistart: accepted LM steps; C-PSO: generations after the first.
    pub iterations: u32,
    /// Rollouts, search and refinement.
    pub rollouts: u32,
    /// Rollouts spent by the search.
    pub search_rollouts: u32,
    /// Rollouts stopped early by their violation cap.
    pub abandoned: u32,
    /// C-PSO stagnation alarms (0 for the multistart).
    pub stagnation_events: u32,
    /// Multistart restarts (0 for C-PSO).
    pub restarts: u32,
    /// 1 if the plan met its tolerance (`RL_CONVERGED`), else 0.
    pub converged: u32,
    /// 0 multistart, 1 C-PSO.
    pub strategy: u32,
    /// End-effector position at `t_f` (m, inertial frame).
    pub end_position: [f64; 3],
    /// End-effector attitude at `t_f`, quaternion `w, x, y, z`.
    pub end_quat_wxyz: [f64; 4],
}

/// One setpoint: time, joint positions, joint rates (as `TrajectoryDigest` folds them).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct rl_setpoint {
    /// Time (s), from 0 to `t_f`.
    pub t: f64,
    /// Joint positions (rad).
    pub q: [f64; RL_JOINTS],
    /// Joint rates (rad/s).
    pub qd: [f64; RL_JOINTS],
}

impl rl_plan {
    /// All zero.
    pub const ZEROED: Self = Self {
        eta: [0.0; RL_PLAN_ETA_LEN],
        segments: 0,
        f: 0.0,
        phi: 0.0,
        iterations: 0,
        rollouts: 0,
        search_rollouts: 0,
        abandoned: 0,
        stagnation_events: 0,
        restarts: 0,
        converged: 0,
        strategy: 0,
        end_position: [0.0; 3],
        end_quat_wxyz: [0.0; 4],
    };

    fn of(p: &Plan<7, 4>, segments: u32) -> Self {
        let mut eta = [0.0; RL_PLAN_ETA_LEN];
        for (d, s) in eta.iter_mut().zip(eta_flat(&p.eta, segments)) {
            *d = s;
        }
        Self {
            eta,
            segments,
            f: p.outcome.f,
            phi: p.outcome.phi,
            iterations: p.iterations,
            rollouts: p.rollouts,
            search_rollouts: p.search_rollouts,
            abandoned: p.abandoned,
            stagnation_events: p.stagnation_events,
            restarts: p.restarts,
            converged: u32::from(p.converged()),
            strategy: p.strategy.code(),
            end_position: p.outcome.end_pose.position,
            end_quat_wxyz: p.outcome.end_pose.quat_wxyz,
        }
    }
}

impl rl_setpoint {
    /// All zero.
    pub const ZEROED: Self = Self {
        t: 0.0,
        q: [0.0; RL_JOINTS],
        qd: [0.0; RL_JOINTS],
    };
}

impl rl_planner {
    /// All zero: not initialised (for Rust callers that need a value to box).
    pub const ZEROED: Self = Self {
        magic: 0,
        loaded: 0,
        task: 0,
        storage: [0; RL_PLANNER_WORDS],
    };

    /// The planner, if `rl_planner_init` has run on this storage.
    #[allow(unsafe_code)]
    fn planner(&self) -> Option<&FlightPlanner> {
        (self.magic == PLANNER_MAGIC).then(|| {
            // SAFETY: the magic is written only by rl_planner_init, right after it wrote a
            // FlightPlanner into `storage` (size and alignment asserted above); from then
            // on `storage` is only written as that planner.
            unsafe { &*self.storage.as_ptr().cast::<FlightPlanner>() }
        })
    }

    /// The planner, mutably, if `rl_planner_init` has run on this storage.
    #[allow(unsafe_code)]
    fn planner_mut(&mut self) -> Option<&mut FlightPlanner> {
        (self.magic == PLANNER_MAGIC).then(|| {
            // SAFETY: as in `planner`; `&mut self` makes the borrow exclusive.
            unsafe { &mut *self.storage.as_mut_ptr().cast::<FlightPlanner>() }
        })
    }

    fn load(&mut self, block: &[u8]) -> rl_status {
        if self.magic != PLANNER_MAGIC {
            return RL_E_UNINITIALIZED;
        }
        self.loaded = 0;
        let decoded = match decode::<7>(block) {
            Ok(b) => b,
            Err(e) => return load_error(e),
        };
        if decoded.two_phase.is_some() {
            return RL_E_TWO_PHASE;
        }
        let Some(planner) = self.planner_mut() else {
            return RL_E_UNINITIALIZED;
        };
        if let Err(e) = decoded.load_into(planner) {
            return load_error(e);
        }
        self.task = checkpoint::task_digest(block);
        self.loaded = 1;
        RL_OK
    }

    fn step(&mut self, budget: u32, plan: &mut rl_plan) -> rl_status {
        let loaded = self.loaded == 1;
        let Some(planner) = self.planner_mut() else {
            return RL_E_UNINITIALIZED;
        };
        if !loaded {
            return RL_E_NO_TASK;
        }
        match planner.step(budget, &mut ()) {
            Ok(Status::Running(_)) => RL_RUNNING,
            Ok(Status::Finished(p)) => {
                *plan = rl_plan::of(&p, planner.task().motion().segments());
                match p.stop {
                    Stop::Converged => RL_CONVERGED,
                    Stop::Exhausted => RL_EXHAUSTED,
                    Stop::Stalled => RL_STALLED,
                }
            }
            Err(Error::NotInitialized) => RL_E_NO_TASK,
            Err(_) => RL_E_PLANNING,
        }
    }

    /// The loaded planner, or the status saying why there is none.
    fn loaded(&self) -> Result<&FlightPlanner, rl_status> {
        match (self.planner(), self.loaded) {
            (None, _) => Err(RL_E_UNINITIALIZED),
            (Some(_), l) if l != 1 => Err(RL_E_NO_TASK),
            (Some(p), _) => Ok(p),
        }
    }

    fn checkpoint(&self, buf: &mut [u8]) -> rl_status {
        let planner = match self.loaded() {
            Ok(p) => p,
            Err(s) => return s,
        };
        match checkpoint::write(planner, self.task, buf) {
            Ok(_) => RL_OK,
            Err(f) => fault_status(f),
        }
    }

    #[allow(unsafe_code)]
    fn restore(&mut self, buf: &[u8]) -> rl_status {
        let expected = (self.loaded == 1).then_some(self.task);
        let Some(planner) = self.planner_mut() else {
            return RL_E_UNINITIALIZED;
        };
        // SAFETY: the C contract of rl_planner_restore: `buf` holds a checkpoint written
        // by rl_planner_checkpoint of this build; header and CRC are checked first.
        match unsafe { checkpoint::restore(planner, expected, buf) } {
            Ok(task) => {
                self.task = task;
                self.loaded = 1;
                RL_OK
            }
            Err(f) => fault_status(f),
        }
    }
}

impl rl_setpoints {
    /// All zero: not initialised (for Rust callers that need a value to box).
    pub const ZEROED: Self = Self {
        magic: 0,
        done: 0,
        task: 0,
        storage: [0; RL_SETPOINTS_WORDS],
    };

    /// The stream, if `rl_setpoints_init` has run on this storage.
    #[allow(unsafe_code)]
    fn stream_mut(&mut self) -> Option<&mut FlightSetpoints> {
        (self.magic == SETPOINTS_MAGIC).then(|| {
            // SAFETY: the magic is written only by rl_setpoints_init, right after it wrote a
            // FlightSetpoints into `storage` (size and alignment asserted above).
            unsafe { &mut *self.storage.as_mut_ptr().cast::<FlightSetpoints>() }
        })
    }

    fn next(&mut self, p: &rl_planner, out: &mut rl_setpoint) -> rl_status {
        if self.magic == two_phase::PHASE1_MAGIC || self.magic == two_phase::PHASE2_MAGIC {
            // A two-phase stream: rl_two_phase_setpoints_next.
            return RL_E_MISMATCH;
        }
        let (task, done) = (self.task, self.done == 1);
        let Some(stream) = self.stream_mut() else {
            return RL_E_UNINITIALIZED;
        };
        let planner = match p.loaded() {
            Ok(pl) => pl,
            Err(s) => return s,
        };
        if p.task != task {
            return RL_E_MISMATCH;
        }
        if done {
            return RL_DONE;
        }
        match stream.next(planner.task()) {
            Ok(Some(s)) => {
                *out = rl_setpoint {
                    t: s.t,
                    q: s.q,
                    qd: s.qd,
                };
                RL_OK
            }
            Ok(None) => {
                self.done = 1;
                RL_DONE
            }
            Err(_) => RL_E_STREAM,
        }
    }
}

/// The status of a task block that did not load.
pub(crate) fn load_error(e: Error) -> rl_status {
    match e {
        Error::NotTwoPhase => RL_E_ONE_PHASE,
        Error::Block(BlockFault::Magic) => RL_E_BLOCK_MAGIC,
        Error::Block(BlockFault::JointCount) => RL_E_BLOCK_JOINTS,
        Error::Block(BlockFault::Length | BlockFault::Truncated) => RL_E_BLOCK_LENGTH,
        Error::Block(BlockFault::Checksum) => RL_E_BLOCK_CRC,
        Error::Block(BlockFault::Field) => RL_E_BLOCK_FIELD,
        _ => RL_E_INVALID_TASK,
    }
}

pub(crate) fn fault_status(f: checkpoint::Fault) -> rl_status {
    use checkpoint::Fault;
    match f {
        Fault::Buffer => RL_E_BUFFER,
        Fault::Length => RL_E_CKPT_LENGTH,
        Fault::Magic => RL_E_CKPT_MAGIC,
        Fault::Version => RL_E_CKPT_VERSION,
        Fault::Layout => RL_E_CKPT_LAYOUT,
        Fault::Checksum => RL_E_CKPT_CRC,
        Fault::Task => RL_E_CKPT_TASK,
    }
}

/// The library's ABI version ([`RL_ABI_VERSION`] of the header it was built with).
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn rl_abi_version() -> u32 {
    RL_ABI_VERSION
}

/// Initialises `p` as an idle planner without a task. `abi_version` and `planner_size`
/// are the caller's `RL_ABI_VERSION` and `sizeof(rl_planner)`: a mismatch with the library
/// is `RL_E_ABI_VERSION` or `RL_E_SIZE`, and `p` is left untouched. Cheap to call again: it
/// forgets the task and the plan.
///
/// # Safety
/// `p` is NULL or points to writable, aligned storage of `sizeof(rl_planner)` bytes that
/// nothing else accesses during the call; it need not be initialised.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_planner_init(
    p: *mut rl_planner,
    abi_version: u32,
    planner_size: usize,
) -> rl_status {
    if p.is_null() {
        return RL_E_NULL;
    }
    if abi_version != RL_ABI_VERSION {
        return RL_E_ABI_VERSION;
    }
    if planner_size != size_of::<rl_planner>() {
        return RL_E_SIZE;
    }
    // SAFETY: `p` is non-NULL and, by the contract, valid for writes of one rl_planner;
    // only writes happen (no read of the possibly uninitialised storage). The planner goes
    // to `storage`, whose size and alignment fit it (asserted at compile time).
    unsafe {
        core::ptr::addr_of_mut!((*p).storage)
            .cast::<FlightPlanner>()
            .write(FlightPlanner::IDLE);
        core::ptr::addr_of_mut!((*p).loaded).write(0);
        core::ptr::addr_of_mut!((*p).task).write(0);
        core::ptr::addr_of_mut!((*p).magic).write(PLANNER_MAGIC);
    }
    RL_OK
}

/// Loads a task block (the bytes `host-sim block TASK --out FILE` writes), validating it
/// as a cFS table: magic, joint count, length and CRC-32, then every value; a two-phase
/// block is refused (`RL_E_TWO_PHASE`: load it into an `rl_two_phase`). On success the planner starts planning from
/// scratch; on failure it has no task (`RL_E_NO_TASK` from `rl_planner_step`) and the
/// status names the fault.
///
/// # Safety
/// `p` is NULL or a planner initialised by `rl_planner_init`, not accessed elsewhere during
/// the call; `block` is NULL or readable for `len` bytes.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_planner_load_block(
    p: *mut rl_planner,
    block: *const u8,
    len: usize,
) -> rl_status {
    if block.is_null() {
        return RL_E_NULL;
    }
    // SAFETY: non-NULL; by the contract `p` is an exclusive rl_planner and `block` is
    // readable for `len` bytes and not written during the call.
    match unsafe { p.as_mut() } {
        Some(p) => p.load(unsafe { core::slice::from_raw_parts(block, len) }),
        None => RL_E_NULL,
    }
}

/// Plans for at most `budget` units of work (integration steps; the task block's frame
/// budget is the intended value, see `rl_planner_frame_budget`). Returns `RL_RUNNING` while
/// there is more to do, then `RL_CONVERGED`, `RL_EXHAUSTED` or `RL_STALLED` with `*plan` filled (and the
/// same again, without work, on every later call). `plan` is untouched while running.
///
/// # Safety
/// `p` is NULL or an initialised planner and `plan` NULL or a writable rl_plan, neither
/// accessed elsewhere during the call.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_planner_step(
    p: *mut rl_planner,
    budget: u32,
    plan: *mut rl_plan,
) -> rl_status {
    // SAFETY: as_mut checks for NULL; the contract makes both references valid and
    // exclusive for the call.
    match unsafe { (p.as_mut(), plan.as_mut()) } {
        (Some(p), Some(plan)) => p.step(budget, plan),
        _ => RL_E_NULL,
    }
}

/// The loaded task's frame budget (integration steps per `rl_planner_step` call, from the
/// task block) in `*budget`.
///
/// # Safety
/// `p` is NULL or an initialised planner; `budget` NULL or writable.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_planner_frame_budget(
    p: *const rl_planner,
    budget: *mut u32,
) -> rl_status {
    // SAFETY: as_ref/as_mut check for NULL; the contract makes the references valid.
    match unsafe { (p.as_ref(), budget.as_mut()) } {
        (Some(p), Some(out)) => match p.loaded() {
            Ok(planner) => {
                *out = planner.config().frame_budget;
                RL_OK
            }
            Err(s) => s,
        },
        _ => RL_E_NULL,
    }
}

/// Starts streaming the setpoints of `p`'s finished plan into `s` (`RL_E_NO_PLAN` before
/// `rl_planner_step` returned `RL_CONVERGED`, `RL_EXHAUSTED` or `RL_STALLED`).
///
/// # Safety
/// `s` is NULL or writable, aligned storage of `sizeof(rl_setpoints)` bytes (it need not be
/// initialised); `p` NULL or an initialised planner; neither accessed elsewhere.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_setpoints_init(
    s: *mut rl_setpoints,
    p: *const rl_planner,
) -> rl_status {
    // SAFETY: as_ref checks for NULL; the contract makes the reference valid.
    let Some(p) = (unsafe { p.as_ref() }) else {
        return RL_E_NULL;
    };
    if s.is_null() {
        return RL_E_NULL;
    }
    let planner = match p.loaded() {
        Ok(pl) => pl,
        Err(st) => return st,
    };
    let Some(plan) = planner.result() else {
        return RL_E_NO_PLAN;
    };
    let Ok(stream) = FlightSetpoints::of(planner.task(), &plan.eta) else {
        return RL_E_STREAM;
    };
    // SAFETY: `s` is non-NULL and, by the contract, valid for writes of one rl_setpoints;
    // only writes happen. The stream fits `storage` (asserted at compile time).
    unsafe {
        core::ptr::addr_of_mut!((*s).storage)
            .cast::<FlightSetpoints>()
            .write(stream);
        core::ptr::addr_of_mut!((*s).done).write(0);
        core::ptr::addr_of_mut!((*s).task).write(p.task);
        core::ptr::addr_of_mut!((*s).magic).write(SETPOINTS_MAGIC);
    }
    RL_OK
}

/// The next setpoint in `*out` (`RL_OK`), for `s = 0 … S`; after the last, `RL_DONE` on
/// every call. Each call does at most one integration step. `p` must be the planner the
/// stream was started from (its task: `RL_E_MISMATCH` otherwise).
///
/// # Safety
/// `s` NULL or a stream initialised by `rl_setpoints_init`; `p` NULL or an initialised
/// planner; `out` NULL or writable; none accessed elsewhere during the call.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_setpoints_next(
    s: *mut rl_setpoints,
    p: *const rl_planner,
    out: *mut rl_setpoint,
) -> rl_status {
    // SAFETY: as_mut/as_ref check for NULL; the contract makes the references valid and
    // `s`, `out` exclusive.
    match unsafe { (s.as_mut(), p.as_ref(), out.as_mut()) } {
        (Some(s), Some(p), Some(out)) => s.next(p, out),
        _ => RL_E_NULL,
    }
}

/// Bytes of a checkpoint (header, planner, CRC).
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn rl_checkpoint_size() -> usize {
    checkpoint::LEN
}

/// Writes the whole planner state (versioned, CRC-protected) to `buf`, which must hold
/// `rl_checkpoint_size()` bytes (`RL_E_BUFFER` otherwise). Call it between two
/// `rl_planner_step` calls; the bytes can go to non-volatile memory (cFS's CDS).
/// A checkpoint is valid for this same build only (a reset, not a software upload).
///
/// # Safety
/// `p` NULL or an initialised planner; `buf` NULL or writable for `len` bytes, not
/// overlapping `*p`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_planner_checkpoint(
    p: *const rl_planner,
    buf: *mut u8,
    len: usize,
) -> rl_status {
    if buf.is_null() {
        return RL_E_NULL;
    }
    // SAFETY: non-NULL; by the contract `buf` is writable for `len` bytes and does not
    // overlap `*p`, which is valid for reads.
    match unsafe { p.as_ref() } {
        Some(p) => p.checkpoint(unsafe { core::slice::from_raw_parts_mut(buf, len) }),
        None => RL_E_NULL,
    }
}

/// Restores a planner from a checkpoint (after a reset: `rl_planner_init`, then optionally
/// `rl_planner_load_block` of the same task, then this). It continues bit-identically to
/// the same η, f, counts and setpoints. The header and CRC are checked before any byte is
/// copied: a bad CRC, a wrong version, length or build, or (if a task is loaded) another
/// task's checkpoint is rejected and `p` is left as it was.
///
/// # Safety
/// `p` NULL or an initialised planner; `buf` NULL or readable for `len` bytes, not
/// overlapping `*p`. The bytes must come from `rl_planner_checkpoint` of this build: the
/// CRC catches corruption, not forgery.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_planner_restore(
    p: *mut rl_planner,
    buf: *const u8,
    len: usize,
) -> rl_status {
    if buf.is_null() {
        return RL_E_NULL;
    }
    // SAFETY: non-NULL; by the contract `p` is exclusive and `buf` readable for `len`
    // bytes without overlapping it.
    match unsafe { p.as_mut() } {
        Some(p) => p.restore(unsafe { core::slice::from_raw_parts(buf, len) }),
        None => RL_E_NULL,
    }
}

/// Static text naming a status or error (never NULL; unknown codes get a text too).
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn rl_status_str(s: rl_status) -> *const c_char {
    let text: &'static core::ffi::CStr = match s {
        RL_OK => c"RL_OK: success",
        RL_RUNNING => c"RL_RUNNING: budget spent, more to do",
        RL_CONVERGED => c"RL_CONVERGED: the plan met its tolerance",
        RL_EXHAUSTED => c"RL_EXHAUSTED: a budget was spent first, best plan found",
        RL_STALLED => c"RL_STALLED: no step got closer to the target, best plan found",
        RL_DONE => c"RL_DONE: last setpoint produced",
        RL_E_NULL => c"RL_E_NULL: a pointer argument is NULL",
        RL_E_ABI_VERSION => c"RL_E_ABI_VERSION: header and library ABI versions differ",
        RL_E_LOOP_SETTING => {
            c"RL_E_LOOP_SETTING: an rl_loop_config value the loop refuses (range, unstable gain, period not a multiple of dt)"
        }
        RL_E_SIZE => c"RL_E_SIZE: sizeof(rl_planner) differs between header and library",
        RL_E_UNINITIALIZED => c"RL_E_UNINITIALIZED: object not initialised",
        RL_E_NO_TASK => c"RL_E_NO_TASK: the planner has no task (load a block)",
        RL_E_NO_PLAN => c"RL_E_NO_PLAN: the planner has no finished plan yet",
        RL_E_BLOCK_MAGIC => c"RL_E_BLOCK_MAGIC: task block: wrong magic bytes",
        RL_E_BLOCK_JOINTS => c"RL_E_BLOCK_JOINTS: task block: another joint count",
        RL_E_BLOCK_LENGTH => c"RL_E_BLOCK_LENGTH: task block: wrong length",
        RL_E_BLOCK_CRC => c"RL_E_BLOCK_CRC: task block: CRC-32 mismatch",
        RL_E_BLOCK_FIELD => c"RL_E_BLOCK_FIELD: task block: a field out of range",
        RL_E_INVALID_TASK => c"RL_E_INVALID_TASK: task block: a value the planner rejects",
        RL_E_PLANNING => c"RL_E_PLANNING: no rollout could be evaluated",
        RL_E_BUFFER => c"RL_E_BUFFER: output buffer too small",
        RL_E_CKPT_LENGTH => c"RL_E_CKPT_LENGTH: checkpoint: wrong length",
        RL_E_CKPT_MAGIC => c"RL_E_CKPT_MAGIC: checkpoint: wrong magic bytes",
        RL_E_CKPT_VERSION => c"RL_E_CKPT_VERSION: checkpoint: another format or ABI version",
        RL_E_CKPT_LAYOUT => c"RL_E_CKPT_LAYOUT: checkpoint: written by another build",
        RL_E_CKPT_CRC => c"RL_E_CKPT_CRC: checkpoint: CRC-32 mismatch",
        RL_E_CKPT_TASK => c"RL_E_CKPT_TASK: checkpoint: of another task",
        RL_E_MISMATCH => c"RL_E_MISMATCH: setpoints of another planner's task",
        RL_E_STREAM => c"RL_E_STREAM: streaming failed",
        RL_BEYOND_REACH => c"RL_BEYOND_REACH: the target lies beyond the arm's reach",
        RL_PRESHAPE_BOUNDS => {
            c"RL_PRESHAPE_BOUNDS: no plan whose phase 1 the attitude control can serve in time"
        }
        RL_E_TWO_PHASE => {
            c"RL_E_TWO_PHASE: a two-phase block; rl_planner plans single-phase tasks (use rl_two_phase)"
        }
        RL_E_PHASE => c"RL_E_PHASE: a two-phase plan has phases 1 and 2 only",
        RL_E_ONE_PHASE => {
            c"RL_E_ONE_PHASE: a single-phase block; rl_two_phase plans two-phase tasks (use rl_planner)"
        }
        _ => c"unknown rl_status",
    };
    text.as_ptr()
}

/// On the flight target, a panic path that survives optimisation fails the link: this
/// handler calls a symbol that exists nowhere (`nm -u` on the archive names it).
#[cfg(target_os = "none")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    #[allow(unsafe_code)]
    unsafe extern "Rust" {
        fn reactionless_ffi_panic_path_survived_optimisation() -> !;
    }
    // SAFETY: never executed: the symbol does not exist, so a program that could reach
    // this line does not link.
    #[allow(unsafe_code)]
    unsafe {
        reactionless_ffi_panic_path_survived_optimisation()
    }
}
