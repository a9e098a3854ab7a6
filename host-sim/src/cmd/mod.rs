//! One module per subcommand; each exposes `run(...) -> Result<(), CliError>`.

pub mod bench;
pub mod model;
pub mod plan;
pub mod rollout;
