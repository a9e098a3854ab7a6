//! The flight image: plans the task QEMU's loader placed in RAM with the reactionless core,
//! in frames of a fixed integration budget, and reports the plan's bits over defmt.
//!
//! Thin on purpose: every computation is the core's; this file only wires the task block,
//! the frame loop (an embedded-hal "planner busy" LED around each frame, a delay between
//! frames), the measurement markers and the report. A block with re-timing settings
//! (`RLTASK03`) also has the finished plan re-timed to minimum time and its setpoints
//! streamed (`reactionless::retime`), in a statically allocated grid of
//! [`RETIME_GRID_CAPACITY`] points. A two-phase block (`RLTASK04`, `RLTASK05`) is planned
//! in two phases (spec §15) by the resumable `reactionless::twophase::TwoPhaseSearch` (static),
//! one unit per frame, reported as phase 2's plan plus a `TWOPHASE` line
//! (how it ended, phase 1's digest and the wheels' demand) and `QS` lines; `RLTASK05`
//! re-times phase 2.
//!
//! After a single-phase plan the image also flies it closed-loop
//! (`reactionless::closed_loop::fly_ideal`) on a robot whose link masses are 5 % off, with
//! ideal sensors, and reports `LOOP`; each executor cycle runs between the cycle markers.
//!
//! Markers: the `rl_mark_*` functions do nothing but a distinct store; host-sim reads their
//! addresses from the ELF and QEMU's instruction-counting plugin logs the instruction count
//! each time one is entered.
#![no_std]
#![no_main]

mod board;
mod logger;

use board::{Delay, Led, exit, stack_high_water, task_block};
use cortex_m as _;
use cortex_m_rt::entry;
use embedded_hal::delay::DelayNs;
use embedded_hal::digital::OutputPin;
use reactionless::block::{RetimeSettings, decode};
use reactionless::retime::{self, GridPoint, Limits, Stream};
use reactionless::twophase::{TwoPhaseConfig, TwoPhasePlan, TwoPhaseSearch, TwoPhaseStatus};
use reactionless::{
    Error, Eta, Plan, Planner, Progress, Rollout, Status, Task, TrajectoryDigest, eta_flat,
    one_segment,
};

/// The flight robot's joint count and null-space dimension.
const N: usize = 7;
const K: usize = N - 3;
/// Swarm capacity of the flight image.
const P: usize = 64;
/// Re-timing grid capacity (points): the 3,000-point grid of the acceptance figures,
/// `64 × 3000 = 192,000` bytes of static RAM for `N = 7`.
const RETIME_GRID_CAPACITY: usize = 3000;

macro_rules! marker {
    ($name:ident, $id:expr) => {
        /// Region marker (see the crate documentation). The `nop` is an effect the compiler
        /// must keep and the distinct id keeps the markers from being merged.
        #[allow(unsafe_code)]
        #[unsafe(no_mangle)]
        #[inline(never)]
        pub extern "C" fn $name() {
            core::hint::black_box($id as u32);
            cortex_m::asm::nop();
        }
    };
}
marker!(rl_mark_call_begin, 1);
marker!(rl_mark_call_end, 2);
marker!(rl_mark_rollout_begin, 3);
marker!(rl_mark_rollout_end, 4);
marker!(rl_mark_step_begin, 5);
marker!(rl_mark_step_end, 6);
marker!(rl_mark_retime_begin, 7);
marker!(rl_mark_retime_end, 8);
marker!(rl_mark_stream_begin, 9);
marker!(rl_mark_stream_end, 10);
marker!(rl_mark_cycle_begin, 11);
marker!(rl_mark_cycle_end, 12);

/// The statically allocated planner, handed out once.
fn planner_slot() -> Option<&'static mut Planner<N, K, P>> {
    static mut PLANNER: Planner<N, K, P> = Planner::IDLE;
    static TAKEN: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);
    if TAKEN.swap(true, core::sync::atomic::Ordering::Relaxed) {
        return None;
    }
    // SAFETY: TAKEN makes this the only reference ever created to PLANNER (single core,
    // no interrupts touch it).
    #[allow(unsafe_code)]
    Some(unsafe { &mut *core::ptr::addr_of_mut!(PLANNER) })
}

/// The statically allocated truth task of the closed-loop flight, handed out once.
fn truth_slot() -> Option<&'static mut Task<N, K>> {
    static mut TRUTH: Task<N, K> = Task::IDLE;
    static TAKEN: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);
    if TAKEN.swap(true, core::sync::atomic::Ordering::Relaxed) {
        return None;
    }
    // SAFETY: TAKEN makes this the only reference ever created to TRUTH (single core, no
    // interrupts touch it).
    #[allow(unsafe_code)]
    Some(unsafe { &mut *core::ptr::addr_of_mut!(TRUTH) })
}

/// The statically allocated re-timing grid, handed out once.
fn grid_slot() -> Option<&'static mut [GridPoint<N>; RETIME_GRID_CAPACITY]> {
    static mut GRID: [GridPoint<N>; RETIME_GRID_CAPACITY] = [GridPoint::ZERO; RETIME_GRID_CAPACITY];
    static TAKEN: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);
    if TAKEN.swap(true, core::sync::atomic::Ordering::Relaxed) {
        return None;
    }
    // SAFETY: TAKEN makes this the only reference ever created to GRID (single core, no
    // interrupts touch it).
    #[allow(unsafe_code)]
    Some(unsafe { &mut *core::ptr::addr_of_mut!(GRID) })
}

/// The statically allocated two-phase search, handed out once.
fn search_slot() -> Option<&'static mut TwoPhaseSearch<N, K>> {
    static mut SCRATCH: TwoPhaseSearch<N, K> = TwoPhaseSearch::IDLE;
    static TAKEN: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);
    if TAKEN.swap(true, core::sync::atomic::Ordering::Relaxed) {
        return None;
    }
    // SAFETY: TAKEN makes this the only reference ever created to SCRATCH (single core, no
    // interrupts touch it).
    #[allow(unsafe_code)]
    Some(unsafe { &mut *core::ptr::addr_of_mut!(SCRATCH) })
}

/// Units of the two-phase search per frame: the finest slice, so the largest frame is the
/// search's largest unit (accepting a start: phase 2 on the truth model).
const TWO_PHASE_UNITS_PER_FRAME: u32 = 1;

/// The integration step timed on its own (inside the plan's rollout).
const TIMED_STEP: u32 = 1500;

#[entry]
fn main() -> ! {
    defmt::println!("reactionless firmware {=str}", env!("CARGO_PKG_VERSION"));
    defmt::println!(
        "SIZES planner={=usize} task={=usize} rollout={=usize} grid={=usize} scratch={=usize}",
        core::mem::size_of::<Planner<N, K, P>>(),
        core::mem::size_of::<reactionless::Task<N, K>>(),
        core::mem::size_of::<Rollout<N, K>>(),
        core::mem::size_of::<[GridPoint<N>; RETIME_GRID_CAPACITY]>(),
        core::mem::size_of::<TwoPhaseSearch<N, K>>()
    );
    #[cfg(feature = "panic-canary")]
    canary();
    let code = match run() {
        Ok(()) => 0,
        Err(e) => {
            defmt::println!("ERROR {}", e);
            1
        }
    };
    let (used, size) = stack_high_water();
    defmt::println!("STACK {=u32} {=u32}", used, size);
    defmt::println!("EXIT {=i32}", code);
    exit(code)
}

fn run() -> Result<(), Error> {
    let planner = planner_slot().ok_or(Error::NotInitialized)?;
    let Loaded {
        frame_budget,
        retime,
        two_phase,
        seed,
    } = load(planner)?;
    if let Some(config) = two_phase {
        defmt::println!("PLAN two_phase");
        return plan_two_phase(planner, &config, seed, retime.as_ref());
    }
    defmt::println!("PLAN frame_budget={=u32}", frame_budget);
    let (plan, frames) = plan(planner, frame_budget)?;
    measure(planner.task(), &plan, frames)?;
    closed_loop(planner.task(), &plan.eta)?;
    match retime {
        Some(settings) => {
            let [first, ..] = &plan.eta;
            retime_and_stream(planner.task(), first, &settings)
        }
        None => Ok(()),
    }
}

/// What the block asks for beyond the task the planner now holds.
struct Loaded {
    frame_budget: u32,
    retime: Option<RetimeSettings<N>>,
    two_phase: Option<TwoPhaseConfig>,
    seed: u64,
}

/// Decodes the task block and gives the planner its task, in place. Its own frame: the
/// block, the robot and the task are dropped before planning starts.
#[inline(never)]
fn load(planner: &mut Planner<N, K, P>) -> Result<Loaded, Error> {
    let block = decode::<N>(task_block())?;
    block.load_into(planner)?;
    Ok(Loaded {
        frame_budget: block.planner.frame_budget,
        retime: block.retime,
        two_phase: block.two_phase,
        seed: block.planner.seed,
    })
}

/// Plans the planner's task in two phases with the static search, one unit per frame
/// ([`TWO_PHASE_UNITS_PER_FRAME`]; each frame timed as a call, the LED on while it runs),
/// moves the task's start to phase 2's `q_s`, reports phase 2 as a plan (`RESULT`, `ETA`,
/// `POSE`, its rollout and one step timed, as [`measure`]) and the rest (`TWOPHASE`, `QS`);
/// with `retime`, re-times phase 2.
#[inline(never)]
fn plan_two_phase(
    planner: &mut Planner<N, K, P>,
    config: &TwoPhaseConfig,
    seed: u64,
    retime: Option<&RetimeSettings<N>>,
) -> Result<(), Error> {
    let search = search_slot().ok_or(Error::NotInitialized)?;
    let task = planner.task_mut();
    search.reset(task, config, seed)?;
    let mut busy = Led::new(0);
    let mut delay = Delay;
    let mut frames: u32 = 0;
    let p: TwoPhasePlan<N, K> = loop {
        let _ = busy.set_high();
        rl_mark_call_begin();
        let s = search.step(TWO_PHASE_UNITS_PER_FRAME)?;
        rl_mark_call_end();
        let _ = busy.set_low();
        frames += 1;
        match s {
            TwoPhaseStatus::Running => delay.delay_us(1),
            TwoPhaseStatus::Finished(p) => break p,
        }
    };
    let mut phase1 = TrajectoryDigest::new();
    p.preshape.write(&mut phase1);
    task.move_start(&p.q_s)?;
    let (converged, rollouts) = (p.converged(), p.rollouts);
    match &p.outcome {
        Some(outcome) => report(
            task,
            &one_segment(p.eta),
            outcome,
            Counts {
                converged,
                iterations: 0,
                rollouts,
                stagnation: 0,
                restarts: 0,
                frames,
            },
        )?,
        None => {
            // Nothing was rolled out (a target beyond reach): no pose, the empty digest.
            defmt::println!(
                "RESULT converged=false iterations=0 rollouts={=u32} stagnation=0 restarts=0 frames={=u32} f={=u64:#018x} samples=0 digest={=u64:#018x} reproducible=true",
                rollouts,
                frames,
                f64::NAN.to_bits(),
                TrajectoryDigest::new().value()
            );
            for (i, v) in p.eta.iter().flatten().enumerate() {
                defmt::println!("ETA {=usize} {=u64:#018x}", i, v.to_bits());
            }
        }
    }
    let d = &p.demand;
    defmt::println!(
        "TWOPHASE stop={=str} starts={=u32} reach_f={=u64:#018x} base={=u64:#018x} steps1={=u32} samples1={=u32} digest1={=u64:#018x} momentum={=u64:#018x} torque={=u64:#018x} shift_x={=u64:#018x} shift_y={=u64:#018x} shift_z={=u64:#018x}",
        p.stop.name(),
        p.starts,
        p.reach_f.to_bits(),
        p.base_disturbance.to_bits(),
        p.preshape.steps(),
        phase1.samples(),
        phase1.value(),
        d.momentum_nms.to_bits(),
        d.torque_nm.to_bits(),
        d.base_shift_m[0].to_bits(),
        d.base_shift_m[1].to_bits(),
        d.base_shift_m[2].to_bits()
    );
    for (i, v) in p.q_s.iter().enumerate() {
        defmt::println!("QS {=usize} {=u64:#018x}", i, v.to_bits());
    }
    match (retime, &p.outcome) {
        (Some(settings), Some(_)) => retime_and_stream(task, &p.eta, settings),
        _ => Ok(()),
    }
}

/// Re-times the plan's path to minimum time in the static grid (timed: the path's two
/// rollouts and the solve, with its streams measuring the written samples), then streams
/// every setpoint into a digest (timed), and reports.
#[inline(never)]
fn retime_and_stream(
    task: &Task<N, K>,
    eta: &[[f64; 2]; K],
    settings: &RetimeSettings<N>,
) -> Result<(), Error> {
    let grid = grid_slot().ok_or(Error::NotInitialized)?;
    let qd_max = task.robot().desc().joints.map(|j| j.velocity);
    let limits = Limits::new(qd_max, settings.qdd_max, settings.margin)?;
    rl_mark_retime_begin();
    let path = retime::path_of_rollout(task, eta, grid, settings.grid)?;
    // Solved until what the stream writes keeps the limits (spec §11), measured on the
    // written samples: the stream below is held to the same definition.
    let (profile, _) = retime::solve_written(grid, &path, &limits, task.motion().dt())?;
    rl_mark_retime_end();
    let mut stream = Stream::new(&profile, task.motion().dt())?;
    let mut digest = TrajectoryDigest::new();
    let mut setpoints: u32 = 0;
    rl_mark_stream_begin();
    // Bounded: a stream yields steps + 1 setpoints, steps ≤ MAX_STEPS.
    while let Some(sp) = stream.next(grid) {
        sp.digest(&mut digest);
        setpoints += 1;
    }
    rl_mark_stream_end();
    defmt::println!(
        "RETIME grid={=u32} steps={=u32} optimal={=u64:#018x} setpoints={=u32} digest={=u64:#018x}",
        settings.grid,
        stream.steps(),
        profile.duration().to_bits(),
        setpoints,
        digest.value()
    );
    Ok(())
}

/// Plans in frames: the "planner busy" LED is on while the planner runs, a short pause
/// separates frames. Returns the finished plan and the number of frames.
#[inline(never)]
fn plan(planner: &mut Planner<N, K, P>, frame_budget: u32) -> Result<(Plan<N, K>, u32), Error> {
    let mut busy = Led::new(0);
    let mut delay = Delay;
    let mut frames: u32 = 0;
    loop {
        let _ = busy.set_high();
        rl_mark_call_begin();
        let s = planner.step(frame_budget, &mut ())?;
        rl_mark_call_end();
        let _ = busy.set_low();
        frames += 1;
        match s {
            Status::Running(_) => delay.delay_us(1),
            Status::Finished(plan) => return Ok((plan, frames)),
        }
    }
}

/// Re-runs the plan's rollout (timed), its digest and one step (timed), and reports.
#[inline(never)]
fn measure(task: &Task<N, K>, plan: &Plan<N, K>, frames: u32) -> Result<(), Error> {
    report(
        task,
        &plan.eta,
        &plan.outcome,
        Counts {
            converged: plan.converged(),
            iterations: plan.iterations,
            rollouts: plan.rollouts,
            stagnation: plan.stagnation_events,
            restarts: plan.restarts,
            frames,
        },
    )
}

/// Flies the plan closed-loop on a robot whose link masses are 5 % off, with ideal
/// sensors (`reactionless::closed_loop::fly_ideal`), each executor cycle between the cycle
/// markers, and reports it (`LOOP`: cycles, the commands' digest, the largest base
/// rotation's bits, the executor's size).
#[inline(never)]
fn closed_loop(task: &Task<N, K>, eta: &Eta<K>) -> Result<(), Error> {
    use reactionless::closed_loop::{Executor, LoopConfig, Mode, fly_ideal};
    let truth = truth_slot().ok_or(Error::NotInitialized)?;
    load_truth(truth, task)?;
    let f = fly_ideal(task, truth, eta, LoopConfig::DEFAULT, &mut |begin| {
        if begin {
            rl_mark_cycle_begin();
        } else {
            rl_mark_cycle_end();
        }
    })?;
    defmt::println!(
        "LOOP cycles={=u32} digest={=u64:#018x} max_angle={=u64:#018x} done={=bool} executor={=usize}",
        f.cycles,
        f.digest,
        f.max_angle.to_bits(),
        f.mode == Mode::Done,
        core::mem::size_of::<Executor<N>>()
    );
    Ok(())
}

/// Builds the closed loop's truth task (the mistaken robot) into `slot`, in a frame of its
/// own: the robot and the task are off the stack before the flight starts.
#[inline(never)]
fn load_truth(slot: &mut Task<N, K>, task: &Task<N, K>) -> Result<(), Error> {
    let desc = reactionless::closed_loop::mistaken(task.robot().desc());
    slot.init(&desc, *task.start(), *task.target(), *task.motion())
}

/// The counts a `RESULT` line reports.
struct Counts {
    converged: bool,
    iterations: u32,
    rollouts: u32,
    stagnation: u32,
    restarts: u32,
    frames: u32,
}

/// Re-runs the rollout of `eta` (timed), its digest and one step (timed), and reports them
/// with `outcome` (the planner's rollout of `eta`) and the counts.
#[inline(never)]
fn report(
    task: &Task<N, K>,
    eta: &Eta<K>,
    o: &reactionless::Outcome<N>,
    c: Counts,
) -> Result<(), Error> {
    rl_mark_rollout_begin();
    let again = task.rollout_of(eta, &mut ())?;
    rl_mark_rollout_end();
    let mut digest = TrajectoryDigest::new();
    task.rollout_of(eta, &mut digest)?;
    // Worked on inside the `Result`: moving the rollout out would copy it on the stack.
    let mut made = Rollout::of(task, eta);
    let r = match &mut made {
        Ok(r) => r,
        Err(e) => return Err(*e),
    };
    r.advance(task, TIMED_STEP, &mut ())?;
    rl_mark_step_begin();
    let p = r.advance(task, 1, &mut ())?;
    rl_mark_step_end();
    let same = again == *o && matches!(p, Progress::Running { .. });

    defmt::println!(
        "RESULT converged={=bool} iterations={=u32} rollouts={=u32} stagnation={=u32} restarts={=u32} frames={=u32} f={=u64:#018x} samples={=u32} digest={=u64:#018x} reproducible={=bool}",
        c.converged,
        c.iterations,
        c.rollouts,
        c.stagnation,
        c.restarts,
        c.frames,
        o.f.to_bits(),
        digest.samples(),
        digest.value(),
        same
    );
    for (i, v) in eta_flat(eta, task.motion().segments()).enumerate() {
        defmt::println!("ETA {=usize} {=u64:#018x}", i, v.to_bits());
    }
    for (i, v) in o
        .end_pose
        .position
        .iter()
        .chain(o.end_pose.quat_wxyz.iter())
        .enumerate()
    {
        defmt::println!("POSE {=usize} {=u64:#018x}", i, v.to_bits());
    }
    Ok(())
}

/// A panic path no optimisation can remove (an index read from the task block): with the
/// `panic-canary` feature the image must fail to link.
#[cfg(feature = "panic-canary")]
#[inline(never)]
#[allow(clippy::indexing_slicing)]
fn canary() {
    let table = [1u8, 2, 3, 4];
    let i = usize::from(task_block().first().copied().unwrap_or(0));
    defmt::println!("canary {=u8}", table[i]);
}

/// Release images prove panic freedom at link time: this handler calls a function that
/// exists nowhere, so if any panic path survives optimisation the link fails.
#[cfg(not(debug_assertions))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    #[allow(unsafe_code)]
    unsafe extern "Rust" {
        fn reactionless_firmware_panic_path_survived_optimisation() -> !;
    }
    // SAFETY: never executed: the symbol does not exist, so an image that could reach this
    // line does not link.
    #[allow(unsafe_code)]
    unsafe {
        reactionless_firmware_panic_path_survived_optimisation()
    }
}

/// Debug images (not optimised, so bounds checks remain) report and stop.
#[cfg(debug_assertions)]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    defmt::println!("PANIC");
    exit(101)
}
