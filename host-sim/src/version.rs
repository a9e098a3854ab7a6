//! Which build of host-sim this is, and the one line that says so.
//!
//! Owns [`Build`] (crate version, git revision, target, profile and optimisation level, as
//! `build.rs` found them) and [`Build::stamp`], `host-sim <version> (<git revision>)`: the
//! build named in the corner of every figure, on the replay page and in a shard's
//! `manifest.json`. Records keep the whole [`Build`].

use serde::{Deserialize, Serialize};

/// A build of host-sim.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Build {
    /// Crate version.
    pub crate_version: String,
    /// Git revision (`-dirty` with local changes), or `unknown`.
    pub git_revision: String,
    /// Target triple.
    pub target: String,
    /// Cargo profile (`debug` or `release`).
    pub profile: String,
    /// Optimisation level.
    pub opt_level: String,
}

impl Build {
    /// This build.
    pub fn current() -> Self {
        Self {
            crate_version: env!("CARGO_PKG_VERSION").into(),
            git_revision: env!("HOST_SIM_GIT_REV").into(),
            target: env!("HOST_SIM_TARGET").into(),
            profile: env!("HOST_SIM_PROFILE").into(),
            opt_level: env!("HOST_SIM_OPT_LEVEL").into(),
        }
    }

    /// `host-sim <version> (<git revision>)`: how outputs name the build that wrote them.
    ///
    /// ```
    /// use host_sim::version::Build;
    /// let build = Build {
    ///     crate_version: "0.1.0".into(),
    ///     git_revision: "3b3df07".into(),
    ///     ..Build::current()
    /// };
    /// assert_eq!(build.stamp(), "host-sim 0.1.0 (3b3df07)");
    /// ```
    pub fn stamp(&self) -> String {
        format!("host-sim {} ({})", self.crate_version, self.git_revision)
    }
}
