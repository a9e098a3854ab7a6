/* The C ABI test: plans a task block through reactionless.h with the task's frame budget,
 * checkpoints and restores once in the middle (into a planner re-initialised over garbage,
 * as after a processor reset), streams the setpoints and folds them into the FNV-1a-64
 * trajectory digest, and checks the misuse paths (NULL pointers, a bad ABI version or size,
 * corrupted blocks, corrupted checkpoints, wrong states).
 *
 * The same file runs on the host (host_main.c: blocks from files) and on the Cortex-M7
 * under QEMU (m7/main.c: blocks placed in RAM by QEMU's loader). It prints one line per
 * result; ffi/tests/c_abi.rs and scripts/c-abi-m7.sh compare them with host-sim's record.
 * C99, no heap: every object is static, as in flight software. */
#include "abi_test.h"

#include <string.h>

#include "reactionless.h"

/* Frame at which the planner is checkpointed and restored. */
#define CHECKPOINT_FRAME 40u

static rl_planner planner;
static rl_planner other;
static rl_setpoints stream;
static rl_loop flight;
static uint8_t saved[RL_CHECKPOINT_CAPACITY];
static uint8_t scratch[4096];

static unsigned failures;
static unsigned checks;

void rl_test_put_u32(uint32_t v) {
    char buf[11];
    int i = 10;
    buf[i] = '\0';
    do {
        buf[--i] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v != 0u && i > 0);
    rl_test_write(&buf[i]);
}

static void put_i32(int32_t v) {
    if (v < 0) {
        rl_test_write("-");
        rl_test_put_u32((uint32_t)(-(v + 1)) + 1u);
    } else {
        rl_test_put_u32((uint32_t)v);
    }
}

static void put_hex64(uint64_t v) {
    static const char digits[] = "0123456789abcdef";
    char buf[19];
    int i;
    buf[0] = '0';
    buf[1] = 'x';
    for (i = 0; i < 16; i++) {
        buf[2 + i] = digits[(v >> (60 - 4 * i)) & 0xfu];
    }
    buf[18] = '\0';
    rl_test_write(buf);
}

static uint64_t bits_of(double x) {
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    return b;
}

/* One expected status; a mismatch prints a line naming the call. */
static void expect(const char *what, rl_status got, rl_status want) {
    checks++;
    if (got != want) {
        failures++;
        rl_test_write("FAIL ");
        rl_test_write(what);
        rl_test_write(": got ");
        put_i32(got);
        rl_test_write(" (");
        rl_test_write(rl_status_str(got));
        rl_test_write("), want ");
        put_i32(want);
        rl_test_write("\n");
    }
}

static void line_u32(const char *key, uint32_t v) {
    rl_test_write(key);
    rl_test_write(" ");
    rl_test_put_u32(v);
    rl_test_write("\n");
}

static void line_hex(const char *key, uint64_t v) {
    rl_test_write(key);
    rl_test_write(" ");
    put_hex64(v);
    rl_test_write("\n");
}

/* FNV-1a-64 over the little-endian bytes of a value's bit pattern (TrajectoryDigest). */
static uint64_t fnv_push(uint64_t h, double x) {
    uint64_t b = bits_of(x);
    int i;
    for (i = 0; i < 8; i++) {
        h ^= (b >> (8 * i)) & 0xffu;
        h *= 0x00000100000001b3ull;
    }
    return h;
}

/* Misuse that needs no task. */
static void misuse_before_load(const uint8_t *block, size_t len) {
    rl_plan plan;
    uint32_t budget = 0;
    size_t mid = len / 2;

    expect("abi version", (rl_status)rl_abi_version(), RL_ABI_VERSION);
    expect("step before init", rl_planner_step(&planner, 10, &plan), RL_E_UNINITIALIZED);
    expect("init NULL", rl_planner_init(NULL, RL_ABI_VERSION, sizeof planner), RL_E_NULL);
    expect("init wrong ABI", rl_planner_init(&planner, RL_ABI_VERSION + 1u, sizeof planner),
           RL_E_ABI_VERSION);
    expect("init wrong size", rl_planner_init(&planner, RL_ABI_VERSION, sizeof planner - 8u),
           RL_E_SIZE);
    expect("init", RL_PLANNER_INIT(&planner), RL_OK);
    expect("step NULL planner", rl_planner_step(NULL, 10, &plan), RL_E_NULL);
    expect("step NULL plan", rl_planner_step(&planner, 10, NULL), RL_E_NULL);
    expect("step without task", rl_planner_step(&planner, 10, &plan), RL_E_NO_TASK);
    expect("frame budget without task", rl_planner_frame_budget(&planner, &budget),
           RL_E_NO_TASK);
    expect("stream without task", rl_setpoints_init(&stream, &planner), RL_E_NO_TASK);
    expect("checkpoint without task", rl_planner_checkpoint(&planner, saved, sizeof saved),
           RL_E_NO_TASK);
    expect("load NULL block", rl_planner_load_block(&planner, NULL, len), RL_E_NULL);
    expect("load NULL planner", rl_planner_load_block(NULL, block, len), RL_E_NULL);
    expect("load short block", rl_planner_load_block(&planner, block, len - 1u),
           RL_E_BLOCK_LENGTH);

    if (len > sizeof scratch) {
        expect("block fits the scratch buffer", RL_E_BUFFER, RL_OK);
        return;
    }
    memcpy(scratch, block, len);
    scratch[mid] ^= 0x10u;
    expect("load corrupted block", rl_planner_load_block(&planner, scratch, len),
           RL_E_BLOCK_CRC);
    memcpy(scratch, block, len);
    scratch[0] = (uint8_t)'X';
    expect("load block with bad magic", rl_planner_load_block(&planner, scratch, len),
           RL_E_BLOCK_MAGIC);
    expect("step after failed load", rl_planner_step(&planner, 10, &plan), RL_E_NO_TASK);
    {
        rl_status s;
        for (s = -30; s <= 10; s++) {
            checks++;
            if (rl_status_str(s) == NULL || rl_status_str(s)[0] == '\0') {
                failures++;
                rl_test_write("FAIL rl_status_str\n");
            }
        }
    }
}

/* Corrupted and foreign checkpoints are rejected, leaving the planner as it was. */
static void misuse_checkpoint(const uint8_t *other_block, size_t other_len, size_t size) {
    expect("checkpoint NULL buffer", rl_planner_checkpoint(&planner, NULL, size), RL_E_NULL);
    expect("checkpoint small buffer", rl_planner_checkpoint(&planner, scratch, sizeof scratch),
           RL_E_BUFFER);
    expect("restore NULL buffer", rl_planner_restore(&planner, NULL, size), RL_E_NULL);
    expect("restore NULL planner", rl_planner_restore(NULL, saved, size), RL_E_NULL);
    expect("restore short", rl_planner_restore(&planner, saved, size - 1u), RL_E_CKPT_LENGTH);
    saved[size / 2] ^= 0x01u;
    expect("restore bad CRC", rl_planner_restore(&planner, saved, size), RL_E_CKPT_CRC);
    saved[size / 2] ^= 0x01u;
    saved[size - 1u] ^= 0x80u;
    expect("restore bad CRC field", rl_planner_restore(&planner, saved, size), RL_E_CKPT_CRC);
    saved[size - 1u] ^= 0x80u;
    saved[8] ^= 0x02u;
    expect("restore wrong version", rl_planner_restore(&planner, saved, size),
           RL_E_CKPT_VERSION);
    saved[8] ^= 0x02u;
    saved[16] ^= 0x04u;
    expect("restore wrong length field", rl_planner_restore(&planner, saved, size),
           RL_E_CKPT_LENGTH);
    saved[16] ^= 0x04u;
    saved[1] ^= 0x20u;
    expect("restore wrong magic", rl_planner_restore(&planner, saved, size), RL_E_CKPT_MAGIC);
    saved[1] ^= 0x20u;
    expect("init other", RL_PLANNER_INIT(&other), RL_OK);
    expect("load other task", rl_planner_load_block(&other, other_block, other_len), RL_OK);
    expect("restore into another task", rl_planner_restore(&other, saved, size),
           RL_E_CKPT_TASK);
}

/* Flies the plan closed-loop through rl_loop on stand-in hardware (joints that follow each
 * command exactly over its period, encoders that read them exactly, a base held still):
 * the commands' digest (every command, cycle 0's first), the cycles, the end mode, and the
 * stack of rl_loop_step. */
static void fly_closed_loop(const double *q0) {
    rl_loop_config cfg;
    rl_loop_command cmd, scratch_cmd;
    rl_measurement m;
    double q[RL_JOINTS], held[RL_JOINTS];
    uint64_t loop_digest = 0xcbf29ce484222325ull;
    uint32_t cycles = 0, max_stack = 0, stack;
    rl_status s;
    int i;
    expect("loop config NULL", rl_loop_config_default(NULL), RL_E_NULL);
    expect("loop config", rl_loop_config_default(&cfg), RL_OK);
    expect("loop NULL", RL_LOOP_INIT(NULL, &planner, &cfg, &cmd), RL_E_NULL);
    expect("loop wrong size",
           rl_loop_init(&flight, RL_ABI_VERSION, sizeof flight - 8u, &planner, &cfg, &cmd),
           RL_E_SIZE);
    cfg.base_gain_per_s = 10.0; /* k_b T_c = 1: unstable */
    expect("loop unstable gain", RL_LOOP_INIT(&flight, &planner, &cfg, &cmd), RL_E_LOOP_SETTING);
    expect("loop config again", rl_loop_config_default(&cfg), RL_OK);
    expect("loop", RL_LOOP_INIT(&flight, &planner, &cfg, &cmd), RL_OK);
    memset(&m, 0, sizeof m);
    m.valid = RL_MEASURED_STAR_TRACKER | RL_MEASURED_GYRO | RL_MEASURED_JOINTS;
    m.star_tracker_wxyz[0] = 1.0;
    memcpy(q, q0, sizeof q);
    memcpy(m.joints_rad, q, sizeof q);
    expect("loop another planner", rl_loop_step(&flight, &other, &m, &scratch_cmd), RL_E_MISMATCH);
    expect("loop NULL measurement", rl_loop_step(&flight, &planner, NULL, &scratch_cmd), RL_E_NULL);
    for (;;) {
        for (i = 0; i < RL_JOINTS; i++) {
            loop_digest = fnv_push(loop_digest, cmd.rate_rad_s[i]);
            held[i] = cmd.rate_rad_s[i];
        }
        if (cmd.finished || cycles > 1000u) {
            break;
        }
        memcpy(m.joints_rad, q, sizeof q);
        rl_test_stack_reset();
        s = rl_loop_step(&flight, &planner, &m, &cmd);
        stack = rl_test_stack_used();
        if (stack > max_stack) {
            max_stack = stack;
        }
        if (s != RL_OK && s != RL_DONE) {
            expect("loop step", s, RL_OK);
            return;
        }
        for (i = 0; i < RL_JOINTS; i++) {
            q[i] += held[i] * cfg.period_s;
        }
        cycles++;
    }
    expect("loop end", rl_loop_step(&flight, &planner, &m, &scratch_cmd), RL_DONE);
    line_u32("LOOP_CYCLES", cycles);
    line_u32("LOOP_MODE", cmd.mode);
    line_hex("LOOP_DIGEST", loop_digest);
    line_u32("STACK loop_step", max_stack);
}

int rl_test_run(const uint8_t *block, size_t len, const uint8_t *other_block, size_t other_len) {
    rl_plan plan;
    rl_setpoint sp;
    rl_status s;
    uint32_t budget = 0;
    uint32_t frames = 0;
    uint32_t samples = 0;
    uint32_t max_step_stack = 0;
    uint32_t max_next_stack = 0;
    uint32_t stack = 0;
    uint64_t digest = 0xcbf29ce484222325ull;
    double q0[RL_JOINTS] = {0};
    size_t size = rl_checkpoint_size();
    int i;

    line_u32("SIZES planner", (uint32_t)sizeof(rl_planner));
    line_u32("SIZES setpoints", (uint32_t)sizeof(rl_setpoints));
    line_u32("SIZES loop", (uint32_t)sizeof(rl_loop));
    line_u32("SIZES checkpoint", (uint32_t)size);
    if (size > sizeof saved) {
        rl_test_write("FAIL checkpoint larger than RL_CHECKPOINT_CAPACITY\n");
        return 1;
    }

    misuse_before_load(block, len);

    rl_test_stack_reset();
    s = rl_planner_load_block(&planner, block, len);
    stack = rl_test_stack_used();
    line_u32("STACK load_block", stack);
    expect("load block", s, RL_OK);
    expect("frame budget", rl_planner_frame_budget(&planner, &budget), RL_OK);
    expect("stream before a plan", rl_setpoints_init(&stream, &planner), RL_E_NO_PLAN);
    line_u32("BUDGET", budget);

    for (;;) {
        rl_test_stack_reset();
        s = rl_planner_step(&planner, budget, &plan);
        stack = rl_test_stack_used();
        if (stack > max_step_stack) {
            max_step_stack = stack;
        }
        frames++;
        if (s != RL_RUNNING) {
            break;
        }
        if (frames == CHECKPOINT_FRAME) {
            rl_test_stack_reset();
            s = rl_planner_checkpoint(&planner, saved, sizeof saved);
            line_u32("STACK checkpoint", rl_test_stack_used());
            expect("checkpoint", s, RL_OK);
            misuse_checkpoint(other_block, other_len, size);
            /* A processor reset: the planner's memory is garbage, then re-initialised. */
            memset(&planner, 0xa5, sizeof planner);
            expect("re-init after reset", RL_PLANNER_INIT(&planner), RL_OK);
            expect("reload the task table", rl_planner_load_block(&planner, block, len), RL_OK);
            rl_test_stack_reset();
            s = rl_planner_restore(&planner, saved, size);
            line_u32("STACK restore", rl_test_stack_used());
            expect("restore", s, RL_OK);
            line_u32("RESTORED_AT_FRAME", frames);
        }
        if (frames > 100000u) {
            rl_test_write("FAIL the planner did not finish\n");
            return 1;
        }
    }
    line_u32("STACK step", max_step_stack);
    if (s != RL_CONVERGED && s != RL_EXHAUSTED && s != RL_STALLED) {
        expect("plan", s, RL_CONVERGED);
        return 1;
    }
    expect("step after the end", rl_planner_step(&planner, budget, &plan), s);
    rl_test_write(s == RL_CONVERGED ? "STATUS converged\n" : "STATUS not_converged\n");
    line_u32("FRAMES", frames);
    line_u32("ITERATIONS", plan.iterations);
    line_u32("ROLLOUTS", plan.rollouts);
    line_u32("STAGNATION", plan.stagnation_events);
    line_u32("RESTARTS", plan.restarts);
    line_hex("F", bits_of(plan.f));
    for (i = 0; i < RL_ETA_LEN; i++) {
        rl_test_write("ETA ");
        rl_test_put_u32((uint32_t)i);
        rl_test_write(" ");
        put_hex64(bits_of(plan.eta[i]));
        rl_test_write("\n");
    }

    expect("stream NULL", rl_setpoints_init(NULL, &planner), RL_E_NULL);
    expect("stream", rl_setpoints_init(&stream, &planner), RL_OK);
    expect("stream another planner", rl_setpoints_next(&stream, &other, &sp), RL_E_MISMATCH);
    expect("stream NULL out", rl_setpoints_next(&stream, &planner, NULL), RL_E_NULL);
    for (;;) {
        rl_test_stack_reset();
        s = rl_setpoints_next(&stream, &planner, &sp);
        stack = rl_test_stack_used();
        if (stack > max_next_stack) {
            max_next_stack = stack;
        }
        if (s != RL_OK) {
            break;
        }
        if (samples == 0) {
            memcpy(q0, sp.q, sizeof q0);
        }
        digest = fnv_push(digest, sp.t);
        for (i = 0; i < RL_JOINTS; i++) {
            digest = fnv_push(digest, sp.q[i]);
        }
        for (i = 0; i < RL_JOINTS; i++) {
            digest = fnv_push(digest, sp.qd[i]);
        }
        samples++;
    }
    expect("stream end", s, RL_DONE);
    expect("stream after the end", rl_setpoints_next(&stream, &planner, &sp), RL_DONE);
    line_u32("STACK setpoints_next", max_next_stack);
    line_u32("SAMPLES", samples);
    line_hex("DIGEST", digest);
    fly_closed_loop(q0);

    line_u32("CHECKS", checks);
    line_u32("FAILURES", failures);
    rl_test_write(failures == 0u ? "RESULT ok\n" : "RESULT fail\n");
    return failures == 0u ? 0 : 1;
}
