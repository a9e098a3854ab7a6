/* Cortex-M7 platform of the C ABI test (QEMU mps2-an500, semihosting): the vector table and
 * reset handler (FPU on, .data copied, .bss zeroed), output and exit through semihosting,
 * the task blocks QEMU's loader placed at _task_block, _other_block and _two_phase_block
 * (the two-phase test, two_phase_test.c, runs after the C ABI test), and the painted
 * stack: every word below the current frame is painted before a call and the deepest word
 * no longer painted after it is the high-water mark. Built with arm-none-eabi-gcc against
 * newlib (string.h) and the thumbv7em-none-eabihf staticlib; see scripts/c-abi-m7.sh. */
#include <stdint.h>
#include <string.h>

#include "../abi_test.h"

#define PAINT 0xccccccccu
/* Bytes left unpainted below the frame of the painting function itself. */
#define PAINT_MARGIN 64u

extern uint32_t _data_load, _data_start, _data_end, _bss_start, _bss_end;
extern uint32_t _stack_top, _stack_limit;
extern const uint8_t _task_block[], _other_block[], _two_phase_block[];

int main(void);
void reset_handler(void);

/* The initial stack pointer and the reset vector (Thumb address: the compiler sets bit 0). */
__attribute__((section(".vectors"), used)) static const uintptr_t vectors[2] = {
    (uintptr_t)&_stack_top,
    (uintptr_t)reset_handler,
};

static int semihost(int op, const void *arg) {
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void rl_test_write(const char *s) { (void)semihost(0x04, s); /* SYS_WRITE0 */ }

static void semihost_exit(int code) {
    /* SYS_EXIT: ADP_Stopped_ApplicationExit or ADP_Stopped_RunTimeErrorUnknown. */
    (void)semihost(0x18, (const void *)(uintptr_t)(code == 0 ? 0x20026u : 0x20023u));
    for (;;) {
    }
}

static volatile uint32_t *paint_floor;
static uint32_t deepest_total;

/* Paints from the bottom of the stack up to just below this function's frame. */
__attribute__((noinline)) void rl_test_stack_reset(void) {
    volatile uint32_t *p = &_stack_limit;
    volatile uint32_t *top = (volatile uint32_t *)((uintptr_t)__builtin_frame_address(0) - PAINT_MARGIN);
    paint_floor = p;
    while (p < top) {
        *p++ = PAINT;
    }
}

/* Bytes between the stack top and the deepest word written since the last reset. */
__attribute__((noinline)) uint32_t rl_test_stack_used(void) {
    volatile uint32_t *p = paint_floor;
    uint32_t used;
    while (p < &_stack_top && *p == PAINT) {
        p++;
    }
    used = (uint32_t)((uintptr_t)&_stack_top - (uintptr_t)p);
    if (used > deepest_total) {
        deepest_total = used;
    }
    return used;
}

/* A block's length from its header (bytes 12..16, little-endian), bounded. */
static size_t block_len(const uint8_t *b) {
    uint32_t n = (uint32_t)b[12] | ((uint32_t)b[13] << 8) | ((uint32_t)b[14] << 16) |
                 ((uint32_t)b[15] << 24);
    return n > 0x8000u ? 0x8000u : (size_t)n;
}

void reset_handler(void) {
    uint32_t *src = &_data_load;
    uint32_t *dst = &_data_start;
    /* CPACR: full access to CP10 and CP11 (the FPU), before any floating-point code. */
    *(volatile uint32_t *)0xe000ed88u |= 0xfu << 20;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    while (dst < &_data_end) {
        *dst++ = *src++;
    }
    for (dst = &_bss_start; dst < &_bss_end; dst++) {
        *dst = 0;
    }
    semihost_exit(main());
}

int main(void) {
    int code;
    rl_test_write("platform cortex-m7 mps2-an500\n");
    code = rl_test_run(_task_block, block_len(_task_block), _other_block,
                       block_len(_other_block));
    code |= rl_two_phase_test_run(_two_phase_block, block_len(_two_phase_block));
    rl_test_write("STACK max ");
    rl_test_put_u32(deepest_total);
    rl_test_write("\nSTACK size ");
    rl_test_put_u32((uint32_t)((uintptr_t)&_stack_top - (uintptr_t)&_stack_limit));
    rl_test_write("\n");
    return code;
}
