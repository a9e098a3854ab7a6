/* RL_APP: a cFS-style cyclic application around the reactionless planner, in plain C99.
 *
 * The shape of NASA cFS's sample_app: all state in static app data (the planner's ~38 KB
 * included, never on the stack), resources only at init, one scheduler wakeup per cycle
 * with a fixed planning budget per wakeup (the task table's frame budget), failures
 * reported as error events, and what must survive a processor reset in the Critical Data
 * Store: a checkpoint written after every planning frame. After a reset, RL_App_Init finds
 * the checkpoint, restores it, and planning continues bit for bit where it stopped. Once
 * planned, the plan is flown closed-loop (rl_loop, the default settings: 10 Hz): each
 * wakeup is one control cycle. It hands the joint controller the rate command computed
 * in the last wakeup (one period of latency, as the loop assumes), reads the sensors,
 * computes the next command, and streams the period's setpoints of the plan as the
 * reference. A sensor fault is an error event once; the loop then brings the arm to rest
 * within its acceleration limit and the app stays in its safe state. Not handled here: a
 * processor reset during the flight (the joint controller must stop the joints on a reset;
 * the app then plans afresh). */
#include "rl_app.h"

#include <string.h>

/* Setpoints of the plan per wakeup: one control period (0.1 s) at the task's dt (10 ms). */
#define RL_APP_SETPOINTS_PER_WAKEUP 10u

static struct {
    RL_AppServices svc;
    rl_planner planner;
    rl_setpoints stream;
    rl_loop flight;
    rl_loop_command pending; /* computed last wakeup, handed to the joints this one */
    uint8_t streaming;       /* 1 until the setpoint stream is done */
    rl_plan plan;
    uint32_t budget;
    RL_AppHk hk;
} App;

static void fail(const char *what, rl_status s) {
    App.hk.errors++;
    App.hk.last_status = s;
    App.hk.state = RL_APP_FAILED;
    App.svc.event(RL_APP_EID_ERROR, "ERROR", what, s);
    App.svc.event(RL_APP_EID_ERROR, "ERROR", rl_status_str(s), s);
}

int32_t RL_App_Init(const RL_AppServices *svc, const uint8_t *table, size_t table_len) {
    rl_status s;
    memset(&App.hk, 0, sizeof App.hk);
    App.svc = *svc;
    s = RL_PLANNER_INIT(&App.planner);
    if (s != RL_OK) {
        fail("planner init (header and library disagree)", s);
        return s;
    }
    /* Table validation: magic, joint count, length, CRC-32, then every value. */
    s = rl_planner_load_block(&App.planner, table, table_len);
    if (s != RL_OK) {
        fail("task table rejected", s);
        return s;
    }
    (void)rl_planner_frame_budget(&App.planner, &App.budget);
    App.svc.event(RL_APP_EID_TABLE, "INFO", "task table loaded", (int32_t)App.budget);
    /* A checkpoint in the CDS from before a processor reset: resume from it. */
    s = rl_planner_restore(&App.planner, App.svc.cds, App.svc.cds_len);
    if (s == RL_OK) {
        App.svc.event(RL_APP_EID_RESTORED, "INFO", "planner restored from the CDS", s);
    } else {
        /* No valid checkpoint (first power-on, another task, corruption): plan afresh. */
        App.svc.event(RL_APP_EID_INIT, "INFO", "no usable checkpoint, planning afresh", s);
    }
    App.hk.state = RL_APP_PLANNING;
    return RL_OK;
}

static void fly_cycle(void);
static void stream_frame(void);

static void plan_frame(void) {
    rl_status s = rl_planner_step(&App.planner, App.budget, &App.plan);
    App.hk.last_status = s;
    if (s == RL_RUNNING) {
        s = rl_planner_checkpoint(&App.planner, App.svc.cds, App.svc.cds_len);
        if (s != RL_OK) {
            fail("checkpoint to the CDS", s);
            return;
        }
        App.hk.checkpoints++;
        return;
    }
    if (s != RL_CONVERGED && s != RL_EXHAUSTED && s != RL_STALLED) {
        fail("planning", s);
        return;
    }
    App.svc.event(RL_APP_EID_PLANNED, "INFO",
                  s == RL_CONVERGED ? "plan converged" : rl_status_str(s),
                  (int32_t)App.plan.rollouts);
    /* The plan is done: a stale checkpoint must not resume planning after a reset. */
    memset(App.svc.cds, 0, App.svc.cds_len);
    s = rl_setpoints_init(&App.stream, &App.planner);
    if (s != RL_OK) {
        fail("setpoint stream", s);
        return;
    }
    App.streaming = 1;
    /* Cycle 0's command (the plan's own, from rest) goes out in this wakeup, t = 0. */
    s = RL_LOOP_INIT(&App.flight, &App.planner, NULL, &App.pending);
    if (s != RL_OK) {
        fail("closed-loop flight", s);
        return;
    }
    App.hk.state = RL_APP_FLYING;
    stream_frame();
    fly_cycle();
}

/* The period's setpoints of the plan, the joint controller's reference (the first, t = 0,
 * in the wakeup that starts the flight). */
static void stream_frame(void) {
    uint32_t i;
    rl_setpoint sp;
    for (i = 0; App.streaming && i < RL_APP_SETPOINTS_PER_WAKEUP; i++) {
        rl_status s = rl_setpoints_next(&App.stream, &App.planner, &sp);
        if (s == RL_DONE) {
            App.svc.event(RL_APP_EID_STREAMED, "INFO", "trajectory streamed",
                          (int32_t)App.hk.setpoints);
            App.streaming = 0;
            return;
        }
        if (s != RL_OK) {
            /* The reference is telemetry: losing it must not stop the flight, whose loop
             * keeps commanding (its own rollout reports a failure as RL_FAULT_MODEL and
             * brings the arm to rest). */
            App.hk.errors++;
            App.svc.event(RL_APP_EID_ERROR, "ERROR", "setpoint stream lost", s);
            App.streaming = 0;
            return;
        }
        App.svc.setpoint(&sp);
        App.hk.setpoints++;
    }
}

/* One control cycle: last wakeup's command to the joints, then this wakeup's measurements
 * give the command held through the next period. */
static void fly_cycle(void) {
    rl_measurement m;
    rl_status s;
    uint32_t degraded = App.hk.loop_mode == RL_LOOP_DEGRADED;
    App.svc.command(&App.pending);
    App.hk.commands++;
    App.hk.limited += App.pending.limited;
    if (App.pending.finished) {
        /* The command that brought the arm to rest is out: the flight is over. */
        if (App.pending.mode == RL_LOOP_DONE) {
            App.svc.event(RL_APP_EID_FLOWN, "INFO", "closed-loop flight complete",
                          (int32_t)App.hk.commands);
            App.hk.state = RL_APP_IDLE;
        } else {
            App.svc.event(RL_APP_EID_SAFE, "INFO", "arm at rest in the safe state",
                          (int32_t)App.pending.fault);
            App.hk.state = RL_APP_SAFE;
        }
        return;
    }
    App.svc.measure(&m);
    s = rl_loop_step(&App.flight, &App.planner, &m, &App.pending);
    App.hk.last_status = s;
    if (s != RL_OK && s != RL_DONE) {
        /* A misuse of the ABI (a bug), not a sensor fault: no valid command exists, so the
         * joints are told to stop now rather than hold their last rate. */
        static const rl_loop_command halt;
        App.svc.command(&halt);
        fail("closed-loop step", s);
        return;
    }
    App.hk.loop_mode = App.pending.mode;
    App.hk.loop_fault = App.pending.fault;
    if (App.pending.event) {
        App.hk.errors++;
        App.svc.event(RL_APP_EID_FAULT, "ERROR", rl_loop_fault_str(App.pending.fault),
                      (int32_t)App.pending.sensor);
    } else if (App.pending.mode == RL_LOOP_DEGRADED && !degraded) {
        App.svc.event(RL_APP_EID_DEGRADED, "INFO", "a sensor is missing: flying on dead reckoning",
                      (int32_t)App.pending.sensor);
    }
}

void RL_App_Wakeup(void) {
    App.hk.wakeups++;
    switch (App.hk.state) {
    case RL_APP_PLANNING:
        plan_frame();
        break;
    case RL_APP_FLYING:
        stream_frame();
        fly_cycle();
        break;
    default:
        break;
    }
}

const RL_AppHk *RL_App_Hk(void) { return &App.hk; }
