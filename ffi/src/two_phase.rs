//! Two-phase plans (spec §15) through the C ABI: the resumable, budgeted two-phase search
//! (`reactionless::twophase::TwoPhaseSearch`, 7 joints, K = 4) in caller-owned storage.
//!
//! Owns [`rl_two_phase`] (the search's storage), [`rl_two_phase_plan`] (what a finished
//! search reports) and their functions `rl_two_phase_init`, `rl_two_phase_load_block`,
//! `rl_two_phase_step`, its checkpoints, and the streams of the two phases' setpoints in an
//! [`crate::rl_setpoints`] (`rl_two_phase_setpoints_init`, `rl_two_phase_setpoints_next`). The same contract as [`crate::rl_planner`]: the caller's header
//! version and `sizeof` are checked at init, storage is the caller's (static app data),
//! every pointer is checked for NULL and every object for its state, nothing panics.
//!
//! A two-phase block (`RLTASK04`, `RLTASK05`: a task with `[preshape]`) goes here; the
//! single-phase `rl_planner` refuses it (`RL_E_TWO_PHASE`) and this refuses a single-phase
//! block (`RL_E_ONE_PHASE`). A unit of `rl_two_phase_step`'s budget is one move of the
//! search (at most a rollout's work: a forward kinematics of the reach check, a rollout,
//! fitting phase 1 for a start that met the goal, or 200 steps of its phase 2 on the truth
//! model); any slicing gives the same bits. Each phase streams on its own, `t` from 0:
//! phase 1 under attitude control, then phase 2 free floating; what is streamed is what was
//! planned, bit for bit. The search checkpoints and restores as the planner does
//! (`rl_two_phase_checkpoint_size`, `rl_two_phase_checkpoint`, `rl_two_phase_restore`;
//! [`crate::checkpoint`]).
//!
//! Verifies RL-FFI-011.

use core::mem::{align_of, size_of};
use reactionless::block::decode;
use reactionless::twophase::{TwoPhasePlan, TwoPhaseSearch, TwoPhaseStatus, TwoPhaseStop};
use reactionless::{Error, PreshapeSetpoints, Sample};

use crate::{
    FlightSetpoints, RL_ABI_VERSION, RL_BEYOND_REACH, RL_CONVERGED, RL_DONE, RL_E_ABI_VERSION,
    RL_E_MISMATCH, RL_E_NO_PLAN, RL_E_NO_TASK, RL_E_NULL, RL_E_PHASE, RL_E_PLANNING, RL_E_SIZE,
    RL_E_STREAM, RL_E_UNINITIALIZED, RL_ETA_LEN, RL_EXHAUSTED, RL_JOINTS, RL_OK,
    RL_PRESHAPE_BOUNDS, RL_RUNNING, RL_SETPOINTS_WORDS, checkpoint, fault_status, load_error,
    rl_setpoint, rl_setpoints, rl_status,
};

/// The flight two-phase search: 7 joints, null-space dimension 4.
pub type FlightTwoPhase = TwoPhaseSearch<7, 4>;

/// Words (u64) of search storage inside [`rl_two_phase`]: room for the search on every
/// target, with headroom so that a small growth of the core keeps the ABI.
pub const RL_TWO_PHASE_WORDS: usize = 3840;
/// Bytes that always hold a two-phase checkpoint of this ABI version
/// (`rl_two_phase_checkpoint_size()` is at most this), for sizing a static buffer or a CDS
/// block at compile time.
pub const RL_TWO_PHASE_CHECKPOINT_CAPACITY: usize = RL_TWO_PHASE_WORDS * 8 + 64;

const TWO_PHASE_MAGIC: u32 = 0x524c_5432; // "RLT2"
/// An [`rl_setpoints`] streaming phase 1 (it holds a `PreshapeSetpoints<7>`).
pub(crate) const PHASE1_MAGIC: u32 = 0x524c_5331; // "RLS1"
/// An [`rl_setpoints`] streaming phase 2 (it holds a `FlightSetpoints` from `q_s`).
pub(crate) const PHASE2_MAGIC: u32 = 0x524c_5332; // "RLS2"

const _: () = assert!(size_of::<FlightTwoPhase>() <= RL_TWO_PHASE_WORDS * 8);
const _: () = assert!(checkpoint::TWO_PHASE_LEN <= RL_TWO_PHASE_CHECKPOINT_CAPACITY);
const _: () = assert!(align_of::<FlightTwoPhase>() <= align_of::<u64>());
const _: () = assert!(size_of::<PreshapeSetpoints<7>>() <= RL_SETPOINTS_WORDS * 8);
const _: () = assert!(align_of::<PreshapeSetpoints<7>>() <= align_of::<u64>());

/// A two-phase search in caller-owned storage (static app data). Initialise with
/// `rl_two_phase_init`; the members are private to the library.
#[repr(C)]
pub struct rl_two_phase {
    /// Set by `rl_two_phase_init`.
    magic: u32,
    /// 1 once a two-phase block is loaded.
    loaded: u32,
    /// Digest of the loaded task block (FNV-1a-64).
    task: u64,
    /// The search itself.
    storage: [u64; RL_TWO_PHASE_WORDS],
}

/// A finished two-phase plan (filled by `rl_two_phase_step` once it returns
/// `RL_CONVERGED`, `RL_EXHAUSTED`, `RL_BEYOND_REACH` or `RL_PRESHAPE_BOUNDS`): phase 1
/// from the task's start to `q_s` with the base attitude held by the attitude control, then
/// phase 2, the reactionless motion of `eta` from `q_s`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct rl_two_phase_plan {
    /// Start of phase 2 (rad), within the joint limits.
    pub q_s: [f64; RL_JOINTS],
    /// Phase 2's η: `a1, b1, a2, b2, …`.
    pub eta: [f64; RL_ETA_LEN],
    /// Pose error norm `f` of phase 2's rollout (planner model; NaN when none was rolled
    /// out: a target beyond reach).
    pub f: f64,
    /// Constraint violation Φ of phase 2 (rad; NaN as `f`).
    pub phi: f64,
    /// End-effector position at the end of phase 2 (m, inertial frame; NaN as `f`).
    pub end_position: [f64; 3],
    /// End-effector attitude at the end of phase 2, quaternion `w, x, y, z` (NaN as `f`).
    pub end_quat_wxyz: [f64; 4],
    /// Phase 1's duration (s).
    pub phase1_duration_s: f64,
    /// Phase 1's largest wheel momentum (N m s) on its written samples.
    pub wheel_momentum_nms: f64,
    /// Phase 1's largest wheel torque (N m) on its written samples.
    pub wheel_torque_nm: f64,
    /// How far phase 1 moves the base (m, inertial frame; the CoM stays put).
    pub base_shift_m: [f64; 3],
    /// `f` of the reach check's kinematic inverse (m and rad).
    pub reach_f: f64,
    /// Phase 2's largest base rotation on the truth model (rad; NaN unless converged).
    pub base_disturbance_rad: f64,
    /// Phase 1's integration steps of the task's `dt`.
    pub phase1_steps: u32,
    /// Rollouts spent.
    pub rollouts: u32,
    /// LM starts begun.
    pub starts: u32,
    /// 1 if the plan met its tolerance (`RL_CONVERGED`), else 0.
    pub converged: u32,
}

impl rl_two_phase_plan {
    /// All zero.
    pub const ZEROED: Self = Self {
        q_s: [0.0; RL_JOINTS],
        eta: [0.0; RL_ETA_LEN],
        f: 0.0,
        phi: 0.0,
        end_position: [0.0; 3],
        end_quat_wxyz: [0.0; 4],
        phase1_duration_s: 0.0,
        wheel_momentum_nms: 0.0,
        wheel_torque_nm: 0.0,
        base_shift_m: [0.0; 3],
        reach_f: 0.0,
        base_disturbance_rad: 0.0,
        phase1_steps: 0,
        rollouts: 0,
        starts: 0,
        converged: 0,
    };

    /// The C view of `p`.
    #[must_use]
    pub fn of(p: &TwoPhasePlan<7, 4>) -> Self {
        let mut eta = [0.0; RL_ETA_LEN];
        for (d, s) in eta.iter_mut().zip(p.eta.iter().flatten()) {
            *d = *s;
        }
        let (f, phi, end_position, end_quat_wxyz) = match &p.outcome {
            Some(o) => (o.f, o.phi, o.end_pose.position, o.end_pose.quat_wxyz),
            None => (f64::NAN, f64::NAN, [f64::NAN; 3], [f64::NAN; 4]),
        };
        Self {
            q_s: p.q_s,
            eta,
            f,
            phi,
            end_position,
            end_quat_wxyz,
            phase1_duration_s: p.preshape.duration(),
            wheel_momentum_nms: p.demand.momentum_nms,
            wheel_torque_nm: p.demand.torque_nm,
            base_shift_m: p.demand.base_shift_m,
            reach_f: p.reach_f,
            base_disturbance_rad: p.base_disturbance,
            phase1_steps: p.preshape.steps(),
            rollouts: p.rollouts,
            starts: p.starts,
            converged: u32::from(p.converged()),
        }
    }
}

impl rl_two_phase {
    /// All zero: not initialised (for Rust callers that need a value to box).
    pub const ZEROED: Self = Self {
        magic: 0,
        loaded: 0,
        task: 0,
        storage: [0; RL_TWO_PHASE_WORDS],
    };

    /// The search, mutably, if `rl_two_phase_init` has run on this storage.
    #[allow(unsafe_code)]
    fn search_mut(&mut self) -> Option<&mut FlightTwoPhase> {
        (self.magic == TWO_PHASE_MAGIC).then(|| {
            // SAFETY: the magic is written only by rl_two_phase_init, right after it wrote
            // a FlightTwoPhase into `storage` (size and alignment asserted above); from
            // then on `storage` is only written as that search. `&mut self` makes the
            // borrow exclusive.
            unsafe { &mut *self.storage.as_mut_ptr().cast::<FlightTwoPhase>() }
        })
    }

    fn load(&mut self, block: &[u8]) -> rl_status {
        if self.magic != TWO_PHASE_MAGIC {
            return RL_E_UNINITIALIZED;
        }
        self.loaded = 0;
        let decoded = match decode::<7>(block) {
            Ok(b) => b,
            Err(e) => return load_error(e),
        };
        let Some(search) = self.search_mut() else {
            return RL_E_UNINITIALIZED;
        };
        if let Err(e) = decoded.load_two_phase_into(search) {
            return load_error(e);
        }
        self.task = checkpoint::task_digest(block);
        self.loaded = 1;
        RL_OK
    }

    /// The search, if `rl_two_phase_init` has run on this storage and a block is loaded.
    #[allow(unsafe_code)]
    fn loaded(&self) -> Result<&FlightTwoPhase, rl_status> {
        if self.magic != TWO_PHASE_MAGIC {
            return Err(RL_E_UNINITIALIZED);
        }
        if self.loaded != 1 {
            return Err(RL_E_NO_TASK);
        }
        // SAFETY: as in `search_mut` (the magic says a FlightTwoPhase is in `storage`).
        Ok(unsafe { &*self.storage.as_ptr().cast::<FlightTwoPhase>() })
    }

    fn checkpoint(&self, buf: &mut [u8]) -> rl_status {
        let search = match self.loaded() {
            Ok(s) => s,
            Err(st) => return st,
        };
        match checkpoint::write(search, self.task, buf) {
            Ok(_) => RL_OK,
            Err(f) => fault_status(f),
        }
    }

    #[allow(unsafe_code)]
    fn restore(&mut self, buf: &[u8]) -> rl_status {
        let expected = (self.loaded == 1).then_some(self.task);
        let Some(search) = self.search_mut() else {
            return RL_E_UNINITIALIZED;
        };
        // SAFETY: the C contract of rl_two_phase_restore: `buf` holds a checkpoint written
        // by rl_two_phase_checkpoint of this build; header and CRC are checked first.
        match unsafe { checkpoint::restore(search, expected, buf) } {
            Ok(task) => {
                self.task = task;
                self.loaded = 1;
                RL_OK
            }
            Err(f) => fault_status(f),
        }
    }

    fn step(&mut self, budget: u32, plan: &mut rl_two_phase_plan) -> rl_status {
        let loaded = self.loaded == 1;
        let Some(search) = self.search_mut() else {
            return RL_E_UNINITIALIZED;
        };
        if !loaded {
            return RL_E_NO_TASK;
        }
        match search.step(budget) {
            Ok(TwoPhaseStatus::Running) => RL_RUNNING,
            Ok(TwoPhaseStatus::Finished(p)) => {
                *plan = rl_two_phase_plan::of(&p);
                match p.stop {
                    TwoPhaseStop::Converged => RL_CONVERGED,
                    TwoPhaseStop::Exhausted => RL_EXHAUSTED,
                    TwoPhaseStop::BeyondReach => RL_BEYOND_REACH,
                    TwoPhaseStop::PreshapeBounds => RL_PRESHAPE_BOUNDS,
                }
            }
            Err(Error::NotInitialized) => RL_E_NO_TASK,
            Err(_) => RL_E_PLANNING,
        }
    }
}

/// Initialises `t` as an idle two-phase search without a task. `abi_version` and
/// `size` are the caller's `RL_ABI_VERSION` and `sizeof(rl_two_phase)`: a mismatch is
/// `RL_E_ABI_VERSION` or `RL_E_SIZE`, and `t` is left untouched.
///
/// # Safety
/// `t` is NULL or points to writable, aligned storage of `sizeof(rl_two_phase)` bytes that
/// nothing else accesses during the call; it need not be initialised.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_two_phase_init(
    t: *mut rl_two_phase,
    abi_version: u32,
    size: usize,
) -> rl_status {
    if t.is_null() {
        return RL_E_NULL;
    }
    if abi_version != RL_ABI_VERSION {
        return RL_E_ABI_VERSION;
    }
    if size != size_of::<rl_two_phase>() {
        return RL_E_SIZE;
    }
    // SAFETY: `t` is non-NULL and, by the contract, valid for writes of one rl_two_phase;
    // only writes happen. The search goes to `storage`, whose size and alignment fit it
    // (asserted at compile time).
    unsafe {
        core::ptr::addr_of_mut!((*t).storage)
            .cast::<FlightTwoPhase>()
            .write(FlightTwoPhase::IDLE);
        core::ptr::addr_of_mut!((*t).loaded).write(0);
        core::ptr::addr_of_mut!((*t).task).write(0);
        core::ptr::addr_of_mut!((*t).magic).write(TWO_PHASE_MAGIC);
    }
    RL_OK
}

/// Loads a two-phase task block (`RLTASK04` or `RLTASK05`, the bytes `host-sim block TASK
/// --out FILE` writes for a task with `[preshape]`), validated as `rl_planner_load_block`
/// validates; a single-phase block is `RL_E_ONE_PHASE` (plan it with `rl_planner`). On
/// success the search starts from scratch with the block's seed; on failure it has no task
/// (`RL_E_NO_TASK` from `rl_two_phase_step`) and the status names the fault.
///
/// # Safety
/// `t` is NULL or initialised by `rl_two_phase_init`, not accessed elsewhere during the
/// call; `block` is NULL or readable for `len` bytes.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_two_phase_load_block(
    t: *mut rl_two_phase,
    block: *const u8,
    len: usize,
) -> rl_status {
    if block.is_null() {
        return RL_E_NULL;
    }
    // SAFETY: non-NULL; by the contract `t` is exclusive and `block` readable for `len`
    // bytes and not written during the call.
    match unsafe { t.as_mut() } {
        Some(t) => t.load(unsafe { core::slice::from_raw_parts(block, len) }),
        None => RL_E_NULL,
    }
}

/// Moves the search on by at most `budget` units (one move of the search each, at most a
/// rollout's work: a forward kinematics of the reach check, a rollout, fitting phase 1 for
/// a start that met the goal, or 200 steps of its phase 2 on the truth model). Returns `RL_RUNNING` while there is more to do, then
/// `RL_CONVERGED`, `RL_EXHAUSTED`, `RL_BEYOND_REACH` or `RL_PRESHAPE_BOUNDS` with `*plan`
/// filled (and the same again, without work, on every later call). `plan` is untouched
/// while running. Any slicing gives the same plan bit for bit.
///
/// # Safety
/// `t` is NULL or an initialised search and `plan` NULL or a writable
/// rl_two_phase_plan, neither accessed elsewhere during the call.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_two_phase_step(
    t: *mut rl_two_phase,
    budget: u32,
    plan: *mut rl_two_phase_plan,
) -> rl_status {
    // SAFETY: as_mut checks for NULL; the contract makes both references valid and
    // exclusive for the call.
    match unsafe { (t.as_mut(), plan.as_mut()) } {
        (Some(t), Some(plan)) => t.step(budget, plan),
        _ => RL_E_NULL,
    }
}

/// Bytes of a two-phase checkpoint (header, search, CRC).
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn rl_two_phase_checkpoint_size() -> usize {
    checkpoint::TWO_PHASE_LEN
}

/// Writes the whole search state (versioned, CRC-protected, magic `RLCKTP01`) to `buf`,
/// which must hold `rl_two_phase_checkpoint_size()` bytes (`RL_E_BUFFER` otherwise). Call
/// it between two `rl_two_phase_step` calls, or after the search finished (the plan and
/// phase 2's start are in it, so both phases stream after a restore). Valid for this same
/// build only (a reset, not a software upload).
///
/// # Safety
/// `t` NULL or an initialised search; `buf` NULL or writable for `len` bytes, not
/// overlapping `*t`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_two_phase_checkpoint(
    t: *const rl_two_phase,
    buf: *mut u8,
    len: usize,
) -> rl_status {
    if buf.is_null() {
        return RL_E_NULL;
    }
    // SAFETY: non-NULL; by the contract `buf` is writable for `len` bytes and does not
    // overlap `*t`, which is valid for reads.
    match unsafe { t.as_ref() } {
        Some(t) => t.checkpoint(unsafe { core::slice::from_raw_parts_mut(buf, len) }),
        None => RL_E_NULL,
    }
}

/// Restores a search from a two-phase checkpoint (after a reset: `rl_two_phase_init`, then
/// optionally `rl_two_phase_load_block` of the same task, then this). It continues
/// bit-identically: the same plan, counts and setpoints of both phases. The header and CRC
/// are checked before any byte is copied: a bad CRC, a wrong version, length or build, a
/// planner's checkpoint (`RL_E_CKPT_MAGIC`) or, if a task is loaded, another task's
/// checkpoint is rejected and `t` is left as it was.
///
/// # Safety
/// `t` NULL or an initialised search; `buf` NULL or readable for `len` bytes, not
/// overlapping `*t`. The bytes must come from `rl_two_phase_checkpoint` of this build: the
/// CRC catches corruption, not forgery.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_two_phase_restore(
    t: *mut rl_two_phase,
    buf: *const u8,
    len: usize,
) -> rl_status {
    if buf.is_null() {
        return RL_E_NULL;
    }
    // SAFETY: non-NULL; by the contract `t` is exclusive and `buf` readable for `len`
    // bytes without overlapping it.
    match unsafe { t.as_mut() } {
        Some(t) => t.restore(unsafe { core::slice::from_raw_parts(buf, len) }),
        None => RL_E_NULL,
    }
}

/// Starts streaming phase `phase` (1 or 2) of `t`'s finished plan into `s`: phase 1 from
/// the task's start to `q_s` (the attitude control holding the base), or phase 2, the
/// reactionless motion from `q_s` (the attitude control off). Each starts at `t = 0`; phase
/// 1 ends at rest at `q_s`, where phase 2 starts. `RL_E_NO_PLAN` before
/// `rl_two_phase_step` finished, or for phase 2 of a plan that has none (a target beyond
/// reach); `RL_E_PHASE` for another phase number.
///
/// # Safety
/// `s` is NULL or writable, aligned storage of `sizeof(rl_setpoints)` bytes (it need not be
/// initialised); `t` NULL or an initialised search; neither accessed elsewhere.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_two_phase_setpoints_init(
    s: *mut rl_setpoints,
    t: *const rl_two_phase,
    phase: u32,
) -> rl_status {
    // SAFETY: as_ref checks for NULL; the contract makes the reference valid.
    let Some(t) = (unsafe { t.as_ref() }) else {
        return RL_E_NULL;
    };
    if s.is_null() {
        return RL_E_NULL;
    }
    let search = match t.loaded() {
        Ok(search) => search,
        Err(st) => return st,
    };
    let Some(plan) = search.plan() else {
        return RL_E_NO_PLAN;
    };
    match phase {
        1 => {
            let stream = plan.preshape.setpoints();
            // SAFETY: `s` is non-NULL and, by the contract, valid for writes of one
            // rl_setpoints; only writes happen. The stream fits `storage` (asserted at
            // compile time).
            unsafe { start(s, stream, t.task, PHASE1_MAGIC) };
            RL_OK
        }
        2 => {
            let (Some(task), Some(_)) = (search.phase2_task(), plan.outcome) else {
                return RL_E_NO_PLAN;
            };
            let Ok(stream) = FlightSetpoints::new(task, &plan.eta) else {
                return RL_E_STREAM;
            };
            // SAFETY: as for phase 1.
            unsafe { start(s, stream, t.task, PHASE2_MAGIC) };
            RL_OK
        }
        _ => RL_E_PHASE,
    }
}

/// Writes `stream` into `s`'s storage and marks it with `magic`.
///
/// # Safety
/// `s` is non-NULL, valid for writes of one rl_setpoints, and `T` fits its storage.
#[allow(unsafe_code)]
unsafe fn start<T>(s: *mut rl_setpoints, stream: T, task: u64, magic: u32) {
    // SAFETY: by this function's contract.
    unsafe {
        core::ptr::addr_of_mut!((*s).storage)
            .cast::<T>()
            .write(stream);
        core::ptr::addr_of_mut!((*s).done).write(0);
        core::ptr::addr_of_mut!((*s).task).write(task);
        core::ptr::addr_of_mut!((*s).magic).write(magic);
    }
}

/// The next setpoint of a phase's stream in `*out` (`RL_OK`), `t` from 0 in steps of the
/// task's `dt`; after the last, `RL_DONE` on every call. At most one integration step per
/// call. `t` must be the search the stream was started from (`RL_E_MISMATCH` otherwise, and
/// for a single-phase stream: use `rl_setpoints_next`).
///
/// # Safety
/// `s` NULL or a stream initialised by `rl_two_phase_setpoints_init`; `t` NULL or an
/// initialised search; `out` NULL or writable; none accessed elsewhere during the call.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_two_phase_setpoints_next(
    s: *mut rl_setpoints,
    t: *const rl_two_phase,
    out: *mut rl_setpoint,
) -> rl_status {
    // SAFETY: as_mut/as_ref check for NULL; the contract makes the references valid and
    // `s`, `out` exclusive.
    let (Some(s), Some(t), Some(out)) = (unsafe { (s.as_mut(), t.as_ref(), out.as_mut()) }) else {
        return RL_E_NULL;
    };
    let search = match t.loaded() {
        Ok(search) => search,
        Err(st) => return st,
    };
    if s.magic != PHASE1_MAGIC && s.magic != PHASE2_MAGIC {
        return if s.magic == crate::SETPOINTS_MAGIC {
            RL_E_MISMATCH
        } else {
            RL_E_UNINITIALIZED
        };
    }
    if s.task != t.task {
        return RL_E_MISMATCH;
    }
    if s.done == 1 {
        return RL_DONE;
    }
    let next: Result<Option<Sample<7>>, Error> = if s.magic == PHASE1_MAGIC {
        // SAFETY: PHASE1_MAGIC is written only by rl_two_phase_setpoints_init, right after
        // it wrote a PreshapeSetpoints<7> into `storage` (size and alignment asserted).
        let stream = unsafe { &mut *s.storage.as_mut_ptr().cast::<PreshapeSetpoints<7>>() };
        Ok(stream.next())
    } else {
        let Some(task) = search.phase2_task() else {
            return RL_E_NO_PLAN;
        };
        // SAFETY: PHASE2_MAGIC is written only by rl_two_phase_setpoints_init, right after
        // it wrote a FlightSetpoints into `storage` (size and alignment asserted in lib.rs).
        let stream = unsafe { &mut *s.storage.as_mut_ptr().cast::<FlightSetpoints>() };
        stream.next(task)
    };
    match next {
        Ok(Some(sp)) => {
            *out = rl_setpoint {
                t: sp.t,
                q: sp.q,
                qd: sp.qd,
            };
            RL_OK
        }
        Ok(None) => {
            s.done = 1;
            RL_DONE
        }
        Err(_) => RL_E_STREAM,
    }
}
