//! Checkpoint and restore of the flight planner and of the two-phase search, for memory that
//! survives a processor reset (cFS's Critical Data Store, a no-init RAM section, an EEPROM
//! page).
//!
//! Owns the checkpoint's byte layout ([`write`], [`verify`], [`verify_as`], [`restore`]),
//! the states it holds ([`Payload`]: [`FlightPlanner`] and [`FlightTwoPhase`]) and the task
//! digest ([`task_digest`]). A checkpoint is the state's own bytes behind a header that
//! says which state, which build and which task they belong to, and a CRC-32 over
//! everything:
//!
//! | bytes | field |
//! |---|---|
//! | 8 | magic: `RLCKPT01` for the planner, `RLCKTP01` for the two-phase search ([`Payload::MAGIC`]) |
//! | 4 | format version ([`FORMAT`], u32) |
//! | 4 | [`crate::RL_ABI_VERSION`] (u32) |
//! | 4 | total length in bytes, CRC included ([`LEN`], [`TWO_PHASE_LEN`], u32) |
//! | 4 | `size_of` the state (u32) |
//! | 8 | layout fingerprint ([`Payload::LAYOUT`], u64) |
//! | 8 | task digest: FNV-1a-64 of the task block ([`task_digest`], u64) |
//! | `size_of` the state | the state's bytes |
//! | 4 | CRC-32 (IEEE, as [`reactionless::block::crc32`]) of everything above |
//!
//! **Same build only.** The payload is the planner's in-memory representation, so a
//! checkpoint is valid only for the build that wrote it: across a processor reset, not
//! across a software upload. The layout fingerprint (sizes and alignments of the state
//! types, the crate version, the target's pointer width and endianness) rejects most
//! mismatches, but not a rebuild that reorders fields with the same sizes: after an upload,
//! discard old checkpoints and plan again.
//!
//! **Why here and not in the core.** Turning bytes back into a `Planner` is `unsafe`
//! (its enums have invalid bit patterns), and the core is `unsafe_code = "forbid"`. The
//! header and the CRC are checked before a single byte is copied in, which guards against
//! corruption (a flipped bit in non-volatile memory, a truncated write, a checkpoint of
//! another task), not against a forged checkpoint with a valid CRC: [`restore`] is an
//! `unsafe fn` whose contract says so.

use core::mem::{align_of, size_of};
use reactionless::block::crc32;
use reactionless::twophase::{TwoPhaseConfig, TwoPhasePlan};
use reactionless::{
    Cpso, Demand, Multistart, Outcome, Plan, PlannerConfig, Preshape, Rollout, Setpoints, Swarm,
    Task, TruthState,
};

use crate::FlightPlanner;
use crate::two_phase::FlightTwoPhase;

/// The planner checkpoint's magic bytes.
pub const MAGIC: [u8; 8] = *b"RLCKPT01";
/// The two-phase search checkpoint's magic bytes.
pub const TWO_PHASE_MAGIC: [u8; 8] = *b"RLCKTP01";
/// Format version of the layout above.
pub const FORMAT: u32 = 1;
/// Header bytes before the state's.
pub const HEADER_LEN: usize = 40;
/// Total length of a planner checkpoint (bytes): header, planner, CRC.
pub const LEN: usize = <FlightPlanner as Payload>::LEN;
/// Total length of a two-phase search checkpoint (bytes): header, search, CRC.
pub const TWO_PHASE_LEN: usize = <FlightTwoPhase as Payload>::LEN;

/// A state a checkpoint holds: [`FlightPlanner`] or [`FlightTwoPhase`] (sealed). Both are
/// plain data (no pointers, references or interior mutability), so that the bytes
/// [`write`] copied out of a value form a valid value again in the same build.
pub trait Payload: sealed::Sealed + Sized {
    /// The magic bytes naming the state.
    const MAGIC: [u8; 8];
    /// The layout fingerprint: FNV-1a-64 over the size and alignment of the state and of
    /// the types it holds, the crate version, the pointer width and the endianness.
    const LAYOUT: u64;
    /// Total length of its checkpoint (bytes): header, state, CRC.
    const LEN: usize = HEADER_LEN + size_of::<Self>() + 4;
}

mod sealed {
    /// Only the states this module knows to be plain data.
    pub trait Sealed {}
    impl Sealed for crate::FlightPlanner {}
    impl Sealed for crate::two_phase::FlightTwoPhase {}
}

// Plain data: the planner, its task, swarm, rollouts and plan are arrays of numbers and
// enums; nothing points anywhere.
impl Payload for FlightPlanner {
    const MAGIC: [u8; 8] = MAGIC;
    const LAYOUT: u64 = LAYOUT;
}

// Plain data: the search holds its own copies of its tasks, and numbers and enums besides.
impl Payload for FlightTwoPhase {
    const MAGIC: [u8; 8] = TWO_PHASE_MAGIC;
    const LAYOUT: u64 = TWO_PHASE_LAYOUT;
}

/// Why a checkpoint was not written or not accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Fault {
    /// The output buffer is shorter than [`LEN`].
    Buffer,
    /// The checkpoint is shorter than [`LEN`], or its length or planner-size field is not
    /// this build's.
    Length,
    /// The magic bytes are not [`MAGIC`].
    Magic,
    /// The format version or the ABI version is not this build's.
    Version,
    /// The layout fingerprint is not this build's ([`LAYOUT`]).
    Layout,
    /// The CRC-32 does not match.
    Checksum,
    /// The checkpoint belongs to another task than the one the planner has loaded.
    Task,
}

impl core::fmt::Display for Fault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Fault::Buffer => "checkpoint buffer too small",
            Fault::Length => "checkpoint: wrong length",
            Fault::Magic => "checkpoint: wrong magic bytes",
            Fault::Version => "checkpoint: another format or ABI version",
            Fault::Layout => "checkpoint: written by another build (layout fingerprint)",
            Fault::Checksum => "checkpoint: CRC-32 mismatch",
            Fault::Task => "checkpoint: of another task",
        })
    }
}

impl core::error::Error for Fault {}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

// Const evaluation only: an index out of range would be a compile error, not a panic.
#[allow(clippy::indexing_slicing)]
const fn fnv_u64(mut h: u64, v: u64) -> u64 {
    let b = v.to_le_bytes();
    let mut i = 0;
    while i < 8 {
        h = (h ^ b[i] as u64).wrapping_mul(FNV_PRIME);
        i += 1;
    }
    h
}

#[allow(clippy::indexing_slicing)]
const fn fnv_bytes(mut h: u64, b: &[u8]) -> u64 {
    let mut i = 0;
    while i < b.len() {
        h = (h ^ b[i] as u64).wrapping_mul(FNV_PRIME);
        i += 1;
    }
    h
}

/// FNV-1a-64 of a task block's bytes: which task a checkpoint belongs to.
#[must_use]
pub fn task_digest(block: &[u8]) -> u64 {
    block.iter().fold(FNV_OFFSET, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(FNV_PRIME)
    })
}

/// FNV-1a-64 over `(size, alignment)` pairs, the pointer width, the endianness and the
/// crate version.
#[allow(clippy::indexing_slicing)]
const fn fingerprint(shapes: &[(usize, usize)]) -> u64 {
    let mut h = FNV_OFFSET;
    let mut i = 0;
    while i < shapes.len() {
        h = fnv_u64(h, shapes[i].0 as u64);
        h = fnv_u64(h, shapes[i].1 as u64);
        i += 1;
    }
    h = fnv_u64(h, size_of::<usize>() as u64);
    h = fnv_u64(h, (1usize.to_le() ^ 1) as u64);
    fnv_bytes(h, env!("CARGO_PKG_VERSION").as_bytes())
}

/// The planner's layout fingerprint ([`Payload::LAYOUT`]).
pub const LAYOUT: u64 = fingerprint(&[
    (size_of::<FlightPlanner>(), align_of::<FlightPlanner>()),
    (size_of::<Task<7, 4>>(), align_of::<Task<7, 4>>()),
    (size_of::<Rollout<7, 4>>(), align_of::<Rollout<7, 4>>()),
    (size_of::<Setpoints<7, 4>>(), align_of::<Setpoints<7, 4>>()),
    (
        size_of::<Multistart<7, 4>>(),
        align_of::<Multistart<7, 4>>(),
    ),
    (size_of::<Cpso<4, 64>>(), align_of::<Cpso<4, 64>>()),
    (size_of::<Swarm<4, 64>>(), align_of::<Swarm<4, 64>>()),
    (size_of::<Plan<7, 4>>(), align_of::<Plan<7, 4>>()),
    (size_of::<Outcome<7>>(), align_of::<Outcome<7>>()),
    (size_of::<PlannerConfig>(), align_of::<PlannerConfig>()),
]);

/// The two-phase search's layout fingerprint ([`Payload::LAYOUT`]).
pub const TWO_PHASE_LAYOUT: u64 = fingerprint(&[
    (size_of::<FlightTwoPhase>(), align_of::<FlightTwoPhase>()),
    (size_of::<Task<7, 4>>(), align_of::<Task<7, 4>>()),
    (size_of::<Rollout<7, 4>>(), align_of::<Rollout<7, 4>>()),
    (size_of::<TruthState<7>>(), align_of::<TruthState<7>>()),
    (size_of::<Preshape<7>>(), align_of::<Preshape<7>>()),
    (size_of::<Demand>(), align_of::<Demand>()),
    (
        size_of::<TwoPhasePlan<7, 4>>(),
        align_of::<TwoPhasePlan<7, 4>>(),
    ),
    (size_of::<TwoPhaseConfig>(), align_of::<TwoPhaseConfig>()),
    (size_of::<Outcome<7>>(), align_of::<Outcome<7>>()),
]);

/// Writes the checkpoint of `state` (the planner or the two-phase search), whose task block
/// has digest `task`, to the first [`Payload::LEN`] bytes of `out`; returns that length.
///
/// # Errors
/// [`Fault::Buffer`] if `out` is shorter than [`Payload::LEN`] (nothing is written).
///
/// ```
/// use reactionless_ffi::{FlightPlanner, checkpoint};
/// let planner = FlightPlanner::IDLE;
/// let mut buf = vec![0u8; checkpoint::LEN];
/// assert_eq!(checkpoint::write(&planner, 42, &mut buf), Ok(checkpoint::LEN));
/// assert_eq!(checkpoint::verify(&buf, Some(42)), Ok(42));
/// buf[100] ^= 1;
/// assert_eq!(checkpoint::verify(&buf, Some(42)), Err(checkpoint::Fault::Checksum));
/// ```
pub fn write<T: Payload>(state: &T, task: u64, out: &mut [u8]) -> Result<usize, Fault> {
    let len = T::LEN;
    let out = out.get_mut(..len).ok_or(Fault::Buffer)?;
    let (head, rest) = out.split_at_mut_checked(HEADER_LEN).ok_or(Fault::Buffer)?;
    let payload = rest.get_mut(..size_of::<T>()).ok_or(Fault::Buffer)?;
    let mut at = 0;
    let mut put = |b: &[u8]| {
        if let Some(dst) = head.get_mut(at..at + b.len()) {
            dst.copy_from_slice(b);
        }
        at += b.len();
    };
    put(&T::MAGIC);
    put(&FORMAT.to_le_bytes());
    put(&crate::RL_ABI_VERSION.to_le_bytes());
    put(&(len as u32).to_le_bytes());
    put(&(size_of::<T>() as u32).to_le_bytes());
    put(&T::LAYOUT.to_le_bytes());
    put(&task.to_le_bytes());
    copy_out(state, payload);
    let sum = crc32(out.get(..len - 4).unwrap_or(&[]));
    if let Some(dst) = out.get_mut(len - 4..len) {
        dst.copy_from_slice(&sum.to_le_bytes());
    }
    Ok(len)
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    let mut v = [0u8; 4];
    if let Some(s) = b.get(at..at + 4) {
        v.copy_from_slice(s);
    }
    u32::from_le_bytes(v)
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    let mut v = [0u8; 8];
    if let Some(s) = b.get(at..at + 8) {
        v.copy_from_slice(s);
    }
    u64::from_le_bytes(v)
}

/// [`verify_as`] for a planner checkpoint.
///
/// # Errors
/// As [`verify_as`].
pub fn verify(buf: &[u8], task: Option<u64>) -> Result<u64, Fault> {
    verify_as::<FlightPlanner>(buf, task)
}

/// Checks a checkpoint of a `T` without touching any state: the length, magic (a
/// checkpoint of the other state is [`Fault::Magic`]), versions, sizes, layout
/// fingerprint, CRC-32 and, if `task` is given, the task digest. Returns the checkpoint's
/// task digest. Bytes of `buf` past [`Payload::LEN`] are ignored.
///
/// # Errors
/// The first check that fails, in the order above ([`Fault`]).
pub fn verify_as<T: Payload>(buf: &[u8], task: Option<u64>) -> Result<u64, Fault> {
    let len = T::LEN;
    let buf = buf.get(..len).ok_or(Fault::Length)?;
    if buf.get(..8) != Some(&T::MAGIC[..]) {
        return Err(Fault::Magic);
    }
    if u32_at(buf, 8) != FORMAT || u32_at(buf, 12) != crate::RL_ABI_VERSION {
        return Err(Fault::Version);
    }
    if u32_at(buf, 16) as usize != len || u32_at(buf, 20) as usize != size_of::<T>() {
        return Err(Fault::Length);
    }
    if u64_at(buf, 24) != T::LAYOUT {
        return Err(Fault::Layout);
    }
    if crc32(buf.get(..len - 4).unwrap_or(&[])) != u32_at(buf, len - 4) {
        return Err(Fault::Checksum);
    }
    let theirs = u64_at(buf, 32);
    match task {
        Some(t) if t != theirs => Err(Fault::Task),
        _ => Ok(theirs),
    }
}

/// Restores `state` from a checkpoint after [`verify_as`] accepts it (with `task`, the
/// digest of the task block the caller has loaded, or `None` to accept any task); returns
/// the checkpoint's task digest. On any fault `state` is left untouched. The restored
/// planner or search continues bit for bit as the one that was checkpointed.
///
/// # Errors
/// As [`verify_as`].
///
/// # Safety
/// `buf` must have been written by [`write`] of this same build (possibly after a reset).
/// The CRC and the header catch corruption, not forgery: bytes with a valid header and CRC
/// that are not a `T`'s are undefined behaviour.
#[allow(unsafe_code)]
pub unsafe fn restore<T: Payload>(
    state: &mut T,
    task: Option<u64>,
    buf: &[u8],
) -> Result<u64, Fault> {
    let theirs = verify_as::<T>(buf, task)?;
    let payload = buf
        .get(HEADER_LEN..HEADER_LEN + size_of::<T>())
        .ok_or(Fault::Length)?;
    // SAFETY: `payload` is exactly size_of::<T>() bytes (checked just above) and does not
    // overlap `state` (a shared and a unique borrow); by this function's contract they are
    // the bytes of a T of this build, which is plain data ([`Payload`]'s contract), so any
    // such bytes form a valid value.
    unsafe {
        core::ptr::copy_nonoverlapping(
            payload.as_ptr(),
            core::ptr::from_mut(state).cast::<u8>(),
            size_of::<T>(),
        );
    }
    Ok(theirs)
}

/// Copies the bytes of `state` into `dst` (`size_of::<T>()` long).
#[allow(unsafe_code)]
fn copy_out<T: Payload>(state: &T, dst: &mut [u8]) {
    let src = core::ptr::from_ref(state).cast::<u8>();
    for (i, d) in dst.iter_mut().take(size_of::<T>()).enumerate() {
        // SAFETY: i < size_of::<T>(), so `src.add(i)` lies inside `*state`, which is
        // borrowed for the whole loop. The read is volatile so that padding bytes are
        // copied as whatever they hold (the CRC covers them); their value never matters on
        // restore.
        *d = unsafe { src.add(i).read_volatile() };
    }
}
