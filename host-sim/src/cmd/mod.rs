//! One module per subcommand; each exposes `run(...) -> Result<(), CliError>`.

pub mod bench;
pub mod campaign;
pub mod check;
pub mod frames;
pub mod generate;
pub mod model;
pub mod plan;
pub mod record;
pub mod rollout;
pub mod target;
