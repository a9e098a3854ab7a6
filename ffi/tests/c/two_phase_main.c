/* Host platform of the two-phase C ABI test (two_phase_test.c): reads the block from the
 * file named on the command line and writes to stdout; no stack measurement.
 * Usage: two_phase_test BLOCK */
#include <stdio.h>

#include "abi_test.h"

static uint8_t block[8192];

void rl_test_write(const char *s) { fputs(s, stdout); }
void rl_test_stack_reset(void) {}
uint32_t rl_test_stack_used(void) { return 0; }

int main(int argc, char **argv) {
    size_t n;
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
    return rl_two_phase_test_run(block, n);
}
