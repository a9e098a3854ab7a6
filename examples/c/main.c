/* A stand-in for cFE on the host: a scheduler that sends RL_APP a wakeup per cycle, an event
 * log, a CDS that survives a simulated processor reset (after wakeup RESET_AT the app's
 * initialisation, RL_App_Init, runs again over its static data and finds the checkpoint),
 * and a joint controller that folds the setpoints into the FNV-1a-64 trajectory digest.
 * Usage: rl_app_demo BLOCK   (a block from `host-sim block TASK --out BLOCK`) */
#include <stdio.h>
#include <string.h>

#include "rl_app.h"

#define RESET_AT 40u

static uint8_t cds[RL_CHECKPOINT_CAPACITY]; /* the Critical Data Store block */
static uint8_t table[4096];
static uint64_t digest = 0xcbf29ce484222325ull;

static void event(uint16_t id, const char *severity, const char *text, int32_t code) {
    printf("EVS %-5s id=%u %s (%d)\n", severity, (unsigned)id, text, (int)code);
}

static void fold(double x) {
    uint64_t b;
    int i;
    memcpy(&b, &x, sizeof b);
    for (i = 0; i < 8; i++) {
        digest = (digest ^ ((b >> (8 * i)) & 0xffu)) * 0x00000100000001b3ull;
    }
}

static void setpoint(const rl_setpoint *sp) {
    int i;
    fold(sp->t);
    for (i = 0; i < RL_JOINTS; i++) fold(sp->q[i]);
    for (i = 0; i < RL_JOINTS; i++) fold(sp->qd[i]);
}

int main(int argc, char **argv) {
    RL_AppServices svc = {event, setpoint, cds, sizeof cds};
    uint32_t cycle;
    size_t n;
    FILE *f;
    if (argc != 2 || (f = fopen(argv[1], "rb")) == NULL) {
        fputs("usage: rl_app_demo BLOCK\n", stderr);
        return 2;
    }
    n = fread(table, 1, sizeof table, f);
    fclose(f);
    printf("sizeof(rl_planner) %u, sizeof(rl_setpoints) %u, checkpoint %u bytes\n",
           (unsigned)sizeof(rl_planner), (unsigned)sizeof(rl_setpoints),
           (unsigned)rl_checkpoint_size());
    if (RL_App_Init(&svc, table, n) != RL_OK) return 1;
    for (cycle = 1; RL_App_Hk()->state == RL_APP_PLANNING || RL_App_Hk()->state == RL_APP_STREAMING;
         cycle++) {
        RL_App_Wakeup();
        if (cycle == RESET_AT) {
            printf("-- processor reset after wakeup %u (CDS kept) --\n", (unsigned)cycle);
            if (RL_App_Init(&svc, table, n) != RL_OK) return 1;
        }
    }
    printf("HK wakeups=%u checkpoints=%u setpoints=%u errors=%u\n",
           (unsigned)RL_App_Hk()->wakeups, (unsigned)RL_App_Hk()->checkpoints,
           (unsigned)RL_App_Hk()->setpoints, (unsigned)RL_App_Hk()->errors);
    printf("DIGEST 0x%016llx\n", (unsigned long long)digest);
    return RL_App_Hk()->state == RL_APP_IDLE && RL_App_Hk()->errors == 0 ? 0 : 1;
}
