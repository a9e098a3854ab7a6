//! Fuzz target: an arbitrary task block, as the flight image receives it: decode, load
//! into an idle planner in place, and plan a few frames. Must never panic; every value a
//! finished plan reports is finite.
//!
//! Each input is tried twice: as is (the CRC rejects almost every mutation) and with its
//! header and CRC repaired, so the fuzzer also reaches field validation and planning.
//!
//! Verifies RL-CORE-006, RL-BLOCK-003, RL-BLOCK-004, RL-BLOCK-005, RL-ROB-008.
#![no_main]

use libfuzzer_sys::fuzz_target;
use reactionless::block::{MAGIC, block_len, crc32, decode};
use reactionless::{Planner, Status};

fn exercise(data: &[u8]) {
    let Ok(block) = decode::<7>(data) else { return };
    let mut planner: Box<Planner<7, 4, 64>> = Box::new(Planner::IDLE);
    if block.load_into(&mut planner).is_err() {
        assert!(
            planner.step(10, &mut ()).is_err(),
            "a planner whose load failed must not run"
        );
        return;
    }
    // Bounded work: at most 20 frames of at most 1500 steps.
    for _ in 0..20 {
        match planner.step(block.planner.frame_budget.clamp(1, 1500), &mut ()) {
            Ok(Status::Running(_)) => {}
            Ok(Status::Finished(p)) => {
                let scalars = [p.outcome.f, p.outcome.phi, p.outcome.g];
                for v in p
                    .eta
                    .iter()
                    .flatten()
                    .flatten()
                    .chain(&p.outcome.q_final)
                    .chain(&scalars)
                {
                    assert!(v.is_finite());
                }
                return;
            }
            Err(_) => return,
        }
    }
}

fuzz_target!(|data: &[u8]| {
    exercise(data);
    let len = block_len(7);
    let mut fixed = vec![0u8; len];
    for (d, s) in fixed.iter_mut().zip(data) {
        *d = *s;
    }
    fixed[..8].copy_from_slice(&MAGIC);
    fixed[8..12].copy_from_slice(&7u32.to_le_bytes());
    fixed[12..16].copy_from_slice(&(len as u32).to_le_bytes());
    let crc = crc32(&fixed[..len - 4]);
    fixed[len - 4..].copy_from_slice(&crc.to_le_bytes());
    exercise(&fixed);
});
