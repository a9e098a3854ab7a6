/* Host platform of the C ABI test: blocks from files (host-sim block), output on stdout.
 * Usage: abi_test BLOCK OTHER_BLOCK */
#include <stdio.h>

#include "abi_test.h"

static uint8_t block[4096];
static uint8_t other[4096];

void rl_test_write(const char *s) { fputs(s, stdout); }
void rl_test_stack_reset(void) {}
uint32_t rl_test_stack_used(void) { return 0; }

static size_t read_file(const char *path, uint8_t *buf, size_t cap) {
    size_t n;
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        return 0;
    }
    n = fread(buf, 1, cap, f);
    fclose(f);
    return n;
}

int main(int argc, char **argv) {
    size_t n, m;
    if (argc != 3) {
        fputs("usage: abi_test BLOCK OTHER_BLOCK\n", stderr);
        return 2;
    }
    n = read_file(argv[1], block, sizeof block);
    m = read_file(argv[2], other, sizeof other);
    if (n == 0 || m == 0 || n == sizeof block || m == sizeof other) {
        fputs("abi_test: cannot read the blocks\n", stderr);
        return 2;
    }
    return rl_test_run(block, n, other, m);
}
