//! One leaf per subcommand. Each file owns its `clap::Args` struct (flags and help) and
//! `Args::run`; leaves import only the shared modules (`args`, `artifacts`, `drive`,
//! `records`, `retiming`, `stats`, `output`, `taskfile`, `goal`, `urdf`, `view`, `flight`,
//! `campaign_report`, `dispersion`, `dispersion_report`, `shards`, `version`), never each
//! other. A new subcommand is one file here plus two lines in `cli.rs`.

pub mod bench;
pub mod block;
pub mod campaign;
pub mod check;
pub mod completions;
pub mod disperse;
pub mod frames;
pub mod generate;
pub mod manpage;
pub mod merge;
pub mod model;
pub mod plan;
pub mod record;
pub mod replay;
pub mod retime;
pub mod rollout;
pub mod target;
pub mod view;
