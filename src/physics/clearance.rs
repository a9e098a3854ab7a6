//! The clearance constraint of planning (spec §13): the robot's collision primitives
//! carried into the frames the rollout computes, the task's keep-outs, the checked pairs,
//! and a lower bound of the clearance over one integration step.
//!
//! Owns [`CollisionSet`] (fixed capacity: [`MAX_PRIMITIVES`], [`MAX_KEEP_OUTS`], bodies
//! below [`MAX_BODIES`]) and the pairs it checks, spec §13's: two primitives on bodies two
//! or more joints apart (so the base against links 2 and on), and every primitive against
//! every keep-out, less the body pairs the caller ignores ([`CollisionSet::ignore`]).
//!
//! **The bound of one step.** Between configurations `q` and `q + Δq` on the straight
//! joint path, a point carried by body `b` moves at most `Σ_{j≤b} |Δq_j| ρ_j` relative to
//! the base, where `ρ_j` bounds the distance from joint `j` to any point of a primitive it
//! carries (the joint offsets along the chain plus the primitive's reach about its body's
//! origin), and the base moves at most `Σ_j |Δq_j| ρ_j m_{≥j}/M` (the system centre of
//! mass is fixed; `m_{≥j}` the mass joint `j` carries). The signed distance is
//! 1-Lipschitz in the motion of either solid, and a rigid motion common to both bodies of
//! a pair changes nothing, so over the step a pair's distance stays above `d(q) − δ`:
//! - bodies `a < b`: `δ = Σ_{a<j≤b} |Δq_j| ρ_j` (joints up to `a` move both alike);
//! - body `b` against a keep-out: `δ = Σ_{j≤b} |Δq_j| ρ_j` plus the base's motion.
//!
//! [`CollisionSet::step_bound`] returns the smallest `d(q) − δ` over the pairs, or the
//! limit `clearance + margin` if every pair is above it. A pair whose bounding balls are
//! farther apart than the limit plus `δ` is not evaluated (one squared distance), so a
//! step costs two centre placements per pair and a signed distance only for the pairs near
//! the limit. Evaluated at every sample of an Euler rollout with the step that follows it,
//! the smallest bound covers the whole written path (the last sample ends a step that was
//! covered): a path the planner calls clear keeps the clearance between samples too, and
//! the bound is below the path's true clearance by at most the largest `δ` of a step.

use crate::collision::{Placed, signed_distance};
use crate::error::{Error, Param};
use crate::geometry::{Mat3, Vec3, mat_vec};
use crate::kinematics::Frames;
use crate::model::Robot;
use heapless::Vec as Capped;

/// Most collision primitives on one robot (the base and the links together).
pub const MAX_PRIMITIVES: usize = 16;
/// Most keep-outs in one task.
pub const MAX_KEEP_OUTS: usize = 8;
/// Bodies (the base and links `1..`) a collision set can name: primitives go on bodies
/// `0..MAX_BODIES`.
pub const MAX_BODIES: usize = 16;

/// One side of an ignored pair ([`CollisionSet::ignore`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Side {
    /// Body `i`: 0 the base, `i` link `i`.
    Body(u8),
    /// Keep-out `k`, by the index [`CollisionSet::add_keep_out`] returned.
    KeepOut(u8),
}

/// A primitive on a body, in that body's rollout frame.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Primitive {
    /// 0 the base, `i` link `i`.
    body: u8,
    /// The primitive's frame in the body's joint frame (the base frame for the base).
    local: Placed,
    /// [`crate::collision::Shape::bounding_radius`] (m).
    radius: f64,
}

/// The collision geometry a rollout evaluates: robot primitives, keep-outs (inertial
/// frame), the ignored pairs, the required clearance and the planning margin above it.
///
/// Build with [`CollisionSet::new`], the `add_` methods and [`CollisionSet::ignore`], then
/// give it to a task ([`crate::Task::with_collision`]), which bounds its motion on the
/// task's robot. `size_of::<CollisionSet<7>>()` is 3,632 bytes (the capacities, whatever
/// is used).
#[derive(Debug, Clone, PartialEq)]
pub struct CollisionSet<const N: usize> {
    primitives: Capped<Primitive, MAX_PRIMITIVES>,
    keep_outs: Capped<(Placed, f64), MAX_KEEP_OUTS>,
    /// Bit `b` of entry `a`: bodies `a` and `b` are not checked against each other.
    ignored: [u16; MAX_BODIES],
    /// Bit `b` of entry `k`: keep-out `k` is not checked against body `b`.
    ignored_keep_outs: [u16; MAX_KEEP_OUTS],
    required: f64,
    margin: f64,
    /// `ρ_j` (m per rad).
    reach: [f64; N],
    /// `ρ_j m_{≥j}/M` (m per rad).
    base_reach: [f64; N],
}

impl<const N: usize> CollisionSet<N> {
    /// No geometry: a task with it plans as if it had none (the reference behaviour, bit
    /// for bit).
    pub const EMPTY: Self = Self {
        primitives: Capped::new(),
        keep_outs: Capped::new(),
        ignored: [0; MAX_BODIES],
        ignored_keep_outs: [0; MAX_KEEP_OUTS],
        required: 0.0,
        margin: 0.0,
        reach: [0.0; N],
        base_reach: [0.0; N],
    };

    /// An empty set for a required clearance `required_m` (m, ≥ 0: a path must keep every
    /// checked pair at least this far apart) and a planning margin `margin_m` (m, ≥ 0):
    /// how far above the required clearance the default strategy aims, and where the
    /// step bound stops evaluating.
    ///
    /// # Errors
    /// [`Error::NotFinite`] or [`Error::Negative`] of [`Param::Clearance`].
    pub fn new(required_m: f64, margin_m: f64) -> Result<Self, Error> {
        for v in [required_m, margin_m] {
            if !v.is_finite() {
                return Err(Error::NotFinite(Param::Clearance));
            }
            if v < 0.0 {
                return Err(Error::Negative(Param::Clearance));
            }
        }
        Ok(Self {
            required: required_m,
            margin: margin_m,
            ..Self::EMPTY
        })
    }

    /// Adds a primitive on `body` (0 the base, `1..=N` link `i`): `local` is its shape and
    /// its frame in that body's URDF frame (attitude a rotation matrix, origin in m), and
    /// returns its index.
    ///
    /// # Errors
    /// [`Error::NotFinite`] of [`Param::Collider`] for a frame that is not finite or a body
    /// above `N` or [`MAX_BODIES`]; [`Error::Negative`] for a size that is negative or not finite;
    /// [`Error::CapacityExceeded`] past [`MAX_PRIMITIVES`].
    pub fn add_primitive(
        &mut self,
        robot: &Robot<N>,
        body: u8,
        local: &Placed,
    ) -> Result<u8, Error> {
        let index = self.primitives.len();
        let param = Param::Collider(u8::try_from(index + 1).unwrap_or(u8::MAX));
        check(local, param)?;
        if usize::from(body) > N || usize::from(body) >= MAX_BODIES {
            return Err(Error::NotFinite(param));
        }
        let (mut rot, mut pos) = (local.rot, local.pos);
        if let Some(q) = robot
            .link_attitudes()
            .get(usize::from(body).wrapping_sub(1))
        {
            let qt = q.transpose();
            rot = qt * rot;
            pos = qt * pos;
        }
        let p = Primitive {
            body,
            local: Placed {
                shape: local.shape,
                rot,
                pos,
            },
            radius: local.shape.bounding_radius(),
        };
        self.primitives
            .push(p)
            .map_err(|_| capacity(param, index, MAX_PRIMITIVES))?;
        Ok(index as u8)
    }

    /// Adds a keep-out, `placed` in the inertial frame (the base frame at `t = 0`), and
    /// returns its index.
    ///
    /// # Errors
    /// As [`CollisionSet::add_primitive`], of [`Param::KeepOut`] and [`MAX_KEEP_OUTS`].
    pub fn add_keep_out(&mut self, placed: &Placed) -> Result<u8, Error> {
        let index = self.keep_outs.len();
        let param = Param::KeepOut(u8::try_from(index + 1).unwrap_or(u8::MAX));
        check(placed, param)?;
        self.keep_outs
            .push((*placed, placed.shape.bounding_radius()))
            .map_err(|_| capacity(param, index, MAX_KEEP_OUTS))?;
        Ok(index as u8)
    }

    /// Leaves the pair `a`, `b` unchecked (`[collision] ignore`): two bodies, or a body and
    /// a keep-out, in either order.
    ///
    /// # Errors
    /// [`Error::NotFinite`] of [`Param::CollisionPair`] for a body at or above
    /// [`MAX_BODIES`], a keep-out not added yet, or two keep-outs (never checked).
    pub fn ignore(&mut self, a: Side, b: Side) -> Result<(), Error> {
        let bad = Error::NotFinite(Param::CollisionPair);
        let bit = |i: u8| {
            1u16.checked_shl(u32::from(i))
                .filter(|_| usize::from(i) < MAX_BODIES)
        };
        match (a, b) {
            (Side::Body(i), Side::Body(j)) => {
                let (bi, bj) = (bit(i).ok_or(bad)?, bit(j).ok_or(bad)?);
                for (row, m) in [(i, bj), (j, bi)] {
                    let slot = self.ignored.get_mut(usize::from(row)).ok_or(bad)?;
                    *slot |= m;
                }
            }
            (Side::Body(i), Side::KeepOut(k)) | (Side::KeepOut(k), Side::Body(i)) => {
                let m = bit(i).ok_or(bad)?;
                if usize::from(k) >= self.keep_outs.len() {
                    return Err(bad);
                }
                let slot = self.ignored_keep_outs.get_mut(usize::from(k)).ok_or(bad)?;
                *slot |= m;
            }
            (Side::KeepOut(_), Side::KeepOut(_)) => return Err(bad),
        }
        Ok(())
    }

    /// `true` if primitives on bodies `a < b` are checked against each other.
    fn checks(&self, a: u8, b: u8) -> bool {
        b >= a.saturating_add(2)
            && self
                .ignored
                .get(usize::from(a))
                .is_some_and(|m| m & (1u16 << (b & 15)) == 0)
    }

    /// `true` if keep-out `k` is checked against body `b`.
    fn checks_keep_out(&self, k: usize, b: u8) -> bool {
        self.ignored_keep_outs
            .get(k)
            .is_some_and(|m| m & (1u16 << (b & 15)) == 0)
    }

    /// The checked pairs of primitives (a primitive against a primitive or a keep-out).
    #[must_use]
    pub fn pair_count(&self) -> usize {
        let mut n = 0;
        for (i, a) in self.primitives.iter().enumerate() {
            for b in self.primitives.iter().skip(i + 1) {
                let (lo, hi) = (a.body.min(b.body), a.body.max(b.body));
                n += usize::from(self.checks(lo, hi));
            }
            for k in 0..self.keep_outs.len() {
                n += usize::from(self.checks_keep_out(k, a.body));
            }
        }
        n
    }

    /// `true` if no pair is checked.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.pair_count() == 0
    }

    /// The required clearance (m).
    #[must_use]
    pub fn required(&self) -> f64 {
        self.required
    }

    /// The required clearance plus the planning margin (m): where
    /// [`CollisionSet::step_bound`] stops evaluating.
    #[must_use]
    pub fn limit(&self) -> f64 {
        self.required + self.margin
    }

    /// `*self = source.clone()` element by element, with no set-sized temporary (the
    /// flight stack).
    pub(crate) fn copy_from(&mut self, source: &Self) {
        self.primitives.clear();
        for p in &source.primitives {
            // The same capacity: every push fits.
            let _ = self.primitives.push(*p);
        }
        self.keep_outs.clear();
        for k in &source.keep_outs {
            let _ = self.keep_outs.push(*k);
        }
        self.ignored = source.ignored;
        self.ignored_keep_outs = source.ignored_keep_outs;
        self.required = source.required;
        self.margin = source.margin;
        self.reach = source.reach;
        self.base_reach = source.base_reach;
    }

    /// Bounds the motion of every primitive on `robot` (`ρ_j` and the base's share):
    /// called once by [`crate::Task::with_collision`].
    pub(crate) fn bound(&mut self, robot: &Robot<N>) {
        // How far a point of body k (k ≥ 1) can be from its joint: its primitives, its
        // centre of mass (for the base's motion) and, for the last link, the end effector.
        let mut extent = [0.0f64; N];
        for (k, (e, seg)) in extent.iter_mut().zip(robot.segments.iter()).enumerate() {
            *e = norm(&seg.com);
            for p in self
                .primitives
                .iter()
                .filter(|p| usize::from(p.body) == k + 1)
            {
                *e = e.max(norm(&p.local.pos) + p.radius);
            }
            if k + 1 == N {
                *e = e.max(norm(&robot.ee_offset));
            }
        }
        let total = robot.total_mass();
        for j in 0..N {
            let (mut path, mut best, mut carried) = (0.0f64, 0.0f64, 0.0f64);
            for k in j..N {
                if k > j {
                    path += robot.segments.get(k).map_or(0.0, |s| norm(&s.offset));
                }
                best = best.max(path + extent.get(k).copied().unwrap_or(0.0));
                carried += robot.segments.get(k).map_or(0.0, |s| s.mass);
            }
            if let Some(r) = self.reach.get_mut(j) {
                *r = best;
            }
            if let Some(r) = self.base_reach.get_mut(j) {
                *r = best * carried / total;
            }
        }
    }

    /// A lower bound of the clearance (m) over the straight joint path from the
    /// configuration of `frames` (base frame) by `qd·dt` (rad/s, s), with the base placed
    /// so that the system centre of mass is at `com0` (m, inertial frame) and its attitude
    /// the identity (the planner model): the smallest `d − δ` over the checked pairs (see
    /// the module documentation), or [`CollisionSet::limit`] if none is below it.
    #[must_use]
    pub fn step_bound(&self, frames: &Frames<N>, com0: &Vec3, qd: &[f64; N], dt: f64) -> f64 {
        let limit = self.limit();
        // Motion of body b's points relative to the base: prefix[b − 1] (m).
        let mut prefix = [0.0f64; N];
        let (mut acc, mut base) = (0.0, 0.0);
        for (((p, v), r), rb) in prefix
            .iter_mut()
            .zip(qd.iter())
            .zip(self.reach.iter())
            .zip(self.base_reach.iter())
        {
            let dq = libm::fabs(*v) * dt;
            acc += dq * r;
            base += dq * rb;
            *p = acc;
        }
        let moved = |body: u8| {
            usize::from(body)
                .checked_sub(1)
                .and_then(|i| prefix.get(i))
                .copied()
                .unwrap_or(0.0)
        };
        let shift = com0 - frames.com;
        let frame = |body: u8| -> (Mat3, Vec3) {
            match usize::from(body)
                .checked_sub(1)
                .and_then(|i| frames.links.get(i))
            {
                Some(l) => (l.rot, l.joint + shift),
                None => (Mat3::identity(), shift),
            }
        };
        let mut low = limit;
        for (i, a) in self.primitives.iter().enumerate() {
            let (ra, ta) = frame(a.body);
            let ca = ta + mat_vec(&ra, &a.local.pos);
            let others = self
                .primitives
                .iter()
                .skip(i + 1)
                .filter(|b| self.checks(a.body.min(b.body), a.body.max(b.body)))
                .map(|b| {
                    let (r, t) = frame(b.body);
                    let delta = libm::fabs(moved(b.body) - moved(a.body));
                    (b.local, r, t + mat_vec(&r, &b.local.pos), b.radius, delta)
                });
            let keep_outs = self
                .keep_outs
                .iter()
                .enumerate()
                .filter(|(k, _)| self.checks_keep_out(*k, a.body))
                .map(|(_, (p, radius))| {
                    (*p, Mat3::identity(), p.pos, *radius, moved(a.body) + base)
                });
            // The other side: its shape in its frame, that frame's attitude, its centre, its
            // bounding radius, and δ.
            for (other, rb, cb, radius, delta) in others.chain(keep_outs) {
                // Broad phase: d ≥ |c_a − c_b| − r_a − r_b, so the pair cannot lower `low`
                // when its bounding balls are farther apart than `low + δ` (always, if that
                // is < 0).
                let gap = low + delta + a.radius + radius;
                let dc = ca - cb;
                if gap < 0.0 || dc.dot(&dc) > gap * gap {
                    continue;
                }
                let pa = Placed {
                    shape: a.local.shape,
                    rot: ra * a.local.rot,
                    pos: ca,
                };
                let pb = Placed {
                    shape: other.shape,
                    rot: rb * other.rot,
                    pos: cb,
                };
                low = low.min(signed_distance(&pa, &pb) - delta);
            }
        }
        low
    }
}

/// A placed primitive's frame is finite and its sizes are finite and ≥ 0.
fn check(p: &Placed, param: Param) -> Result<(), Error> {
    if !(p.rot.iter().chain(p.pos.iter()).all(|v| v.is_finite())) {
        return Err(Error::NotFinite(param));
    }
    if !p.shape.is_valid() {
        return Err(Error::Negative(param));
    }
    Ok(())
}

fn capacity(param: Param, index: usize, capacity: usize) -> Error {
    Error::CapacityExceeded {
        param,
        requested: (index + 1) as u32,
        capacity: capacity as u32,
    }
}

fn norm(v: &Vec3) -> f64 {
    libm::sqrt(v.dot(v))
}
