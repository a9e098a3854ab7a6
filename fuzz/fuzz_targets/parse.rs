//! Fuzz target: arbitrary text through host-sim's URDF loader and task-file parser, and the
//! two together into a core task. Must never panic: bad input is an error message.
//!
//! Verifies RL-ROB-014.
#![no_main]

use host_sim::taskfile::{TaskFile, from_texts};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    // The first NUL splits URDF text from task text.
    let (urdf, task) = text.split_once('\0').unwrap_or((&text, ""));
    let _ = host_sim::urdf::parse(urdf, None);
    let _ = toml::from_str::<TaskFile>(task);
    if let Ok(lt) = from_texts(Path::new("fuzz.toml"), task, urdf) {
        let n = lt.chain.dof();
        if n == 7 {
            let _ = lt.task::<7, 4>();
            let _ = lt.planner(64, &host_sim::taskfile::Overrides::default());
        } else if n == 6 {
            let _ = lt.task::<6, 3>();
        }
    }
});
