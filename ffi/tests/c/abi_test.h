/* The C ABI test (abi_test.c) and what each platform provides for it. */
#ifndef RL_ABI_TEST_H
#define RL_ABI_TEST_H

#include <stddef.h>
#include <stdint.h>

/* Runs the test on `block` (planned) and `other` (another task's block); returns 0 if every
 * check passed. */
int rl_test_run(const uint8_t *block, size_t len, const uint8_t *other, size_t other_len);

/* Runs the two-phase test (two_phase_test.c) on a two-phase `block`; returns 0 if it
 * planned and streamed both phases. */
int rl_two_phase_test_run(const uint8_t *block, size_t len);

/* Writes `v` in decimal with rl_test_write. */
void rl_test_put_u32(uint32_t v);

/* Platform: writes a NUL-terminated string to the test's output. */
void rl_test_write(const char *s);
/* Platform: starts a stack measurement (0 where not measured). */
void rl_test_stack_reset(void);
/* Platform: deepest stack use since rl_test_stack_reset, bytes (0 where not measured). */
uint32_t rl_test_stack_used(void);

#endif
