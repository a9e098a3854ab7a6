//! What a plan must reach, resolved once from the task file and the command line, and the
//! one wording of whether it did.
//!
//! Owns [`Goal`] (`[target] goal`), the default pose tolerances
//! ([`DEFAULT_POSITION_TOLERANCE_M`], [`DEFAULT_ORIENTATION_TOLERANCE_DEG`]), [`Asked`] (the
//! resolved goal: the refinement tolerance the planner is given and the pose tolerances
//! that `plan`, `campaign` and `check` hold a plan to) and [`status_name`].
//!
//! **The default goal is the pose.** A plan is converged when its end pose is within
//! `[target] position_tolerance_m` and `orientation_tolerance_deg` (defaults 1e-6 m and
//! 1e-4°) on the planner model (or on the truth model with `refine_against = "truth"`). The
//! planner is asked for `f ≤ min(refine_tolerance, position_tolerance_m,
//! orientation_tolerance_deg in rad)`: each error is at most f, so that meets both.
//! `[target] goal = "sigma_e"` (or `--paper`) asks for the paper's test instead: Φ = 0 and
//! `f ≤ σ_e` (`[planner] tolerance`, a norm of metres and radians mixed), refined further
//! only if `refine_tolerance` is set.

use crate::error::CliError;
use reactionless::{PlannerConfig, RefineAgainst};
use serde::{Deserialize, Serialize};

/// Default `[target] position_tolerance_m` (m).
pub const DEFAULT_POSITION_TOLERANCE_M: f64 = 1e-6;
/// Default `[target] orientation_tolerance_deg` (deg).
pub const DEFAULT_ORIENTATION_TOLERANCE_DEG: f64 = 1e-4;

/// What a plan must reach (`[target] goal`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Goal {
    /// The pose tolerances (`"pose"`, the default).
    #[default]
    Pose,
    /// The paper's success test, `f ≤ σ_e` with Φ = 0 (`"sigma_e"`, or `--paper`).
    SigmaE,
}

impl Goal {
    /// The task-file name.
    pub fn name(self) -> &'static str {
        match self {
            Goal::Pose => "pose",
            Goal::SigmaE => "sigma_e",
        }
    }
}

/// The goal of one run, resolved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Asked {
    /// Which goal.
    pub goal: Goal,
    /// σ_e (`[planner] tolerance`).
    pub sigma_e: f64,
    /// The refinement tolerance handed to the planner (`None`: σ_e only).
    pub refine_tolerance: Option<f64>,
    /// The model the refinement tolerance applies to.
    pub against: RefineAgainst,
    /// The position tolerance (m) of the pose goal.
    pub position_m: Option<f64>,
    /// The orientation tolerance (deg) of the pose goal.
    pub orientation_deg: Option<f64>,
}

impl Asked {
    /// Resolves the goal of `config` (the task's `[planner]` with the command line's
    /// overrides applied) for `goal` and the task's pose tolerances (`None`: the default).
    /// `name` names the task file in errors.
    pub fn resolve(
        goal: Goal,
        config: &PlannerConfig,
        position_m: Option<f64>,
        orientation_deg: Option<f64>,
        name: &str,
    ) -> Result<Self, CliError> {
        for (key, v) in [
            ("position_tolerance_m", position_m),
            ("orientation_tolerance_deg", orientation_deg),
        ] {
            match v {
                Some(v) if !(v.is_finite() && v > 0.0) => {
                    return Err(CliError::input(format!(
                        "{name}: [target] {key} = {v} must be a finite number > 0"
                    )));
                }
                Some(v) if goal == Goal::SigmaE => {
                    return Err(CliError::input(format!(
                        "{name}: [target] {key} = {v} is set, but the goal is sigma_e (the paper's f ≤ σ_e), which ignores it: remove one of the two"
                    )));
                }
                _ => {}
            }
        }
        let (position_m, orientation_deg, refine_tolerance) = match goal {
            Goal::SigmaE => (None, None, config.refine_tolerance),
            Goal::Pose => {
                let p = position_m.unwrap_or(DEFAULT_POSITION_TOLERANCE_M);
                let o = orientation_deg.unwrap_or(DEFAULT_ORIENTATION_TOLERANCE_DEG);
                let f = match config.refine_tolerance {
                    // Left as it is, for the planner's validation to name.
                    Some(t) if !(t.is_finite() && t > 0.0) => t,
                    t => [t, Some(p), Some(o.to_radians())]
                        .into_iter()
                        .flatten()
                        .fold(f64::INFINITY, f64::min),
                };
                (Some(p), Some(o), Some(f))
            }
        };
        Ok(Self {
            goal,
            sigma_e: config.tolerance,
            refine_tolerance,
            against: config.refine_against,
            position_m,
            orientation_deg,
        })
    }

    /// `true` if the goal is judged on the truth model (a refinement against it).
    pub fn against_truth(&self) -> bool {
        self.refine_tolerance.is_some() && self.against == RefineAgainst::Truth
    }

    /// The model the goal is judged on.
    pub fn model(&self) -> &'static str {
        if self.against_truth() {
            "truth model"
        } else {
            "planner model"
        }
    }

    /// What was asked, in words: `position ≤ 1e-6 m, orientation ≤ 1e-4 deg (planner
    /// model)`, `f ≤ σ_e = 0.05`, `f ≤ σ_e = 0.05, refined to truth_f ≤ 1e-9 (truth model)`.
    pub fn describe(&self) -> String {
        let f_name = match self.against {
            RefineAgainst::Truth => "truth_f",
            RefineAgainst::Planner => "f",
        };
        match (
            self.goal,
            self.position_m,
            self.orientation_deg,
            self.refine_tolerance,
        ) {
            (Goal::Pose, Some(p), Some(o), t) => {
                // A refinement tolerance tighter than the pose tolerances is asked too.
                let tighter = t
                    .filter(|t| *t < p.min(o.to_radians()))
                    .map_or(String::new(), |t| format!(", {f_name} ≤ {}", number(t)));
                format!(
                    "position ≤ {} m, orientation ≤ {} deg{tighter} ({})",
                    number(p),
                    number(o),
                    self.model()
                )
            }
            (_, _, _, Some(t)) => format!(
                "f ≤ σ_e = {}, refined to {f_name} ≤ {} ({})",
                number(self.sigma_e),
                number(t),
                self.model()
            ),
            _ => format!("f ≤ σ_e = {} (the paper's test)", number(self.sigma_e)),
        }
    }
}

/// `"converged"` or `"not_converged"`: the status of a plan in `plan.json`, `runs.csv` and
/// records.
pub fn status_name(converged: bool) -> &'static str {
    if converged {
        "converged"
    } else {
        "not_converged"
    }
}

/// A number as a reader wants it: plain where that is short (`0.05`, `97.57`, `1.44`),
/// else scientific (`1e-6`, `3.254e-5`), with at most 4 significant digits.
pub fn number(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if a == 0.0 || (1e-3..1e5).contains(&a) {
        let digits = if a == 0.0 {
            0
        } else {
            (3 - a.log10().floor() as i32).max(0) as usize
        };
        let s = format!("{v:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.3e}");
        let (m, e) = s.split_once('e').unwrap_or((&s, "0"));
        let m = if m.contains('.') {
            m.trim_end_matches('0').trim_end_matches('.')
        } else {
            m
        };
        format!("{m}e{e}")
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn config() -> PlannerConfig {
        PlannerConfig::default_with_seed(1)
    }

    /// The default goal asks the planner for f ≤ 1e-6 (the tighter of 1e-6 m and 1e-4° in
    /// rad); a tighter refine_tolerance wins; the paper's goal keeps σ_e and no refinement;
    /// tolerances that contradict the goal, or are not positive, are refused.
    /// Verifies RL-SIM-TASK-005.
    #[test]
    fn the_pose_goal_resolves_to_the_tightest_tolerance() {
        let a = Asked::resolve(Goal::Pose, &config(), None, None, "t").unwrap();
        assert_eq!(a.refine_tolerance, Some(1e-6));
        assert_eq!((a.position_m, a.orientation_deg), (Some(1e-6), Some(1e-4)));
        let mut c = config();
        c.refine_tolerance = Some(1e-9);
        let a = Asked::resolve(Goal::Pose, &c, Some(1e-3), Some(1.0), "t").unwrap();
        assert_eq!(a.refine_tolerance, Some(1e-9));
        let a = Asked::resolve(Goal::Pose, &config(), Some(1e-3), Some(1.0), "t").unwrap();
        assert_eq!(a.refine_tolerance, Some(1e-3));
        let a = Asked::resolve(Goal::Pose, &config(), Some(1.0), Some(1e-3), "t").unwrap();
        assert_eq!(a.refine_tolerance, Some(1e-3f64.to_radians()));
        let a = Asked::resolve(Goal::SigmaE, &config(), None, None, "t").unwrap();
        assert_eq!(a.refine_tolerance, None);
        assert_eq!(a.describe(), "f ≤ σ_e = 0.05 (the paper's test)");
        let e = Asked::resolve(Goal::SigmaE, &config(), Some(1e-3), None, "t").unwrap_err();
        assert!(e.to_string().contains("position_tolerance_m"), "{e}");
        let e = Asked::resolve(Goal::Pose, &config(), None, Some(-1.0), "t").unwrap_err();
        assert!(
            e.to_string().contains("orientation_tolerance_deg = -1"),
            "{e}"
        );
    }

    /// Numbers read plainly where they are short, scientifically where they are not.
    /// Verifies RL-SIM-CAMP-004.
    #[test]
    fn numbers_read_as_an_engineer_writes_them() {
        assert_eq!(number(1.440), "1.44");
        assert_eq!(number(97.57), "97.57");
        assert_eq!(number(0.05), "0.05");
        assert_eq!(number(3.0), "3");
        assert_eq!(number(1e-6), "1e-6");
        assert_eq!(number(3.254e-5), "3.254e-5");
        assert_eq!(number(0.0), "0");
        assert_eq!(number(123456.0), "1.235e5");
    }
}
