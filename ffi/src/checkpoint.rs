//! Checkpoint and restore of the flight planner, for memory that survives a processor reset
//! (cFS's Critical Data Store, a no-init RAM section, an EEPROM page).
//!
//! Owns the checkpoint's byte layout ([`write`], [`verify`], [`restore`]) and the task
//! digest ([`task_digest`]). A checkpoint is the planner's own bytes behind a header that
//! says which build and which task they belong to, and a CRC-32 over everything:
//!
//! | bytes | field |
//! |---|---|
//! | 8 | magic `RLCKPT01` |
//! | 4 | format version ([`FORMAT`], u32) |
//! | 4 | [`crate::RL_ABI_VERSION`] (u32) |
//! | 4 | total length in bytes, CRC included ([`LEN`], u32) |
//! | 4 | `size_of::<Planner<7, 4, 64>>()` (u32) |
//! | 8 | layout fingerprint ([`LAYOUT`], u64) |
//! | 8 | task digest: FNV-1a-64 of the task block ([`task_digest`], u64) |
//! | `size_of::<Planner>` | the planner's bytes |
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
use reactionless::{
    Cpso, Multistart, Outcome, Plan, PlannerConfig, Rollout, Setpoints, Swarm, Task,
};

use crate::FlightPlanner;

/// The checkpoint's magic bytes.
pub const MAGIC: [u8; 8] = *b"RLCKPT01";
/// Format version of the layout above.
pub const FORMAT: u32 = 1;
/// Header bytes before the planner's.
pub const HEADER_LEN: usize = 40;
/// Total length of a checkpoint (bytes): header, planner, CRC.
pub const LEN: usize = HEADER_LEN + size_of::<FlightPlanner>() + 4;

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

/// The layout fingerprint: FNV-1a-64 over the size and alignment of the planner and of
/// the state types it holds, the crate version, the pointer width and the endianness.
#[allow(clippy::indexing_slicing)]
pub const LAYOUT: u64 = {
    let shapes = [
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
        (size_of::<usize>(), 1usize.to_le() ^ 1),
    ];
    let mut h = FNV_OFFSET;
    let mut i = 0;
    while i < shapes.len() {
        h = fnv_u64(h, shapes[i].0 as u64);
        h = fnv_u64(h, shapes[i].1 as u64);
        i += 1;
    }
    fnv_bytes(h, env!("CARGO_PKG_VERSION").as_bytes())
};

/// Writes the checkpoint of `planner`, whose task block has digest `task`, to the first
/// [`LEN`] bytes of `out`; returns [`LEN`].
///
/// # Errors
/// [`Fault::Buffer`] if `out` is shorter than [`LEN`] (nothing is written).
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
pub fn write(planner: &FlightPlanner, task: u64, out: &mut [u8]) -> Result<usize, Fault> {
    let out = out.get_mut(..LEN).ok_or(Fault::Buffer)?;
    let (head, rest) = out.split_at_mut_checked(HEADER_LEN).ok_or(Fault::Buffer)?;
    let payload = rest
        .get_mut(..size_of::<FlightPlanner>())
        .ok_or(Fault::Buffer)?;
    let mut at = 0;
    let mut put = |b: &[u8]| {
        if let Some(dst) = head.get_mut(at..at + b.len()) {
            dst.copy_from_slice(b);
        }
        at += b.len();
    };
    put(&MAGIC);
    put(&FORMAT.to_le_bytes());
    put(&crate::RL_ABI_VERSION.to_le_bytes());
    put(&(LEN as u32).to_le_bytes());
    put(&(size_of::<FlightPlanner>() as u32).to_le_bytes());
    put(&LAYOUT.to_le_bytes());
    put(&task.to_le_bytes());
    copy_out(planner, payload);
    let sum = crc32(out.get(..LEN - 4).unwrap_or(&[]));
    if let Some(dst) = out.get_mut(LEN - 4..LEN) {
        dst.copy_from_slice(&sum.to_le_bytes());
    }
    Ok(LEN)
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

/// Checks a checkpoint without touching any planner: the length, magic, versions, sizes,
/// layout fingerprint, CRC-32 and, if `task` is given, the task digest. Returns the
/// checkpoint's task digest. Bytes of `buf` past [`LEN`] are ignored.
///
/// # Errors
/// The first check that fails, in the order above ([`Fault`]).
pub fn verify(buf: &[u8], task: Option<u64>) -> Result<u64, Fault> {
    let buf = buf.get(..LEN).ok_or(Fault::Length)?;
    if buf.get(..8) != Some(&MAGIC[..]) {
        return Err(Fault::Magic);
    }
    if u32_at(buf, 8) != FORMAT || u32_at(buf, 12) != crate::RL_ABI_VERSION {
        return Err(Fault::Version);
    }
    if u32_at(buf, 16) as usize != LEN || u32_at(buf, 20) as usize != size_of::<FlightPlanner>() {
        return Err(Fault::Length);
    }
    if u64_at(buf, 24) != LAYOUT {
        return Err(Fault::Layout);
    }
    if crc32(buf.get(..LEN - 4).unwrap_or(&[])) != u32_at(buf, LEN - 4) {
        return Err(Fault::Checksum);
    }
    let theirs = u64_at(buf, 32);
    match task {
        Some(t) if t != theirs => Err(Fault::Task),
        _ => Ok(theirs),
    }
}

/// Restores `planner` from a checkpoint after [`verify`] accepts it (with `task`, the
/// digest of the task block the caller has loaded, or `None` to accept any task); returns
/// the checkpoint's task digest. On any fault `planner` is left untouched. The restored
/// planner continues bit for bit as the one that was checkpointed.
///
/// # Errors
/// As [`verify`].
///
/// # Safety
/// `buf` must have been written by [`write`] of this same build (possibly after a reset).
/// The CRC and the header catch corruption, not forgery: bytes with a valid header and CRC
/// that are not a planner's are undefined behaviour.
#[allow(unsafe_code)]
pub unsafe fn restore(
    planner: &mut FlightPlanner,
    task: Option<u64>,
    buf: &[u8],
) -> Result<u64, Fault> {
    let theirs = verify(buf, task)?;
    let payload = buf
        .get(HEADER_LEN..HEADER_LEN + size_of::<FlightPlanner>())
        .ok_or(Fault::Length)?;
    // SAFETY: `payload` is exactly size_of::<FlightPlanner>() bytes (checked just above)
    // and does not overlap `planner` (a shared and a unique borrow); by this function's
    // contract they are the bytes of a FlightPlanner of this build, which has no pointers
    // or references (plain data), so any such bytes form a valid value.
    unsafe {
        core::ptr::copy_nonoverlapping(
            payload.as_ptr(),
            core::ptr::from_mut(planner).cast::<u8>(),
            size_of::<FlightPlanner>(),
        );
    }
    Ok(theirs)
}

/// Copies the bytes of `planner` into `dst` (`size_of::<FlightPlanner>()` long).
#[allow(unsafe_code)]
fn copy_out(planner: &FlightPlanner, dst: &mut [u8]) {
    let src = core::ptr::from_ref(planner).cast::<u8>();
    for (i, d) in dst.iter_mut().take(size_of::<FlightPlanner>()).enumerate() {
        // SAFETY: i < size_of::<FlightPlanner>(), so `src.add(i)` lies inside `*planner`,
        // which is borrowed for the whole loop. The read is volatile so that padding bytes
        // are copied as whatever they hold (the CRC covers them); their value never
        // matters on restore.
        *d = unsafe { src.add(i).read_volatile() };
    }
}
