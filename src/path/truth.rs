//! The truth model (spec §5 and §11): the base attitude that a joint path really produces.
//!
//! Owns [`TruthState`], the integrator state (no reference to the task, so a planner can
//! keep one between budgeted calls), and [`TruthModel`], a [`Sink`] that feeds it the
//! samples of a rollout. The joint path is piecewise linear between the samples; each
//! segment is integrated with `m` midpoint sub-steps
//! ([`crate::integrator::midpoint_substep`]), which can be resumed between sub-steps:
//!
//! - zero angular momentum (spec §5): `δθ = −H~b⁻¹ H~bm(q_mid) δq` (base frame), which
//!   depends only on the joint increment: the path as written is what is checked;
//! - angular momentum `L ≠ 0` about the system CoM (inertial frame, spec §11, from an
//!   initial base rate): `δθ = H~b⁻¹(q_mid) (R₀ᵀ L δt − H~bm(q_mid) δq)`, with `R₀` the base
//!   attitude at the start of the sub-step and `δt` the sub-step's share of the segment's
//!   duration.
//!
//! The base disturbance is the largest base rotation angle over the motion; the truth
//! end pose ([`TruthState::end_pose`]) places the end effector with the integrated base
//! attitude and the base by CoM conservation.

use crate::error::Error;
use crate::geometry::{Pose, Vec3, normalized, quat_angle, quat_exp, quat_matrix, quat_mul};
use crate::integrator::midpoint_substep;
use crate::kinematics::{Frames, IDENTITY_WXYZ};
use crate::momentum::Momentum;
use crate::rollout::{Sample, Sink};
use crate::task::Task;

/// Smallest number of midpoint sub-steps per segment the specification accepts.
pub const MIN_SUBSTEPS: u32 = 10;

/// Midpoint sub-steps per segment wherever this project runs the truth model: the
/// planner's truth-evaluated candidates, `host-sim` (`check`, summaries, dispersions) and
/// the flight image.
pub const TRUTH_SUBSTEPS: u32 = MIN_SUBSTEPS;

/// The truth model's state along a joint path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthState<const N: usize> {
    substeps: u32,
    /// The last sample: configuration (rad) and time (s).
    last: Option<([f64; N], f64)>,
    attitude: [f64; 4],
    max_angle: f64,
    error: Option<Error>,
    segments: u32,
    /// Angular momentum about the system CoM, inertial frame (kg m²/s).
    momentum: Vec3,
    /// The segment being integrated (resumable): from, to, duration of a sub-step, next j.
    pending: Option<Segment<N>>,
}

/// A segment whose sub-steps are not all integrated yet.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment<const N: usize> {
    from: [f64; N],
    to: [f64; N],
    dt: f64,
    next: u32,
}

impl<const N: usize> TruthState<N> {
    /// At rest at the start (identity attitude, zero momentum), `substeps` midpoint
    /// sub-steps per segment (at least [`MIN_SUBSTEPS`] is used).
    #[must_use]
    pub fn new(substeps: u32) -> Self {
        Self {
            substeps: substeps.max(MIN_SUBSTEPS),
            last: None,
            attitude: IDENTITY_WXYZ,
            max_angle: 0.0,
            error: None,
            segments: 0,
            momentum: Vec3::new(0.0, 0.0, 0.0),
            pending: None,
        }
    }

    /// The same with angular momentum `l` (kg m²/s, inertial frame, about the system CoM),
    /// constant along the motion. For an initial base rate `ω(0)` (rad/s, base frame) with
    /// the arm at rest, `L = R₀(0)·H~b(q₀)·ω(0)` (spec §11), and `R₀(0)` is the identity.
    #[must_use]
    pub fn with_momentum(mut self, l: [f64; 3]) -> Self {
        self.momentum = Vec3::new(l[0], l[1], l[2]);
        self
    }

    /// Integrates the segment from the previous sample to configuration `q` (rad) at time
    /// `t` (s), with the robot of `task`.
    pub fn push<const K: usize>(&mut self, task: &Task<N, K>, q: &[f64; N], t: f64) {
        self.begin(q, t);
        let _ = self.integrate(task, u32::MAX);
    }

    /// Starts the segment to the sample `(q, t)`: [`TruthState::integrate`] then works
    /// through its sub-steps (the first sample only sets the start). A segment still
    /// pending is finished first.
    pub fn begin(&mut self, q: &[f64; N], t: f64) {
        if self.pending.is_some() {
            // Not expected: callers integrate a segment before starting the next.
            return;
        }
        if let Some((prev, t_prev)) = self.last.replace((*q, t)) {
            if self.error.is_none() {
                self.pending = Some(Segment {
                    from: prev,
                    to: *q,
                    dt: (t - t_prev) / f64::from(self.substeps),
                    next: 0,
                });
            }
        }
    }

    /// `true` while a segment has sub-steps left.
    #[must_use]
    pub fn pending(&self) -> bool {
        self.pending.is_some()
    }

    /// Integrates at most `budget` sub-steps of the pending segment; returns how many.
    pub fn integrate<const K: usize>(&mut self, task: &Task<N, K>, budget: u32) -> u32 {
        let Some(mut seg) = self.pending else {
            return 0;
        };
        let robot = task.robot();
        let moving = self.momentum != Vec3::new(0.0, 0.0, 0.0);
        let l = self.momentum;
        let mut used = 0;
        while seg.next < self.substeps && used < budget {
            let (mid, dq) = midpoint_substep(&seg.from, &seg.to, self.substeps, seg.next);
            let m = Momentum::new(robot, &Frames::new(robot, &mid));
            let dtheta = if moving {
                match m.hb.ldlt() {
                    Some(f) => {
                        let body_l = quat_matrix(self.attitude).transpose() * l;
                        Ok(f.solve(&(body_l * seg.dt - m.coupling_momentum(&dq))))
                    }
                    None => Err(Error::SingularInertia),
                }
            } else {
                m.base_angular_velocity(&dq)
            };
            used += 1;
            seg.next += 1;
            match dtheta {
                Ok(d) => {
                    self.attitude = normalized(quat_mul(self.attitude, quat_exp(&d)));
                    self.max_angle = self.max_angle.max(quat_angle(self.attitude));
                }
                Err(e) => {
                    self.error = Some(e);
                    self.pending = None;
                    return used;
                }
            }
        }
        if seg.next >= self.substeps {
            self.pending = None;
            self.segments += 1;
        } else {
            self.pending = Some(seg);
        }
        used
    }

    /// Sub-steps per segment.
    #[must_use]
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// Base attitude at the last sample (unit quaternion, base → inertial).
    #[must_use]
    pub fn attitude(&self) -> [f64; 4] {
        self.attitude
    }

    /// Base rotation angle at the last sample (rad).
    #[must_use]
    pub fn angle(&self) -> f64 {
        quat_angle(self.attitude)
    }

    /// Largest base rotation angle so far (rad).
    #[must_use]
    pub fn max_angle(&self) -> f64 {
        self.max_angle
    }

    /// Segments integrated so far.
    #[must_use]
    pub fn segments(&self) -> u32 {
        self.segments
    }

    /// The first error met (a singular `H~b`; never for a valid model), if any.
    #[must_use]
    pub fn error(&self) -> Option<Error> {
        self.error
    }

    /// End-effector pose at the last sample with the integrated base attitude and the base
    /// placed by CoM conservation (inertial frame).
    #[must_use]
    pub fn end_pose<const K: usize>(&self, task: &Task<N, K>) -> Option<Pose> {
        self.last.map(|(q, _)| task.end_pose(&q, self.attitude))
    }
}

/// The truth model as a [`Sink`]: the state and the task it integrates.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthModel<'t, const N: usize, const K: usize> {
    task: &'t Task<N, K>,
    state: TruthState<N>,
}

impl<'t, const N: usize, const K: usize> TruthModel<'t, N, K> {
    /// A truth model for `task` with `substeps` midpoint sub-steps per segment (at least
    /// [`MIN_SUBSTEPS`] is used), zero momentum.
    #[must_use]
    pub fn new(task: &'t Task<N, K>, substeps: u32) -> Self {
        Self::from_state(task, TruthState::new(substeps))
    }

    /// A truth model for `task` continuing from `state` (e.g. one with momentum).
    #[must_use]
    pub fn from_state(task: &'t Task<N, K>, state: TruthState<N>) -> Self {
        Self { task, state }
    }

    /// The integrator state.
    #[must_use]
    pub fn state(&self) -> &TruthState<N> {
        &self.state
    }

    /// Integrates the segment from the previous configuration to `q` (rad) at time `t`.
    pub fn push(&mut self, q: &[f64; N], t: f64) {
        self.state.push(self.task, q, t);
    }

    /// Base attitude at the last sample (unit quaternion, base → inertial).
    #[must_use]
    pub fn attitude(&self) -> [f64; 4] {
        self.state.attitude()
    }

    /// Base rotation angle at the last sample (rad).
    #[must_use]
    pub fn angle(&self) -> f64 {
        self.state.angle()
    }

    /// Largest base rotation angle so far (rad).
    #[must_use]
    pub fn max_angle(&self) -> f64 {
        self.state.max_angle()
    }

    /// Segments integrated so far.
    #[must_use]
    pub fn segments(&self) -> u32 {
        self.state.segments()
    }

    /// The first error met (a singular `H~b`; never for a valid model), if any.
    #[must_use]
    pub fn error(&self) -> Option<Error> {
        self.state.error()
    }

    /// End-effector pose at the last sample with the integrated base attitude and the base
    /// placed by CoM conservation (inertial frame).
    #[must_use]
    pub fn end_pose(&self) -> Option<Pose> {
        self.state.end_pose(self.task)
    }
}

impl<const N: usize, const K: usize> Sink<N> for TruthModel<'_, N, K> {
    fn sample(&mut self, s: &Sample<N>) {
        self.push(&s.q, s.t);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::reference::paper_task;

    /// Spec §11: with the arm at rest and momentum `L`, the base turns at
    /// `ω = H~b⁻¹ R₀ᵀ L`; over a short time the angle is `|H~b⁻¹ L| t` to first order, and
    /// the integrated attitude keeps `R₀ H~b ω = L`.
    /// Verifies RL-TRUTH-005.
    #[test]
    fn a_base_rate_at_rest_turns_the_base_at_hb_inverse_l() {
        let task = paper_task().unwrap();
        let q = *task.start();
        let hb = Momentum::new(task.robot(), &Frames::new(task.robot(), &q)).hb;
        let omega0 = Vec3::new(1e-3, -2e-3, 0.5e-3);
        let l = hb.mul_vec(&omega0);
        let mut s = TruthState::<7>::new(10).with_momentum([l.x, l.y, l.z]);
        for k in 0..=100 {
            s.push(&task, &q, f64::from(k) * 0.01);
        }
        // Second-order effects (body-frame L turning with the base) are of the order of the
        // angle itself, 2.3e-3 here.
        let expected = omega0.norm() * 1.0;
        let got = s.max_angle();
        assert!(
            (got - expected).abs() < 1e-5 * expected,
            "{got} vs {expected}"
        );
        // Momentum conservation at the end: R₀ H~b ω(1 s) = L.
        let r0 = quat_matrix(s.attitude());
        let w = hb.ldlt().unwrap().solve(&(r0.transpose() * l));
        let back = r0 * hb.mul_vec(&w);
        assert!((back - l).norm() < 1e-12 * l.norm());
        // Zero momentum and the arm at rest: nothing moves, exactly.
        let mut still = TruthState::<7>::new(10);
        for k in 0..=10 {
            still.push(&task, &q, f64::from(k));
        }
        assert_eq!(still.max_angle(), 0.0);
    }
}
