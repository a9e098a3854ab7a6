/* RL_APP: a cFS-style cyclic application around the reactionless planner (see rl_app.c). */
#ifndef RL_APP_H
#define RL_APP_H

#include <stddef.h>
#include <stdint.h>

#include "reactionless.h"

/* What the app's "platform" provides (cFE services in a real cFS app). */
typedef struct {
    /* CFE_EVS_SendEvent: an event with an id, a severity ("INFO"/"ERROR") and a text. */
    void (*event)(uint16_t id, const char *severity, const char *text, int32_t code);
    /* The plan's setpoints, streamed as the joint controller's reference (telemetry). */
    void (*setpoint)(const rl_setpoint *sp);
    /* The sensors' readings at this wakeup (star tracker, gyro, joint encoders). */
    void (*measure)(rl_measurement *m);
    /* The joint controller's rate command: hold cmd->rate_rad_s until the next one. */
    void (*command)(const rl_loop_command *cmd);
    /* The Critical Data Store block: survives a processor reset. */
    uint8_t *cds;
    size_t cds_len;
} RL_AppServices;

/* Housekeeping telemetry. */
typedef struct {
    uint32_t wakeups;
    uint32_t checkpoints;
    uint32_t setpoints;
    uint32_t commands; /* rate commands handed to the joint controller */
    uint32_t limited;  /* of which a limit (rate, acceleration, range) changed */
    uint32_t errors;
    int32_t last_status;
    uint32_t loop_mode;  /* RL_LOOP_* of the last command */
    uint32_t loop_fault; /* RL_FAULT_* of the last command */
    uint8_t state; /* RL_APP_IDLE, RL_APP_PLANNING, RL_APP_FLYING, RL_APP_FAILED, RL_APP_SAFE */
} RL_AppHk;

enum {
    RL_APP_IDLE = 0,
    RL_APP_PLANNING = 1,
    RL_APP_FLYING = 2,
    RL_APP_FAILED = 3,
    RL_APP_SAFE = 4 /* the loop brought the arm to rest after a fault */
};

enum {
    RL_APP_EID_INIT = 1,
    RL_APP_EID_TABLE = 2,
    RL_APP_EID_RESTORED = 3,
    RL_APP_EID_PLANNED = 4,
    RL_APP_EID_STREAMED = 5,
    RL_APP_EID_FLOWN = 6,
    RL_APP_EID_DEGRADED = 7,
    RL_APP_EID_SAFE = 8,
    RL_APP_EID_ERROR = 10,
    RL_APP_EID_FAULT = 11,
};

/* Initialisation (power-on or processor reset): the task table (a task block) is validated
 * and loaded; if the CDS holds a checkpoint of this task, planning resumes from it. */
int32_t RL_App_Init(const RL_AppServices *svc, const uint8_t *table, size_t table_len);
/* One scheduler wakeup message, one per control period (10 Hz): one frame of planning (the
 * table's frame budget) and a checkpoint to the CDS; once planned, one closed-loop control
 * cycle (the pending rate command to the joint controller, the sensors read, the next
 * command computed) and the period's setpoints of the plan. */
void RL_App_Wakeup(void);
/* Housekeeping. */
const RL_AppHk *RL_App_Hk(void);

#endif
