/* A stand-in for cFE on the host: a scheduler that sends RL_APP a wakeup per control period,
 * an event log, a CDS that survives a simulated processor reset (after wakeup RESET_AT the
 * app's initialisation, RL_App_Init, runs again over its static data and finds the
 * checkpoint), and the hardware: a joint controller that folds the setpoints into the
 * FNV-1a-64 trajectory digest and the rate commands into a second one, joints that follow
 * each command exactly over its period, encoders that read them exactly, and a base held
 * still (the star tracker reads the identity, the gyro zero; no dynamics here: host-sim's
 * truth model flies the loop on a real robot).
 * Usage: rl_app_demo BLOCK [FAULT_AT]   (a block from `host-sim block TASK --out BLOCK`;
 * FAULT_AT: the encoders read NaN from that wakeup of the flight on) */
#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#include "rl_app.h"

#define RESET_AT 40u

static uint8_t cds[RL_CHECKPOINT_CAPACITY]; /* the Critical Data Store block */
static uint8_t table[4096];
static uint64_t digest = 0xcbf29ce484222325ull;
static uint64_t loop_digest = 0xcbf29ce484222325ull;
static double q[RL_JOINTS];    /* the joints' true angles (rad) */
static double held[RL_JOINTS]; /* the rate command the joints hold (rad/s) */
static uint32_t flight_wakeups, fault_at;

static void event(uint16_t id, const char *severity, const char *text, int32_t code) {
    printf("EVS %-5s id=%u %s (%d)\n", severity, (unsigned)id, text, (int)code);
}

static void fold(uint64_t *d, double x) {
    uint64_t b;
    int i;
    memcpy(&b, &x, sizeof b);
    for (i = 0; i < 8; i++) {
        *d = (*d ^ ((b >> (8 * i)) & 0xffu)) * 0x00000100000001b3ull;
    }
}

static void setpoint(const rl_setpoint *sp) {
    int i;
    fold(&digest, sp->t);
    for (i = 0; i < RL_JOINTS; i++) fold(&digest, sp->q[i]);
    for (i = 0; i < RL_JOINTS; i++) fold(&digest, sp->qd[i]);
    /* The first setpoint is the start: the joints are there before the flight. */
    if (sp->t == 0.0) memcpy(q, sp->q, sizeof q);
}

static void measure(rl_measurement *m) {
    memset(m, 0, sizeof *m);
    m->valid = RL_MEASURED_STAR_TRACKER | RL_MEASURED_GYRO | RL_MEASURED_JOINTS;
    m->star_tracker_wxyz[0] = 1.0;
    memcpy(m->joints_rad, q, sizeof q);
    if (fault_at != 0 && flight_wakeups >= fault_at) m->joints_rad[2] = NAN;
}

static void command(const rl_loop_command *cmd) {
    int i;
    for (i = 0; i < RL_JOINTS; i++) fold(&loop_digest, cmd->rate_rad_s[i]);
    memcpy(held, cmd->rate_rad_s, sizeof held);
}

int main(int argc, char **argv) {
    RL_AppServices svc = {event, setpoint, measure, command, cds, sizeof cds};
    rl_loop_config config;
    uint32_t cycle;
    size_t n;
    int i;
    FILE *f;
    if (argc < 2 || argc > 3 || (f = fopen(argv[1], "rb")) == NULL) {
        fputs("usage: rl_app_demo BLOCK [FAULT_AT]\n", stderr);
        return 2;
    }
    if (argc == 3) fault_at = (uint32_t)strtoul(argv[2], NULL, 10);
    (void)rl_loop_config_default(&config); /* the app flies the defaults: T_c */
    n = fread(table, 1, sizeof table, f);
    fclose(f);
    printf("sizeof(rl_planner) %u, sizeof(rl_setpoints) %u, checkpoint %u bytes\n",
           (unsigned)sizeof(rl_planner), (unsigned)sizeof(rl_setpoints),
           (unsigned)rl_checkpoint_size());
    if (RL_App_Init(&svc, table, n) != RL_OK) return 1;
    for (cycle = 1; RL_App_Hk()->state == RL_APP_PLANNING || RL_App_Hk()->state == RL_APP_FLYING;
         cycle++) {
        RL_App_Wakeup();
        /* The joints hold the command over the period to the next wakeup. */
        if (RL_App_Hk()->commands > 0) {
            for (i = 0; i < RL_JOINTS; i++) q[i] += held[i] * config.period_s;
            flight_wakeups++;
        }
        if (cycle == RESET_AT) {
            printf("-- processor reset after wakeup %u (CDS kept) --\n", (unsigned)cycle);
            if (RL_App_Init(&svc, table, n) != RL_OK) return 1;
        }
    }
    printf("HK wakeups=%u checkpoints=%u setpoints=%u commands=%u limited=%u errors=%u\n",
           (unsigned)RL_App_Hk()->wakeups, (unsigned)RL_App_Hk()->checkpoints,
           (unsigned)RL_App_Hk()->setpoints, (unsigned)RL_App_Hk()->commands,
           (unsigned)RL_App_Hk()->limited, (unsigned)RL_App_Hk()->errors);
    printf("DIGEST 0x%016llx\n", (unsigned long long)digest);
    printf("COMMANDS %u\n", (unsigned)RL_App_Hk()->commands);
    printf("LOOP_MODE %u\n", (unsigned)RL_App_Hk()->loop_mode);
    printf("LOOP_FAULT %u\n", (unsigned)RL_App_Hk()->loop_fault);
    printf("LOOP_DIGEST 0x%016llx\n", (unsigned long long)loop_digest);
    for (i = 0; i < RL_JOINTS; i++) printf("Q%d %.17g\n", i + 1, q[i]);
    if (fault_at != 0) return RL_App_Hk()->state == RL_APP_SAFE ? 0 : 1;
    return RL_App_Hk()->state == RL_APP_IDLE && RL_App_Hk()->errors == 0 ? 0 : 1;
}
