//! The truth model (spec §5, checking only): the base attitude that a joint path really
//! produces under zero angular momentum.
//!
//! Owns [`TruthModel`], a [`Sink`] that follows the piecewise-linear joint path through
//! the samples it is fed and integrates `w₀ = −H~b⁻¹ H~bm q̇` with `m` midpoint sub-steps
//! per segment ([`crate::integrator::midpoint_substeps`]). The rotation over a sub-step depends only on the joint increment
//! (`δθ = −H~b⁻¹ H~bm(q_mid) δq`, base frame), so the samples' times and rates are not
//! needed: the path as written is what is checked. The base disturbance is the largest
//! base rotation angle over the motion.

use crate::error::Error;
use crate::geometry::{Pose, normalized, quat_angle, quat_exp, quat_mul};
use crate::integrator::midpoint_substeps;
use crate::kinematics::{Frames, IDENTITY_WXYZ};
use crate::momentum::Momentum;
use crate::rollout::{Sample, Sink};
use crate::task::Task;

/// Smallest number of midpoint sub-steps per segment the specification accepts.
pub const MIN_SUBSTEPS: u32 = 10;

/// Base attitude integrator fed with trajectory samples.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthModel<'t, const N: usize, const K: usize> {
    task: &'t Task<N, K>,
    substeps: u32,
    last: Option<[f64; N]>,
    attitude: [f64; 4],
    max_angle: f64,
    error: Option<Error>,
    segments: u32,
}

impl<'t, const N: usize, const K: usize> TruthModel<'t, N, K> {
    /// A truth model for `task` with `substeps` midpoint sub-steps per segment (at least
    /// [`MIN_SUBSTEPS`] is used).
    #[must_use]
    pub fn new(task: &'t Task<N, K>, substeps: u32) -> Self {
        Self {
            task,
            substeps: substeps.max(MIN_SUBSTEPS),
            last: None,
            attitude: IDENTITY_WXYZ,
            max_angle: 0.0,
            error: None,
            segments: 0,
        }
    }

    /// Integrates the segment from the previous configuration to `q` (rad).
    pub fn push(&mut self, q: &[f64; N]) {
        let Some(prev) = self.last.replace(*q) else {
            return;
        };
        if self.error.is_some() {
            return;
        }
        let robot = self.task.robot();
        let mut attitude = self.attitude;
        let mut max_angle = self.max_angle;
        let result = midpoint_substeps(&prev, q, self.substeps, |mid, dq| {
            let dtheta =
                Momentum::new(robot, &Frames::new(robot, mid)).base_angular_velocity(dq)?;
            attitude = normalized(quat_mul(attitude, quat_exp(&dtheta)));
            max_angle = max_angle.max(quat_angle(attitude));
            Ok(())
        });
        self.attitude = attitude;
        self.max_angle = max_angle;
        if let Err(e) = result {
            self.error = Some(e);
            return;
        }
        self.segments += 1;
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
    pub fn end_pose(&self) -> Option<Pose> {
        self.last.map(|q| self.task.end_pose(&q, self.attitude))
    }
}

impl<const N: usize, const K: usize> Sink<N> for TruthModel<'_, N, K> {
    fn sample(&mut self, s: &Sample<N>) {
        self.push(&s.q);
    }
}
