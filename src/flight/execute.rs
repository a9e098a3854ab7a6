//! Execution: the planned joint setpoints `(t, q, q̇)`, one per call, from `(q₀, η)`.
//!
//! Owns [`Setpoints`]. It drives the very [`Rollout`] the planner evaluated, one integration
//! step per call, and holds at most one sample back (the last call of a rollout yields two).
//! Memory is O(1) in the trajectory length, and what is flown is exactly what was verified,
//! bit for bit.

use crate::error::Error;
use crate::rollout::{Outcome, Progress, Rollout, Sample};
use crate::task::Task;
use crate::trajectory::Eta;

/// A stream of setpoints for one η.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setpoints<const N: usize, const K: usize> {
    rollout: Rollout<N, K>,
    pending: Option<Sample<N>>,
    outcome: Option<Outcome<N>>,
}

impl<const N: usize, const K: usize> Setpoints<N, K> {
    /// The setpoints of `eta` for `task`, before the first one.
    ///
    /// # Errors
    /// An invalid η (see [`Rollout::new`]).
    pub fn new(task: &Task<N, K>, eta: &[[f64; 2]; K]) -> Result<Self, Error> {
        Ok(Self {
            rollout: Rollout::new(task, eta)?,
            pending: None,
            outcome: None,
        })
    }

    /// The setpoints of `eta` (one set of pairs per segment of the task's motion,
    /// [`Rollout::of`]) for `task`, before the first one.
    ///
    /// # Errors
    /// An invalid η (see [`Rollout::of`]).
    pub fn of(task: &Task<N, K>, eta: &Eta<K>) -> Result<Self, Error> {
        Ok(Self {
            rollout: Rollout::of(task, eta)?,
            pending: None,
            outcome: None,
        })
    }

    /// The next setpoint (`t` from 0 to `t_f` in steps of `dt`), or `None` after the last.
    /// Each call does at most one integration step (with [`crate::Integrator::Rk4`] or
    /// [`crate::Integrator::Ab5`], a call at an integrator node does the whole step to the
    /// next node).
    ///
    /// # Errors
    /// As [`Rollout::advance`] (rank loss, non-finite state); the stream then stays failed.
    ///
    /// Verifies RL-EXEC-001.
    ///
    /// ```
    /// use reactionless::{Setpoints, reference};
    /// let task = reference::paper_task().unwrap();
    /// let mut sp = Setpoints::new(&task, &reference::ETA_HAT).unwrap();
    /// let mut n = 0;
    /// while let Some(s) = sp.next(&task).unwrap() {
    ///     assert_eq!(s.step, n);
    ///     n += 1;
    /// }
    /// assert_eq!(n, 3001);
    /// ```
    pub fn next(&mut self, task: &Task<N, K>) -> Result<Option<Sample<N>>, Error> {
        if let Some(s) = self.pending.take() {
            return Ok(Some(s));
        }
        if self.outcome.is_some() {
            return Ok(None);
        }
        let mut slots: [Option<Sample<N>>; 2] = [None, None];
        let mut sink = |s: &Sample<N>| {
            if let Some(slot) = slots.iter_mut().find(|x| x.is_none()) {
                *slot = Some(*s);
            }
        };
        if let Progress::Done(o) = self.rollout.advance(task, 1, &mut sink)? {
            self.outcome = Some(o);
        }
        let [first, second] = slots;
        self.pending = second;
        Ok(first)
    }

    /// The rollout's outcome once the last setpoint has been produced.
    #[must_use]
    pub fn outcome(&self) -> Option<&Outcome<N>> {
        self.outcome.as_ref()
    }
}
