/* The two-phase C ABI test, shared by the host (two_phase_main.c) and the Cortex-M7
 * (m7/main.c): plans a two-phase block with rl_two_phase in frames of a few units
 * (checkpointed, wiped and restored at frame 10), streams both phases, and writes what a
 * flight app would log, one "TWO_KEY value" line each: bit patterns and trajectory digests
 * in hex. Output goes through the platform's rl_test_write only (no printf), so the same
 * code runs on newlib without an operating system. */
#include <string.h>

#include "abi_test.h"
#include "reactionless.h"

static rl_two_phase search;
static rl_setpoints stream;
/* A checkpoint taken mid-search, as flight software would keep in a CDS block. */
static uint8_t checkpoint[RL_TWO_PHASE_CHECKPOINT_CAPACITY];

static void put(const char *key, const char *value) {
    rl_test_write("TWO_");
    rl_test_write(key);
    rl_test_write(" ");
    rl_test_write(value);
    rl_test_write("\n");
}

static void put_hex(const char *key, uint64_t v) {
    static const char digits[] = "0123456789abcdef";
    char text[19];
    int i;
    text[0] = '0';
    text[1] = 'x';
    for (i = 0; i < 16; i++) {
        text[2 + i] = digits[(v >> (60 - 4 * i)) & 0xfu];
    }
    text[18] = '\0';
    put(key, text);
}

static void put_u32(const char *key, uint32_t v) {
    char text[11];
    int i = 10;
    text[i] = '\0';
    do {
        text[--i] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v != 0u && i > 0);
    put(key, &text[i]);
}

static void put_bits(const char *key, double v) {
    uint64_t b;
    memcpy(&b, &v, sizeof b);
    put_hex(key, b);
}

/* `prefix` followed by the index `i` (< 100). */
static const char *indexed(char *buf, const char *prefix, int i) {
    size_t n = strlen(prefix);
    memcpy(buf, prefix, n);
    if (i >= 10) {
        buf[n++] = (char)('0' + i / 10);
    }
    buf[n++] = (char)('0' + i % 10);
    buf[n] = '\0';
    return buf;
}

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

/* Streams phase `phase` and writes its digest and sample count; 0 on success. */
static int stream_phase(unsigned phase) {
    rl_setpoint sp;
    uint64_t h = 0xcbf29ce484222325ull;
    uint32_t n = 0;
    int j;
    char key[16];
    rl_status s = rl_two_phase_setpoints_init(&stream, &search, phase);
    if (s != RL_OK) {
        put(indexed(key, "STREAM", (int)phase), rl_status_str(s));
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
        put(indexed(key, "STREAM", (int)phase), rl_status_str(s));
        return 1;
    }
    put_hex(indexed(key, "DIGEST", (int)phase), h);
    put_u32(indexed(key, "SAMPLES", (int)phase), n);
    return 0;
}

int rl_two_phase_test_run(const uint8_t *block, size_t len) {
    rl_status s;
    rl_two_phase_plan plan;
    uint32_t frames = 0;
    uint32_t deepest = 0;
    int i;
    char key[16];
    s = RL_TWO_PHASE_INIT(&search);
    if (s != RL_OK) {
        put("INIT", rl_status_str(s));
        return 1;
    }
    s = rl_two_phase_load_block(&search, block, len);
    if (s != RL_OK) {
        put("LOAD", rl_status_str(s));
        return 1;
    }
    do {
        uint32_t used;
        rl_test_stack_reset();
        s = rl_two_phase_step(&search, 25, &plan);
        used = rl_test_stack_used();
        deepest = used > deepest ? used : deepest;
        frames++;
        if (frames == 10 && s == RL_RUNNING) {
            /* Checkpoint, "reset" (the storage wiped), initialise and restore: the search
               goes on as if nothing happened. */
            rl_status c = rl_two_phase_checkpoint(&search, checkpoint,
                                                  rl_two_phase_checkpoint_size());
            if (c != RL_OK) {
                put("CHECKPOINT", rl_status_str(c));
                return 1;
            }
            memset(&search, 0xA5, sizeof search);
            c = RL_TWO_PHASE_INIT(&search);
            if (c == RL_OK) {
                c = rl_two_phase_restore(&search, checkpoint, rl_two_phase_checkpoint_size());
            }
            if (c != RL_OK) {
                put("RESTORE", rl_status_str(c));
                return 1;
            }
        }
    } while (s == RL_RUNNING);
    if (s < 0) {
        put("STEP", rl_status_str(s));
        return 1;
    }
    put_u32("STATUS", (uint32_t)s);
    put_u32("FRAMES", frames);
    put_u32("ROLLOUTS", plan.rollouts);
    put_u32("STARTS", plan.starts);
    put_u32("STEPS1", plan.phase1_steps);
    put_bits("F", plan.f);
    put_bits("REACH_F", plan.reach_f);
    put_bits("BASE", plan.base_disturbance_rad);
    put_bits("MOMENTUM", plan.wheel_momentum_nms);
    put_bits("TORQUE", plan.wheel_torque_nm);
    for (i = 0; i < RL_JOINTS; i++) {
        put_bits(indexed(key, "QS", i), plan.q_s[i]);
    }
    for (i = 0; i < RL_ETA_LEN; i++) {
        put_bits(indexed(key, "ETA", i), plan.eta[i]);
    }
    put_u32("STACK_STEP", deepest);
    put_u32("CHECKPOINT_BYTES", (uint32_t)rl_two_phase_checkpoint_size());
    return stream_phase(1) || stream_phase(2);
}
