//! Build information for certification records: target, profile, optimisation level and,
//! when the sources are a git checkout, the revision (with `-dirty` for local changes).
//!
//! The revision is re-read only when it can have changed: a commit or checkout (`HEAD`, the
//! branch's ref, `packed-refs`) or an edit of the sources this binary is built from. Git's
//! index is not watched, so `git add`, `git status` or a touched index do not relink the
//! (fat-LTO) binary.

use std::path::{Path, PathBuf};
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// The files whose change means a new commit is checked out.
fn ref_files() -> Vec<PathBuf> {
    let Some(git_dir) = git(&["rev-parse", "--git-dir"]) else {
        return Vec::new();
    };
    let git_dir = PathBuf::from(git_dir);
    let mut files = vec![git_dir.join("HEAD"), git_dir.join("packed-refs")];
    if let Some(head) = git(&["symbolic-ref", "-q", "HEAD"]) {
        files.push(git_dir.join(head));
    }
    // A path that does not exist would make cargo re-run the script on every build.
    files.retain(|f| f.exists());
    files
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
    for f in ref_files() {
        println!("cargo:rerun-if-changed={}", f.display());
    }
    // Edits of the sources the binary is built from (they make the tree dirty or clean).
    for p in ["src", "../src", "Cargo.toml", "../Cargo.toml", "build.rs"] {
        if Path::new(p).exists() {
            println!("cargo:rerun-if-changed={p}");
        }
    }
}
