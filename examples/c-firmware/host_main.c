/* Host replay: reads the recording named on the command line, replays it through the host
 * libpmsm_ffi.a and prints `CFFI host replay bit_exact=<true|false> steps=<n>`. */
#include <stdio.h>
#include <stdlib.h>
#include "replay.h"

static void print(const char *s) { fputs(s, stdout); }

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s RECORD.bin\n", argv[0]);
        return 2;
    }
    FILE *f = fopen(argv[1], "rb");
    if (!f) {
        perror(argv[1]);
        return 2;
    }
    static int32_t words[1 << 20];
    size_t n = fread(words, sizeof words[0], sizeof words / sizeof words[0], f);
    fclose(f);
    uint32_t steps = 0;
    int bad = replay_run(words, n, print, &steps);
    printf("CFFI host replay bit_exact=%s steps=%u\n", bad == 0 ? "true" : "false", steps);
    return bad == 0 ? 0 : 1;
}
