//! One module per subcommand; each exposes `run(...) -> Result<(), CliError>`.

pub mod model;
pub mod rollout;
