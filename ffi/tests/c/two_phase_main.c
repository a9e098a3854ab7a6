/* A two-phase block through the C ABI from C: plans it with rl_two_phase in frames of a
 * few units, streams both phases, and prints what a flight app would log, bit patterns
 * and trajectory digests in hex.
 * Usage: two_phase_test BLOCK */
#include <stdio.h>
#include <string.h>

#include "reactionless.h"

static uint8_t block[4096];
static rl_two_phase search;
static rl_setpoints stream;

/* FNV-1a-64 over the little-endian bytes of v's bit pattern (the trajectory digest). */
static uint64_t fold(uint64_t h, double v) {
    uint64_t b;
    int i;
    memcpy(&b, &v, sizeof b);
    for (i = 0; i < 8; i++) {
        h = (h ^ ((b >> (8 * i)) & 0xffu)) * 0x00000100000001b3ull;
    }
    return h;
}

/* Streams phase `phase` and prints its digest and sample count; 0 on success. */
static int stream_phase(unsigned phase) {
    rl_setpoint sp;
    uint64_t h = 0xcbf29ce484222325ull;
    unsigned n = 0;
    int j;
    rl_status s = rl_two_phase_setpoints_init(&stream, &search, phase);
    if (s != RL_OK) {
        printf("STREAM%u %s\n", phase, rl_status_str(s));
        return 1;
    }
    while ((s = rl_two_phase_setpoints_next(&stream, &search, &sp)) == RL_OK) {
        h = fold(h, sp.t);
        for (j = 0; j < RL_JOINTS; j++) {
            h = fold(h, sp.q[j]);
        }
        for (j = 0; j < RL_JOINTS; j++) {
            h = fold(h, sp.qd[j]);
        }
        n++;
    }
    if (s != RL_DONE) {
        printf("STREAM%u %s\n", phase, rl_status_str(s));
        return 1;
    }
    printf("DIGEST%u 0x%016llx\n", phase, (unsigned long long)h);
    printf("SAMPLES%u %u\n", phase, n);
    return 0;
}

static void put_bits(const char *key, double v) {
    uint64_t b;
    memcpy(&b, &v, sizeof b);
    printf("%s 0x%016llx\n", key, (unsigned long long)b);
}

int main(int argc, char **argv) {
    size_t n;
    rl_status s;
    rl_two_phase_plan plan;
    unsigned frames = 0;
    int i;
    FILE *f;
    if (argc != 2) {
        fputs("usage: two_phase_test BLOCK\n", stderr);
        return 2;
    }
    f = fopen(argv[1], "rb");
    if (f == NULL) {
        return 2;
    }
    n = fread(block, 1, sizeof block, f);
    fclose(f);
    if (n == 0 || n == sizeof block) {
        return 2;
    }
    s = RL_TWO_PHASE_INIT(&search);
    if (s != RL_OK) {
        printf("INIT %s\n", rl_status_str(s));
        return 1;
    }
    s = rl_two_phase_load_block(&search, block, n);
    if (s != RL_OK) {
        printf("LOAD %s\n", rl_status_str(s));
        return 1;
    }
    do {
        s = rl_two_phase_step(&search, 25, &plan);
        frames++;
    } while (s == RL_RUNNING);
    if (s < 0) {
        printf("STEP %s\n", rl_status_str(s));
        return 1;
    }
    printf("STATUS %d\n", (int)s);
    printf("FRAMES %u\n", frames);
    printf("ROLLOUTS %u\n", (unsigned)plan.rollouts);
    printf("STARTS %u\n", (unsigned)plan.starts);
    printf("STEPS1 %u\n", (unsigned)plan.phase1_steps);
    put_bits("F", plan.f);
    put_bits("REACH_F", plan.reach_f);
    put_bits("BASE", plan.base_disturbance_rad);
    put_bits("MOMENTUM", plan.wheel_momentum_nms);
    put_bits("TORQUE", plan.wheel_torque_nm);
    for (i = 0; i < RL_JOINTS; i++) {
        char key[16];
        sprintf(key, "QS%d", i);
        put_bits(key, plan.q_s[i]);
    }
    for (i = 0; i < RL_ETA_LEN; i++) {
        char key[16];
        sprintf(key, "ETA%d", i);
        put_bits(key, plan.eta[i]);
    }
    return stream_phase(1) || stream_phase(2);
}
