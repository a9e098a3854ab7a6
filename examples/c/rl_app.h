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
    /* The joint controller's input: one setpoint. */
    void (*setpoint)(const rl_setpoint *sp);
    /* The Critical Data Store block: survives a processor reset. */
    uint8_t *cds;
    size_t cds_len;
} RL_AppServices;

/* Housekeeping telemetry. */
typedef struct {
    uint32_t wakeups;
    uint32_t checkpoints;
    uint32_t setpoints;
    uint32_t errors;
    int32_t last_status;
    uint8_t state; /* RL_APP_IDLE, RL_APP_PLANNING, RL_APP_STREAMING, RL_APP_FAILED */
} RL_AppHk;

enum { RL_APP_IDLE = 0, RL_APP_PLANNING = 1, RL_APP_STREAMING = 2, RL_APP_FAILED = 3 };

enum {
    RL_APP_EID_INIT = 1,
    RL_APP_EID_TABLE = 2,
    RL_APP_EID_RESTORED = 3,
    RL_APP_EID_PLANNED = 4,
    RL_APP_EID_STREAMED = 5,
    RL_APP_EID_ERROR = 10,
};

/* Initialisation (power-on or processor reset): the task table (a task block) is validated
 * and loaded; if the CDS holds a checkpoint of this task, planning resumes from it. */
int32_t RL_App_Init(const RL_AppServices *svc, const uint8_t *table, size_t table_len);
/* One scheduler wakeup message: one frame of planning (the table's frame budget) and a
 * checkpoint to the CDS, or a frame of setpoints once planned. */
void RL_App_Wakeup(void);
/* Housekeeping. */
const RL_AppHk *RL_App_Hk(void);

#endif
