//! The task block: how a whole planning task crosses from the ground to the flight image.
//!
//! Owns [`TaskBlock`] and its fixed little-endian byte layout ([`encode`], [`decode`]). A
//! block carries the robot description (so any robot with the image's `N` can be planned
//! without rebuilding), the start, the target, the time grid and every planner setting, and
//! ends with a CRC-32 (IEEE 802.3) over all preceding bytes. Decoding is bounds-checked and
//! rejects a wrong magic, joint count, length or checksum with a typed error; the values
//! are then validated by the usual constructors ([`crate::Robot::new`], [`crate::Task::new`],
//! [`crate::Planner::new`]).
//!
//! Layout (all little-endian; `f64` as IEEE-754 bits):
//!
//! | bytes | field |
//! |---|---|
//! | 8 | magic `RLTASK02` |
//! | 4 | `N` (u32) |
//! | 4 | total length in bytes, checksum included (u32) |
//! | 13·8 | base: mass, inertial xyz, inertial rpy, ixx ixy ixz iyy iyz izz |
//! | N·12·8 | joints: origin xyz, origin rpy, axis, lower, upper, velocity |
//! | N·13·8 | links: as the base |
//! | 6·8 | end effector: xyz, rpy |
//! | N·8 | start q₀ (rad) |
//! | 7·8 | target: position (m), quaternion `[w, x, y, z]` |
//! | 2·8 + 4 | `t_f`, `dt` (s); `n` (u32: bits 0–7 the degree; bits 8–15 the integrator's stride, 0 for Euler or the samples per step `1..=255` of RK4 or AB5 ([`Motion::with_integrator_stride`]); bits 16–19 the motion family, [`Family::code`]: 0 paper, 1 free amplitude; bits 20–23 the integrator where the stride does not say it: 0 for Euler (stride 0) and RK4 (stride ≥ 1), 2 for AB5; bits 24–31 the segment count less one, [`Motion::with_segments`]) |
//! | 4 + 4 | particles, max_iterations (u32) |
//! | 6·8 | c1, c2, w_max, w_min, tolerance, eta_bound |
//! | 8 | seed (u64) |
//! | 4 + 3·8 | stagnation window (u32); min_relative_improvement, eps1, eps2 |
//! | 4 + 8 + 4 | refine flag (u32, 0 or 1), refine tolerance, refine max rollouts (u32) |
//! | 4 | frame budget (u32, integration steps per call of `step`) |
//! | 4 + 4 + 4 | strategy (u32, [`Strategy::code`]: 0 multistart, 1 cpso), max_rollouts (u32), refine_against (u32, [`RefineAgainst::code`]: 0 planner, 1 truth) |
//! | 4 + 8 + N·8 | only with magic `RLTASK03` or `RLTASK05`: re-timing grid (u32), margin, `q̈max` per joint (rad/s²) |
//! | 9·8 + 4 | only with magic `RLTASK04` or `RLTASK05`: a two-phase plan ([`TwoPhaseConfig`], spec §15): `q̈max` of phase 1 (rad/s²), longest phase 1 (s), wheel momentum (N m s) and torque (N m), standoff (m, rad), phase 2's tolerance on `f`, joint-limit margin (rad), largest base disturbance (rad); rollout budget (u32) |
//! | 4 | CRC-32 of everything above |
//!
//! The magic names the optional sections: `RLTASK02` none, `RLTASK03` re-timing, `RLTASK04`
//! two-phase, `RLTASK05` both. A block without them is written with magic `RLTASK02` and is
//! byte for byte what earlier versions wrote; [`decode`] reads all four. A block of the
//! paper's family has family bits 0, so blocks written before the family existed read as
//! the paper's; likewise one segment has segment bits 0, and Euler integrator bits 0.

use crate::config::{PlannerConfig, RefineAgainst, StagnationConfig, Strategy};
use crate::error::{BlockFault, Error};
use crate::geometry::Pose;
use crate::model::{BodyDesc, Inertia, JointDesc, Origin, RobotDesc};
use crate::planner::Planner;
use crate::trajectory::{Family, Integrator, Motion};
use crate::twophase::{TwoPhaseConfig, TwoPhaseSearch};

/// The block's magic bytes (`01` had no strategy, budget or refinement target).
pub const MAGIC: [u8; 8] = *b"RLTASK02";
/// The magic of a block that also carries [`RetimeSettings`].
pub const MAGIC_RETIME: [u8; 8] = *b"RLTASK03";
/// The magic of a block that carries a two-phase plan's [`TwoPhaseConfig`].
pub const MAGIC_TWO_PHASE: [u8; 8] = *b"RLTASK04";
/// The magic of a block that carries both [`RetimeSettings`] and a [`TwoPhaseConfig`].
pub const MAGIC_TWO_PHASE_RETIME: [u8; 8] = *b"RLTASK05";

/// Bytes of the two-phase section.
const TWO_PHASE_LEN: usize = 9 * 8 + 4;

/// Size in bytes of a block for `n` joints.
#[must_use]
pub const fn block_len(n: usize) -> usize {
    8 + 4
        + 4
        + 13 * 8
        + n * 12 * 8
        + n * 13 * 8
        + 6 * 8
        + n * 8
        + 7 * 8
        + 2 * 8
        + 4
        + 4
        + 4
        + 6 * 8
        + 8
        + 4
        + 3 * 8
        + 4
        + 8
        + 4
        + 4
        + 4
        + 3 * 4
}

/// Size in bytes of a block for `n` joints that carries [`RetimeSettings`] (`RLTASK03`).
#[must_use]
pub const fn retime_block_len(n: usize) -> usize {
    block_len(n) + 4 + 8 + n * 8
}

/// Size in bytes of a block for `n` joints with the optional sections asked for: re-timing
/// settings (`retime`) and a two-phase plan (`two_phase`).
#[must_use]
pub const fn sectioned_block_len(n: usize, retime: bool, two_phase: bool) -> usize {
    let base = if retime {
        retime_block_len(n)
    } else {
        block_len(n)
    };
    if two_phase {
        base + TWO_PHASE_LEN
    } else {
        base
    }
}

/// The magic naming the optional sections: (re-timing, two-phase).
const fn magic_of(retime: bool, two_phase: bool) -> [u8; 8] {
    match (retime, two_phase) {
        (false, false) => MAGIC,
        (true, false) => MAGIC_RETIME,
        (false, true) => MAGIC_TWO_PHASE,
        (true, true) => MAGIC_TWO_PHASE_RETIME,
    }
}

/// The optional sections a magic announces: (re-timing, two-phase); `None` for no magic
/// of this version.
fn sections_of(magic: &[u8; 8]) -> Option<(bool, bool)> {
    [(false, false), (true, false), (false, true), (true, true)]
        .into_iter()
        .find(|(r, t)| magic_of(*r, *t) == *magic)
}

/// Re-timing settings a block may carry: the flight image then re-times the finished plan
/// to minimum time ([`crate::retime`]) and streams its setpoints. Validated where they are
/// used ([`crate::retime::Limits::new`], [`crate::retime::PathBuilder::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RetimeSettings<const N: usize> {
    /// Arc-length grid points.
    pub grid: u32,
    /// Limit margin factor in (0, 1].
    pub margin: f64,
    /// Acceleration limit per joint (rad/s²); the rate limits are the robot's.
    pub qdd_max: [f64; N],
}

/// Everything the flight image needs to plan one task.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TaskBlock<const N: usize> {
    /// The robot.
    pub robot: RobotDesc<N>,
    /// Start configuration (rad).
    pub q0: [f64; N],
    /// Target pose (inertial frame).
    pub target: Pose,
    /// Duration (s).
    pub tf_s: f64,
    /// Integration step (s).
    pub dt_s: f64,
    /// Time-law degree.
    pub n: u32,
    /// The motion family ([`Motion::with_family`]).
    pub family: Family,
    /// Segments of the motion ([`Motion::with_segments`], `1..=`[`crate::MAX_SEGMENTS`]).
    pub segments: u32,
    /// How rollouts integrate the path ([`Motion::with_integrator`]).
    pub integrator: Integrator,
    /// Samples per integrator step: 0 for [`Integrator::Euler`], `1..=255` for
    /// [`Integrator::Rk4`] and [`Integrator::Ab5`] ([`Motion::with_integrator_stride`]).
    pub stride: u32,
    /// Planner settings (with the frame budget: integration steps the flight software
    /// gives the planner per frame).
    pub planner: PlannerConfig,
    /// Re-time the plan once it is finished (`RLTASK03`, `RLTASK05`), or not.
    pub retime: Option<RetimeSettings<N>>,
    /// Plan in two phases ([`crate::twophase::plan`] with the planner's seed; `RLTASK04`,
    /// `RLTASK05`), or in one.
    pub two_phase: Option<TwoPhaseConfig>,
}

impl<const N: usize> TaskBlock<N> {
    /// Gives `planner` this block's task and settings, building everything in place (the
    /// robot model, the task, the swarm): nothing planner- or task-sized passes through
    /// the stack. This is how flight software loads a task into a statically allocated
    /// [`Planner`].
    ///
    /// # Errors
    /// Any validation error of the robot, motion, task or settings; the planner is then
    /// idle and [`Planner::step`] returns the error.
    pub fn load_into<const K: usize, const P: usize>(
        &self,
        planner: &mut Planner<N, K, P>,
    ) -> Result<(), Error> {
        let loaded = Motion::new(self.tf_s, self.dt_s, self.n).and_then(|motion| {
            let motion = self.integrate(
                motion
                    .with_family(self.family)
                    .with_segments(self.segments)?,
            )?;
            planner
                .task_mut()
                .init(&self.robot, self.q0, self.target, motion)
        });
        match loaded {
            Ok(()) => planner.restart(self.planner),
            Err(e) => {
                planner.fail(e);
                Err(e)
            }
        }
    }
}

impl<const N: usize> TaskBlock<N> {
    /// `motion` integrated as the block says ([`TaskBlock::integrator`],
    /// [`TaskBlock::stride`]).
    fn integrate(&self, motion: Motion) -> Result<Motion, Error> {
        match self.integrator {
            Integrator::Euler if self.stride == 0 => Ok(motion),
            // What `encode` refuses too: a stride names RK4 or AB5.
            Integrator::Euler => Err(Error::StrideUneven {
                stride: self.stride,
            }),
            other => motion
                .with_integrator(other)?
                .with_integrator_stride(self.stride),
        }
    }

    /// Gives `search` this block's task and two-phase settings, building the task in place
    /// (nothing task-sized passes through the stack), and starts it with the planner's
    /// seed: how flight software loads a two-phase block into a statically allocated
    /// [`TwoPhaseSearch`].
    ///
    /// # Errors
    /// [`Error::NotTwoPhase`] for a single-phase block; any validation error of the robot,
    /// motion, task or settings. The search then returns the error on every step.
    pub fn load_two_phase_into<const K: usize>(
        &self,
        search: &mut TwoPhaseSearch<N, K>,
    ) -> Result<(), Error> {
        let loaded = match &self.two_phase {
            None => Err(Error::NotTwoPhase),
            Some(config) => Motion::new(self.tf_s, self.dt_s, self.n)
                .and_then(|motion| {
                    let motion = self.integrate(
                        motion
                            .with_family(self.family)
                            .with_segments(self.segments)?,
                    )?;
                    search
                        .task_mut()
                        .init(&self.robot, self.q0, self.target, motion)
                })
                .and_then(|()| search.restart(config, self.planner.seed)),
        };
        if let Err(e) = loaded {
            search.fail(e);
        }
        loaded
    }
}

/// CRC-32 (IEEE 802.3, reflected, polynomial `0xEDB88320`), bitwise.
#[must_use]
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for b in bytes {
        crc ^= u32::from(*b);
        for _ in 0..8 {
            let mask = (crc & 1).wrapping_neg();
            crc = (crc >> 1) ^ (0xEDB8_8320 & mask);
        }
    }
    !crc
}

struct Writer<'a> {
    out: &'a mut [u8],
    at: usize,
    overflow: bool,
}

impl Writer<'_> {
    fn bytes(&mut self, b: &[u8]) {
        match self.out.get_mut(self.at..self.at + b.len()) {
            Some(dst) => dst.copy_from_slice(b),
            None => self.overflow = true,
        }
        self.at += b.len();
    }
    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
    fn f64s(&mut self, v: &[f64]) {
        for x in v {
            self.f64(*x);
        }
    }
    fn body(&mut self, b: &BodyDesc) {
        self.f64(b.mass);
        self.f64s(&b.inertial.xyz);
        self.f64s(&b.inertial.rpy);
        let i = &b.inertia;
        self.f64s(&[i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz]);
    }
}

struct Reader<'a> {
    data: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const M: usize>(&mut self) -> Result<[u8; M], Error> {
        let mut out = [0u8; M];
        let src = self
            .data
            .get(self.at..self.at + M)
            .ok_or(Error::Block(BlockFault::Truncated))?;
        out.copy_from_slice(src);
        self.at += M;
        Ok(out)
    }
    fn u32(&mut self) -> Result<u32, Error> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    fn u64(&mut self) -> Result<u64, Error> {
        Ok(u64::from_le_bytes(self.take()?))
    }
    fn f64(&mut self) -> Result<f64, Error> {
        Ok(f64::from_bits(self.u64()?))
    }
    fn f64s<const M: usize>(&mut self) -> Result<[f64; M], Error> {
        let mut out = [0.0; M];
        for v in &mut out {
            *v = self.f64()?;
        }
        Ok(out)
    }
    fn body(&mut self) -> Result<BodyDesc, Error> {
        let mass = self.f64()?;
        let xyz = self.f64s::<3>()?;
        let rpy = self.f64s::<3>()?;
        let [ixx, ixy, ixz, iyy, iyz, izz] = self.f64s::<6>()?;
        Ok(BodyDesc {
            mass,
            inertial: Origin { xyz, rpy },
            inertia: Inertia {
                ixx,
                ixy,
                ixz,
                iyy,
                iyz,
                izz,
            },
        })
    }
}

/// Writes `block` into `out`; returns the number of bytes written
/// ([`sectioned_block_len`]: [`block_len`] without optional sections).
///
/// # Errors
/// [`BlockFault::Truncated`] if `out` is shorter than that.
pub fn encode<const N: usize>(block: &TaskBlock<N>, out: &mut [u8]) -> Result<usize, Error> {
    let (retime, two_phase) = (block.retime.is_some(), block.two_phase.is_some());
    let (magic, len) = (
        magic_of(retime, two_phase),
        sectioned_block_len(N, retime, two_phase),
    );
    let mut w = Writer {
        out,
        at: 0,
        overflow: false,
    };
    w.bytes(&magic);
    w.u32(N as u32);
    w.u32(len as u32);
    w.body(&block.robot.base);
    for j in &block.robot.joints {
        w.f64s(&j.origin.xyz);
        w.f64s(&j.origin.rpy);
        w.f64s(&j.axis);
        w.f64s(&[j.lower, j.upper, j.velocity]);
    }
    for l in &block.robot.links {
        w.body(l);
    }
    w.f64s(&block.robot.end_effector.xyz);
    w.f64s(&block.robot.end_effector.rpy);
    w.f64s(&block.q0);
    w.f64s(&block.target.position);
    w.f64s(&block.target.quat_wxyz);
    w.f64(block.tf_s);
    w.f64(block.dt_s);
    // Bits 20–23 name the integrator where the stride alone does not: 0 for Euler (stride
    // 0) and RK4 (stride ≥ 1, as blocks of ABI version 6 wrote it), 2 for AB5.
    let multistep = match (block.integrator, block.stride) {
        (Integrator::Euler, 0) => 0,
        (Integrator::Rk4, 1..=0xFF) => 0,
        (Integrator::Ab5, 1..=0xFF) => u32::from(Integrator::Ab5.code()),
        _ => return Err(Error::Block(BlockFault::Field)),
    };
    if block.n > 0xFF || block.family.code() > 0xF {
        return Err(Error::Block(BlockFault::Field));
    }
    w.u32(
        block.n
            | (block.stride << 8)
            | (u32::from(block.family.code()) << 16)
            | (multistep << 20)
            | (block.segments.saturating_sub(1).min(0xFF) << 24),
    );
    let p = &block.planner;
    w.u32(p.particles);
    w.u32(p.max_iterations);
    w.f64s(&[p.c1, p.c2, p.w_max, p.w_min, p.tolerance, p.eta_bound]);
    w.u64(p.seed);
    w.u32(p.stagnation.window);
    w.f64s(&[
        p.stagnation.min_relative_improvement,
        p.stagnation.eps1,
        p.stagnation.eps2,
    ]);
    let (flag, tol) = match p.refine_tolerance {
        Some(t) => (1, t),
        None => (0, 0.0),
    };
    w.u32(flag);
    w.f64(tol);
    w.u32(p.refine_max_rollouts);
    w.u32(p.frame_budget);
    w.u32(p.strategy.code());
    w.u32(p.max_rollouts);
    w.u32(p.refine_against.code());
    if let Some(r) = &block.retime {
        w.u32(r.grid);
        w.f64(r.margin);
        w.f64s(&r.qdd_max);
    }
    if let Some(c) = &block.two_phase {
        w.f64s(&[
            c.qdd_max,
            c.max_duration,
            c.max_momentum,
            c.max_torque,
            c.standoff_m,
            c.standoff_rad,
            c.tolerance,
            c.margin,
            c.max_base_disturbance,
        ]);
        w.u32(c.max_rollouts);
    }
    let crc = crc32(w.out.get(..w.at).unwrap_or(&[]));
    w.u32(crc);
    if w.overflow || w.at != len {
        return Err(Error::Block(BlockFault::Truncated));
    }
    Ok(len)
}

/// Reads a block for `N` joints from `data` (trailing bytes after the block are ignored).
///
/// # Errors
/// [`Error::Block`] naming what is wrong: magic, joint count, length, checksum, truncation,
/// or a refine flag other than 0 or 1.
pub fn decode<const N: usize>(data: &[u8]) -> Result<TaskBlock<N>, Error> {
    let mut r = Reader { data, at: 0 };
    let magic = r.take::<8>()?;
    let (with_retime, with_two_phase) =
        sections_of(&magic).ok_or(Error::Block(BlockFault::Magic))?;
    let len = sectioned_block_len(N, with_retime, with_two_phase);
    if r.u32()? as usize != N {
        return Err(Error::Block(BlockFault::JointCount));
    }
    if r.u32()? as usize != len {
        return Err(Error::Block(BlockFault::Length));
    }
    let body = data
        .get(..len - 4)
        .ok_or(Error::Block(BlockFault::Truncated))?;
    let stored = data
        .get(len - 4..len)
        .and_then(|b| b.try_into().ok())
        .map(u32::from_le_bytes)
        .ok_or(Error::Block(BlockFault::Truncated))?;
    if crc32(body) != stored {
        return Err(Error::Block(BlockFault::Checksum));
    }
    let base = r.body()?;
    let mut joints = [JointDesc {
        origin: Origin::IDENTITY,
        axis: [0.0; 3],
        lower: 0.0,
        upper: 0.0,
        velocity: 0.0,
    }; N];
    for j in &mut joints {
        let xyz = r.f64s::<3>()?;
        let rpy = r.f64s::<3>()?;
        let axis = r.f64s::<3>()?;
        let [lower, upper, velocity] = r.f64s::<3>()?;
        *j = JointDesc {
            origin: Origin { xyz, rpy },
            axis,
            lower,
            upper,
            velocity,
        };
    }
    let mut links = [base; N];
    for l in &mut links {
        *l = r.body()?;
    }
    let ee = Origin {
        xyz: r.f64s::<3>()?,
        rpy: r.f64s::<3>()?,
    };
    let mut q0 = [0.0; N];
    for q in &mut q0 {
        *q = r.f64()?;
    }
    let target = Pose {
        position: r.f64s::<3>()?,
        quat_wxyz: r.f64s::<4>()?,
    };
    let tf_s = r.f64()?;
    let dt_s = r.f64()?;
    let degree_family = r.u32()?;
    let n = degree_family & 0xFF;
    let stride = (degree_family >> 8) & 0xFF;
    let family = u8::try_from((degree_family >> 16) & 0xF)
        .ok()
        .and_then(Family::from_code)
        .ok_or(Error::Block(BlockFault::Field))?;
    let integrator = match ((degree_family >> 20) & 0xF, stride) {
        (0, 0) => Integrator::Euler,
        (0, _) => Integrator::Rk4,
        (2, 1..) => Integrator::Ab5,
        _ => return Err(Error::Block(BlockFault::Field)),
    };
    let segments = (degree_family >> 24) + 1;
    let particles = r.u32()?;
    let max_iterations = r.u32()?;
    let [c1, c2, w_max, w_min, tolerance, eta_bound] = r.f64s::<6>()?;
    let seed = r.u64()?;
    let window = r.u32()?;
    let [min_relative_improvement, eps1, eps2] = r.f64s::<3>()?;
    let flag = r.u32()?;
    let refine_tolerance = r.f64()?;
    let refine_rollouts = r.u32()?;
    let frame_budget = r.u32()?;
    let strategy = Strategy::from_code(r.u32()?).ok_or(Error::Block(BlockFault::Field))?;
    let max_rollouts = r.u32()?;
    let refine_against =
        RefineAgainst::from_code(r.u32()?).ok_or(Error::Block(BlockFault::Field))?;
    let retime = if with_retime {
        let grid = r.u32()?;
        let margin = r.f64()?;
        let qdd_max = r.f64s::<N>()?;
        Some(RetimeSettings {
            grid,
            margin,
            qdd_max,
        })
    } else {
        None
    };
    let two_phase = if with_two_phase {
        let [
            qdd_max,
            max_duration,
            max_momentum,
            max_torque,
            standoff_m,
            standoff_rad,
            tolerance,
            margin,
            max_base_disturbance,
        ] = r.f64s::<9>()?;
        Some(TwoPhaseConfig {
            qdd_max,
            max_duration,
            max_momentum,
            max_torque,
            standoff_m,
            standoff_rad,
            tolerance,
            max_rollouts: r.u32()?,
            margin,
            max_base_disturbance,
            // The planner's refinement says which model phase 2's goal is on (as
            // host-sim's `Asked::against_truth`: a refinement tolerance, on the truth).
            against_truth: flag == 1 && refine_against == RefineAgainst::Truth,
        })
    } else {
        None
    };
    let refine_tolerance = match flag {
        0 => None,
        1 => Some(refine_tolerance),
        _ => return Err(Error::Block(BlockFault::Field)),
    };
    Ok(TaskBlock {
        robot: RobotDesc {
            base,
            joints,
            links,
            end_effector: ee,
        },
        q0,
        target,
        tf_s,
        dt_s,
        n,
        family,
        segments,
        integrator,
        stride,
        planner: PlannerConfig {
            strategy,
            max_rollouts,
            particles,
            max_iterations,
            c1,
            c2,
            w_max,
            w_min,
            tolerance,
            eta_bound,
            seed,
            refine_tolerance,
            refine_max_rollouts: refine_rollouts,
            refine_against,
            frame_budget,
            stagnation: StagnationConfig {
                window,
                min_relative_improvement,
                eps1,
                eps2,
            },
        },
        retime,
        two_phase,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::model::CHASER7;
    use crate::reference::{Q0_DEG, TARGET};

    fn block() -> TaskBlock<7> {
        let mut planner = PlannerConfig::reference(42);
        planner.refine_tolerance = Some(1e-6);
        planner.refine_max_rollouts = 300;
        TaskBlock {
            robot: CHASER7,
            q0: Q0_DEG.map(f64::to_radians),
            target: TARGET,
            tf_s: 30.0,
            dt_s: 0.01,
            n: 1,
            family: Family::Paper,
            segments: 1,
            integrator: Integrator::Euler,
            stride: 0,
            planner,
            retime: None,
            two_phase: None,
        }
    }

    fn retime_block() -> TaskBlock<7> {
        TaskBlock {
            retime: Some(RetimeSettings {
                grid: 2000,
                margin: 0.95,
                qdd_max: [5f64.to_radians(); 7],
            }),
            ..block()
        }
    }

    /// Every single-byte corruption of the encoded block `bytes`, and its last byte cut off,
    /// fail to decode.
    fn every_flip_and_truncation_is_caught(bytes: &[u8]) {
        let n = bytes.len();
        for i in 0..n {
            let mut bad = [0u8; 4096];
            bad[..n].copy_from_slice(bytes);
            bad[i] ^= 0x10;
            assert!(decode::<7>(&bad[..n]).is_err(), "flip at byte {i}");
        }
        assert_eq!(
            decode::<7>(&bytes[..bytes.len() - 1]),
            Err(Error::Block(BlockFault::Truncated))
        );
    }

    /// CRC-32 of "123456789" is the standard check value 0xCBF43926.
    /// Verifies RL-BLOCK-002.
    #[test]
    fn crc32_known_answer() {
        // The standard check value of CRC-32/ISO-HDLC.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    /// A block encodes to `block_len(7)` bytes and decodes to itself exactly.
    /// Verifies RL-BLOCK-001.
    #[test]
    fn roundtrip_is_exact() {
        let mut buf = [0u8; 4096];
        let len = encode(&block(), &mut buf).unwrap();
        assert_eq!(len, block_len(7));
        assert_eq!(decode::<7>(&buf[..len]).unwrap(), block());
    }

    /// A block with re-timing settings is written as `RLTASK03`, `retime_block_len(7)`
    /// bytes, decodes to itself exactly, and every single-byte corruption of it is caught;
    /// without them the bytes are those of `RLTASK02`.
    /// Verifies RL-BLOCK-006.
    #[test]
    fn retime_settings_roundtrip_and_are_checked() {
        let mut buf = [0u8; 4096];
        let len = encode(&retime_block(), &mut buf).unwrap();
        assert_eq!(len, retime_block_len(7));
        assert_eq!(&buf[..8], &MAGIC_RETIME);
        assert_eq!(decode::<7>(&buf[..len]).unwrap(), retime_block());
        every_flip_and_truncation_is_caught(&buf[..len]);
        let mut plain = [0u8; 4096];
        let n = encode(&block(), &mut plain).unwrap();
        assert_eq!(&plain[..8], &MAGIC);
        // The shared prefix (after magic and length) is the same bytes.
        assert_eq!(&plain[16..n - 4], &buf[16..n - 4]);
    }

    /// The family rides in `n`'s upper half: a free-amplitude block round-trips, differs
    /// from the paper's only in that word (and the CRC), loads a planner whose task has
    /// that family; an unknown family code is a field error.
    /// Verifies RL-BLOCK-007.
    #[test]
    fn the_motion_family_rides_in_the_degree_word() {
        let free = TaskBlock {
            family: Family::FreeAmplitude,
            ..block()
        };
        let (mut a, mut b) = ([0u8; 4096], [0u8; 4096]);
        let len = encode(&block(), &mut a).unwrap();
        assert_eq!(encode(&free, &mut b).unwrap(), len);
        assert_eq!(decode::<7>(&b[..len]).unwrap(), free);
        // Offset of the degree word: header, base, joints, links, end effector, start,
        // target, t_f and dt.
        let word = 16 + 13 * 8 + 7 * 12 * 8 + 7 * 13 * 8 + 6 * 8 + 7 * 8 + 7 * 8 + 2 * 8;
        assert_eq!(u32::from_le_bytes(a[word..word + 4].try_into().unwrap()), 1);
        assert_eq!(
            u32::from_le_bytes(b[word..word + 4].try_into().unwrap()),
            1 | 1 << 16
        );
        for i in (0..len - 4).filter(|&i| i != word + 2) {
            assert_eq!(a[i], b[i], "byte {i}");
        }
        let mut planner = Planner::<7, 4, 64>::IDLE;
        decode::<7>(&b[..len])
            .unwrap()
            .load_into(&mut planner)
            .unwrap();
        assert_eq!(planner.task().motion().family(), Family::FreeAmplitude);
        // Code 2 (no such family), the CRC recomputed so that only the field is wrong.
        b[word + 2] = 2;
        let crc = crc32(&b[..len - 4]);
        b[len - 4..len].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(decode::<7>(&b[..len]), Err(Error::Block(BlockFault::Field)));
    }

    /// RK4's stride rides in bits 8–15 of the degree word: an RK4 block round-trips,
    /// differs from Euler's only in that byte (and the CRC), and loads a planner whose task
    /// integrates by RK4 with that stride; a stride that does not divide the steps is the
    /// motion's error.
    /// Verifies RL-CONT-007.
    #[test]
    fn the_rk4_stride_rides_in_the_degree_word() {
        let rk4 = TaskBlock {
            integrator: Integrator::Rk4,
            stride: 40,
            ..block()
        };
        let (mut a, mut b) = ([0u8; 4096], [0u8; 4096]);
        let len = encode(&block(), &mut a).unwrap();
        assert_eq!(encode(&rk4, &mut b).unwrap(), len);
        assert_eq!(decode::<7>(&b[..len]).unwrap(), rk4);
        let word = 16 + 13 * 8 + 7 * 12 * 8 + 7 * 13 * 8 + 6 * 8 + 7 * 8 + 7 * 8 + 2 * 8;
        assert_eq!(
            u32::from_le_bytes(b[word..word + 4].try_into().unwrap()),
            1 | 40 << 8
        );
        for i in (0..len - 4).filter(|&i| i != word + 1) {
            assert_eq!(a[i], b[i], "byte {i}");
        }
        let mut planner = Planner::<7, 4, 64>::IDLE;
        rk4.load_into(&mut planner).unwrap();
        let m = planner.task().motion();
        assert_eq!((m.integrator(), m.stride()), (Integrator::Rk4, 40));
        let odd = TaskBlock {
            integrator: Integrator::Rk4,
            stride: 7,
            ..block()
        };
        assert_eq!(
            odd.load_into(&mut planner),
            Err(Error::StrideUneven { stride: 7 })
        );
        let wide = TaskBlock {
            integrator: Integrator::Rk4,
            stride: 256,
            ..block()
        };
        assert_eq!(encode(&wide, &mut b), Err(Error::Block(BlockFault::Field)));
        for (integrator, stride) in [(Integrator::Euler, 40), (Integrator::Ab5, 0)] {
            let bad = TaskBlock {
                integrator,
                stride,
                ..block()
            };
            assert_eq!(encode(&bad, &mut b), Err(Error::Block(BlockFault::Field)));
        }
        // Loading refuses a stride for Euler too (a stride names RK4 or AB5).
        let euler_with_stride = TaskBlock {
            stride: 40,
            ..block()
        };
        assert_eq!(
            euler_with_stride.load_into(&mut planner),
            Err(Error::StrideUneven { stride: 40 })
        );
    }

    /// An AB5 block carries its stride as RK4's does and code 2 in bits 20–23 of the degree
    /// word, and loads a planner whose task integrates by AB5; code 2 without a stride, or
    /// an unknown code, is refused.
    /// Verifies RL-CONT-009.
    #[test]
    fn an_ab5_block_names_its_integrator_in_the_degree_word() {
        let ab5 = TaskBlock {
            integrator: Integrator::Ab5,
            stride: 20,
            ..block()
        };
        let mut b = [0u8; 4096];
        let len = encode(&ab5, &mut b).unwrap();
        assert_eq!(decode::<7>(&b[..len]).unwrap(), ab5);
        let word = 16 + 13 * 8 + 7 * 12 * 8 + 7 * 13 * 8 + 6 * 8 + 7 * 8 + 7 * 8 + 2 * 8;
        assert_eq!(
            u32::from_le_bytes(b[word..word + 4].try_into().unwrap()),
            1 | 20 << 8 | 2 << 20
        );
        let mut planner = Planner::<7, 4, 64>::IDLE;
        ab5.load_into(&mut planner).unwrap();
        let m = planner.task().motion();
        assert_eq!((m.integrator(), m.stride()), (Integrator::Ab5, 20));
        for word_value in [1 | 2 << 20, 1 | 20 << 8 | 3 << 20] {
            let mut c = b;
            c[word..word + 4].copy_from_slice(&u32::to_le_bytes(word_value));
            let crc = crc32(&c[..len - 4]);
            c[len - 4..len].copy_from_slice(&crc.to_le_bytes());
            assert_eq!(
                decode::<7>(&c[..len]),
                Err(Error::Block(BlockFault::Field)),
                "{word_value:#x}"
            );
        }
    }

    /// A two-phase block is written as `RLTASK04` (with re-timing settings `RLTASK05`),
    /// `sectioned_block_len` bytes, decodes to itself exactly, every single-byte corruption
    /// of it is caught, and before its section it holds the bytes of the single-phase block.
    /// Verifies RL-BLOCK-008.
    #[test]
    fn two_phase_settings_roundtrip_and_are_checked() {
        let config = TwoPhaseConfig {
            max_rollouts: 4000,
            ..TwoPhaseConfig::reference()
        };
        for (base, magic, retime) in [
            (block(), MAGIC_TWO_PHASE, false),
            (retime_block(), MAGIC_TWO_PHASE_RETIME, true),
        ] {
            let two = TaskBlock {
                two_phase: Some(config),
                ..base
            };
            let mut buf = [0u8; 4096];
            let len = encode(&two, &mut buf).unwrap();
            assert_eq!(len, sectioned_block_len(7, retime, true));
            assert_eq!(len, sectioned_block_len(7, retime, false) + 76);
            assert_eq!(&buf[..8], &magic);
            assert_eq!(decode::<7>(&buf[..len]).unwrap(), two);
            every_flip_and_truncation_is_caught(&buf[..len]);
            let mut one = [0u8; 4096];
            let n = encode(&base, &mut one).unwrap();
            assert_eq!(&one[16..n - 4], &buf[16..n - 4]);
        }
    }

    /// Every single-byte corruption, a wrong joint count, truncation and a short buffer are
    /// typed block errors.
    /// Verifies RL-BLOCK-003.
    #[test]
    fn every_corruption_is_caught() {
        let mut buf = [0u8; 4096];
        let len = encode(&block(), &mut buf).unwrap();
        for i in 0..len {
            let mut bad = buf;
            bad[i] ^= 0x10;
            assert!(
                decode::<7>(&bad[..len]).is_err(),
                "flip at byte {i} not detected"
            );
        }
        assert_eq!(
            decode::<6>(&buf[..len]),
            Err(Error::Block(BlockFault::JointCount))
        );
        assert_eq!(
            decode::<7>(&buf[..len - 1]),
            Err(Error::Block(BlockFault::Truncated))
        );
        assert_eq!(
            encode(&block(), &mut buf[..100]),
            Err(Error::Block(BlockFault::Truncated))
        );
    }
}
