//! The closed loop through the C ABI (`rl_loop`): its contract (NULL, ABI version and size,
//! a planner without a task or a plan, a refused setting, another planner's task), its
//! commands bit-identical to the core's `PlanLoop`, and each sensor fault reported once in
//! the command, the arm then brought to rest within the acceleration limit.
//!
//! Requirements: RL-FFI-014 (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use reactionless::closed_loop::{LoopConfig, Measurement, PlanLoop};
use reactionless_ffi::closed_loop::*;
use reactionless_ffi::*;
use std::path::Path;

fn block(task: &str) -> Vec<u8> {
    let lt = host_sim::taskfile::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(task))
        .unwrap();
    host_sim::flight::task_block(&lt, &host_sim::taskfile::Overrides::default()).unwrap()
}

/// A planner with `task`'s block loaded and, if `finish`, planned to the end.
#[allow(unsafe_code)]
fn planner(task: &str, finish: bool) -> Box<rl_planner> {
    let b = block(task);
    let mut p = Box::new(rl_planner::ZEROED);
    let mut plan = rl_plan::ZEROED;
    // SAFETY: `p` is a valid, exclusive rl_planner; the block is readable for its length.
    unsafe {
        assert_eq!(
            rl_planner_init(&mut *p, RL_ABI_VERSION, size_of::<rl_planner>()),
            RL_OK
        );
        assert_eq!(rl_planner_load_block(&mut *p, b.as_ptr(), b.len()), RL_OK);
        while finish && rl_planner_step(&mut *p, 100_000, &mut plan) == RL_RUNNING {}
    }
    p
}

/// The start of the reference task (the measured joints before the flight).
fn start() -> [f64; 7] {
    *reactionless::reference::paper_task().unwrap().start()
}

fn fine(q: [f64; 7]) -> rl_measurement {
    rl_measurement {
        valid: RL_MEASURED_STAR_TRACKER | RL_MEASURED_GYRO | RL_MEASURED_JOINTS,
        star_tracker_wxyz: [1.0, 0.0, 0.0, 0.0],
        gyro_rad_s: [0.0; 3],
        joints_rad: q,
    }
}

/// Every misuse is a negative status naming it, and leaves nothing half-initialised.
/// Verifies RL-FFI-014.
#[test]
#[allow(unsafe_code)]
fn rl_loop_names_what_is_wrong() {
    let done = planner("spec/tasks/paper.toml", true);
    let unplanned = planner("spec/tasks/paper.toml", false);
    let other = planner("tests/records/tasks/chaser7/task_002.toml", true);
    let mut l = Box::new(rl_loop::ZEROED);
    let mut c = rl_loop_command::ZEROED;
    let size = size_of::<rl_loop>();
    let m = fine(start());
    let null = core::ptr::null_mut::<rl_loop>();
    // SAFETY: every pointer is NULL or valid and exclusive for the call.
    unsafe {
        assert_eq!(rl_loop_config_default(core::ptr::null_mut()), RL_E_NULL);
        let mut cfg = rl_loop_config::DEFAULT;
        assert_eq!(rl_loop_config_default(&mut cfg), RL_OK);
        assert_eq!(cfg.period_s, 0.1);
        let nocfg = core::ptr::null();
        assert_eq!(
            rl_loop_init(null, RL_ABI_VERSION, size, &*done, nocfg, &mut c),
            RL_E_NULL
        );
        assert_eq!(
            rl_loop_init(
                &mut *l,
                RL_ABI_VERSION,
                size,
                core::ptr::null(),
                nocfg,
                &mut c
            ),
            RL_E_NULL
        );
        assert_eq!(
            rl_loop_init(&mut *l, RL_ABI_VERSION + 1, size, &*done, nocfg, &mut c),
            RL_E_ABI_VERSION
        );
        assert_eq!(
            rl_loop_init(&mut *l, RL_ABI_VERSION, size - 8, &*done, nocfg, &mut c),
            RL_E_SIZE
        );
        // Stepped before init.
        assert_eq!(
            rl_loop_step(&mut *l, &*done, &m, &mut c),
            RL_E_UNINITIALIZED
        );
        // A planner that has not finished planning has no plan to fly.
        assert_eq!(
            rl_loop_init(&mut *l, RL_ABI_VERSION, size, &*unplanned, nocfg, &mut c),
            RL_E_NO_PLAN
        );
        // Refused settings: an unstable gain, a period that is not a multiple of dt, NaN.
        for bad in [
            rl_loop_config {
                base_gain_per_s: 10.0,
                ..cfg
            },
            rl_loop_config {
                period_s: 0.015,
                ..cfg
            },
            rl_loop_config {
                filter_gain: f64::NAN,
                ..cfg
            },
            rl_loop_config {
                qdd_max_rad_s2: 0.0,
                ..cfg
            },
        ] {
            assert_eq!(
                rl_loop_init(&mut *l, RL_ABI_VERSION, size, &*done, &bad, &mut c),
                RL_E_LOOP_SETTING,
                "{bad:?}"
            );
        }
        assert_eq!(
            rl_loop_step(&mut *l, &*done, &m, &mut c),
            RL_E_UNINITIALIZED
        );
        assert_eq!(
            rl_loop_init(&mut *l, RL_ABI_VERSION, size, &*done, &cfg, &mut c),
            RL_OK
        );
        // Another task's planner.
        assert_eq!(rl_loop_step(&mut *l, &*other, &m, &mut c), RL_E_MISMATCH);
        assert_eq!(
            rl_loop_step(&mut *l, &*done, core::ptr::null(), &mut c),
            RL_E_NULL
        );
        assert_eq!(rl_loop_step(&mut *l, &*done, &m, &mut c), RL_OK);
        let name = core::ffi::CStr::from_ptr(rl_status_str(RL_E_LOOP_SETTING));
        assert!(name.to_str().unwrap().starts_with("RL_E_LOOP_SETTING"));
        for f in 0..=7 {
            let name = core::ffi::CStr::from_ptr(rl_loop_fault_str(f))
                .to_str()
                .unwrap();
            assert!(!name.is_empty());
        }
    }
}

/// A whole flight through `rl_loop` gives the core's commands bit for bit, ends with
/// `RL_DONE` once at rest, and then keeps answering `RL_DONE` with zero commands.
/// Verifies RL-FFI-014.
#[test]
#[allow(unsafe_code)]
fn rl_loop_flies_the_core_loop_bit_for_bit() {
    let p = planner("spec/tasks/paper.toml", true);
    let task = reactionless::reference::paper_task().unwrap();
    let b = block("spec/tasks/paper.toml");
    let decoded = reactionless::block::decode::<7>(&b).unwrap();
    let mut core_planner = Box::new(reactionless::Planner::<7, 4, 64>::IDLE);
    decoded.load_into(&mut core_planner).unwrap();
    let eta = loop {
        if let reactionless::Status::Finished(p) = core_planner.step(u32::MAX, &mut ()).unwrap() {
            break p.eta;
        }
    };
    let (mut core, first) = PlanLoop::new(LoopConfig::DEFAULT, core_planner.task(), &eta).unwrap();
    let mut l = Box::new(rl_loop::ZEROED);
    let mut c = rl_loop_command::ZEROED;
    let mut q = *task.start();
    // SAFETY: every pointer is valid and exclusive for the call.
    unsafe {
        assert_eq!(
            rl_loop_init(
                &mut *l,
                RL_ABI_VERSION,
                size_of::<rl_loop>(),
                &*p,
                core::ptr::null(),
                &mut c
            ),
            RL_OK
        );
        assert_eq!(c.rate_rad_s, first);
        let mut held = c.rate_rad_s;
        let mut k = 0;
        loop {
            // A base that turns slowly (a wrong model), seen by both sensors: real corrections.
            let angle = 1e-6 * f64::from(k);
            let st = [(angle / 2.0).cos(), 0.0, 0.0, (angle / 2.0).sin()];
            let m = rl_measurement {
                star_tracker_wxyz: st,
                gyro_rad_s: [0.0, 0.0, 1e-5],
                ..fine(q)
            };
            let s = rl_loop_step(&mut *l, &*p, &m, &mut c);
            let want = core.step(
                core_planner.task(),
                &Measurement {
                    star_tracker: Some(st),
                    gyro: Some([0.0, 0.0, 1e-5]),
                    joints: Some(q),
                },
            );
            assert_eq!(
                c.rate_rad_s.map(f64::to_bits),
                want.rate.map(f64::to_bits),
                "cycle {k}"
            );
            assert_eq!(c.cycle, k);
            assert_eq!(c.event, 0);
            assert!(c.fault == RL_FAULT_NONE && c.base_estimate_rad[2] > 0.0 || k == 0);
            for (qi, v) in q.iter_mut().zip(held.iter()) {
                *qi += v * 0.1;
            }
            held = c.rate_rad_s;
            k += 1;
            if s == RL_DONE {
                break;
            }
            assert_eq!(s, RL_OK);
            assert!(k < 1000);
        }
        assert_eq!(c.mode, RL_LOOP_DONE);
        assert_eq!(c.finished, 1);
        // t_f and the 30 cycles after it (330), then the ramp to rest.
        assert!((330..=340).contains(&k), "{k} cycles");
        assert_eq!(rl_loop_step(&mut *l, &*p, &fine(q), &mut c), RL_DONE);
        assert_eq!(c.rate_rad_s, [0.0; 7]);
    }
}

/// Each fault (a NaN, a joint out of range, a stale sensor, a frozen encoder, a base error
/// past its limit) is reported once, in the cycle that found it, and the command then goes
/// to rest by at most `qdd_max T_c` per cycle; nothing leaves the safe state.
/// Verifies RL-FFI-014.
#[test]
#[allow(unsafe_code)]
fn each_fault_is_reported_once_and_ends_at_rest() {
    let p = planner("spec/tasks/paper.toml", true);
    let cfg = rl_loop_config::DEFAULT;
    let dv = cfg.qdd_max_rad_s2 * cfg.period_s;
    type Spoil = fn(&mut rl_measurement, u32);
    let cases: [(&str, Spoil, u32, u32); 5] = [
        (
            "NaN gyro",
            |m, _| m.gyro_rad_s[1] = f64::NAN,
            RL_FAULT_NOT_FINITE,
            RL_SENSOR_GYRO,
        ),
        (
            "joint 4 out of range",
            |m, _| m.joints_rad[3] = 100.0,
            RL_FAULT_OUT_OF_RANGE,
            RL_SENSOR_JOINTS,
        ),
        (
            "star tracker outage",
            |m, _| m.valid &= !RL_MEASURED_STAR_TRACKER,
            RL_FAULT_STALE,
            RL_SENSOR_STAR_TRACKER,
        ),
        (
            "frozen encoder",
            |m, k| m.joints_rad[1] -= 0.01 * f64::from(k - 60),
            RL_FAULT_TRACKING,
            RL_SENSOR_JOINTS,
        ),
        (
            "base past its limit",
            |m, _| {
                let a: f64 = 0.5_f64.to_radians();
                m.star_tracker_wxyz = [(a / 2.0).cos(), (a / 2.0).sin(), 0.0, 0.0];
            },
            RL_FAULT_BASE_ERROR,
            RL_SENSOR_NONE,
        ),
    ];
    for (what, spoil, fault, sensor) in cases {
        let mut l = Box::new(rl_loop::ZEROED);
        let mut c = rl_loop_command::ZEROED;
        let mut q = start();
        let mut events = 0;
        // SAFETY: every pointer is valid and exclusive for the call.
        unsafe {
            assert_eq!(
                rl_loop_init(
                    &mut *l,
                    RL_ABI_VERSION,
                    size_of::<rl_loop>(),
                    &*p,
                    &cfg,
                    &mut c
                ),
                RL_OK
            );
            let mut held = c.rate_rad_s;
            for k in 0..200u32 {
                let mut m = fine(q);
                if k >= 60 {
                    spoil(&mut m, k);
                }
                let before = c.rate_rad_s;
                let s = rl_loop_step(&mut *l, &*p, &m, &mut c);
                events += c.event;
                for (a, b) in before.iter().zip(c.rate_rad_s.iter()) {
                    assert!(
                        (a - b).abs() <= dv * (1.0 + 1e-12),
                        "{what}: cycle {k} jumps"
                    );
                }
                if c.event == 1 {
                    assert_eq!((c.fault, c.sensor), (fault, sensor), "{what}");
                    if fault == RL_FAULT_OUT_OF_RANGE {
                        assert_eq!(c.fault_joint, 4);
                    }
                    if fault == RL_FAULT_BASE_ERROR {
                        assert!(c.fault_value > LoopConfig::DEFAULT.base_limit);
                    }
                }
                for (qi, v) in q.iter_mut().zip(held.iter()) {
                    *qi += v * cfg.period_s;
                }
                held = c.rate_rad_s;
                if s == RL_DONE {
                    break;
                }
            }
            assert_eq!(events, 1, "{what}: reported once");
            assert_eq!(
                (c.mode, c.fault, c.finished),
                (RL_LOOP_STOPPED, fault, 1),
                "{what}"
            );
            assert_eq!(c.rate_rad_s, [0.0; 7], "{what}");
        }
    }
}
