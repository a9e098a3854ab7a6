//! The `host-sim` binary: [`host_sim::cli::main`].

fn main() -> std::process::ExitCode {
    host_sim::cli::main()
}
