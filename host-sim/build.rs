//! Build information for certification records: target, profile, optimisation level and,
//! when the sources are a git checkout, the revision (with `-dirty` for local changes).

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    let rev = git(&["rev-parse", "--short=12", "HEAD"]).map(|r| {
        let dirty =
            git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
        if dirty { format!("{r}-dirty") } else { r }
    });
    println!(
        "cargo:rustc-env=HOST_SIM_GIT_REV={}",
        rev.unwrap_or_else(|| "unknown".into())
    );
    for (key, var) in [
        ("HOST_SIM_TARGET", "TARGET"),
        ("HOST_SIM_PROFILE", "PROFILE"),
        ("HOST_SIM_OPT_LEVEL", "OPT_LEVEL"),
    ] {
        println!(
            "cargo:rustc-env={key}={}",
            std::env::var(var).unwrap_or_else(|_| "unknown".into())
        );
    }
    println!("cargo:rerun-if-changed=../.git/HEAD");
    println!("cargo:rerun-if-changed=../.git/index");
    println!("cargo:rerun-if-changed=build.rs");
}
