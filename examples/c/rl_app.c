/* RL_APP: a cFS-style cyclic application around the reactionless planner, in plain C99.
 *
 * The shape of NASA cFS's sample_app: all state in static app data (the planner's ~38 KB
 * included, never on the stack), resources only at init, one scheduler wakeup per cycle
 * with a fixed planning budget per wakeup (the task table's frame budget), failures
 * reported as error events, and what must survive a processor reset in the Critical Data
 * Store: a checkpoint written after every planning frame. After a reset, RL_App_Init finds
 * the checkpoint, restores it, and planning continues bit for bit where it stopped. Once
 * planned, each wakeup streams a frame of setpoints to the joint controller. */
#include "rl_app.h"

#include <string.h>

/* Setpoints handed to the joint controller per wakeup (1 s of trajectory at dt = 10 ms). */
#define RL_APP_SETPOINTS_PER_WAKEUP 100u

static struct {
    RL_AppServices svc;
    rl_planner planner;
    rl_setpoints stream;
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
    App.hk.state = RL_APP_STREAMING;
}

static void stream_frame(void) {
    uint32_t i;
    rl_setpoint sp;
    for (i = 0; i < RL_APP_SETPOINTS_PER_WAKEUP; i++) {
        rl_status s = rl_setpoints_next(&App.stream, &App.planner, &sp);
        if (s == RL_DONE) {
            App.svc.event(RL_APP_EID_STREAMED, "INFO", "trajectory streamed",
                          (int32_t)App.hk.setpoints);
            App.hk.state = RL_APP_IDLE;
            return;
        }
        if (s != RL_OK) {
            fail("streaming setpoints", s);
            return;
        }
        App.svc.setpoint(&sp);
        App.hk.setpoints++;
    }
}

void RL_App_Wakeup(void) {
    App.hk.wakeups++;
    switch (App.hk.state) {
    case RL_APP_PLANNING:
        plan_frame();
        break;
    case RL_APP_STREAMING:
        stream_frame();
        break;
    default:
        break;
    }
}

const RL_AppHk *RL_App_Hk(void) { return &App.hk; }
