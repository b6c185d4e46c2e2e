/* Host side of the C examples:
 *   replay-host RECORD.bin
 *     replays the recording through the host libpmsm_ffi.a and prints
 *     `CFFI host replay bit_exact=<true|false> steps=<n>`;
 *   replay-host --image OUT.bin ESTIMATOR PERIOD
 *     builds the recorded drive's configuration (replay_config) with estimator code
 *     ESTIMATOR and timer period PERIOD, and writes its drive image for
 *     pmsm_drive_init_image on a target (the firmware then links no design code). */
#include <stdio.h>
#include <stdlib.h>
#include "pmsm.h"
#include "replay.h"

static void print(const char *s) { fputs(s, stdout); }

static pmsm_storage_t storage;
static unsigned char image[sizeof(pmsm_storage_t) + 64];

static int write_image(const char *path, uint32_t estimator, uint32_t period) {
    pmsm_config_t c;
    replay_config(&c, period);
    c.estimator = estimator;
    if (estimator != PMSM_ESTIMATOR_MRAS_CURRENT) c.startup = PMSM_STARTUP_ALIGN;
    pmsm_drive_t *drive = 0;
    pmsm_status_t st = pmsm_drive_init(&storage, sizeof storage, &c, &drive);
    if (st != PMSM_OK) {
        char msg[200];
        pmsm_config_error_message(&c, msg, sizeof msg);
        fprintf(stderr, "image: %s: %s\n", pmsm_status_message(st), msg);
        return 1;
    }
    size_t n = pmsm_drive_image(drive, image, sizeof image);
    if (n == 0 || n > sizeof image) {
        fprintf(stderr, "image: %zu bytes do not fit\n", n);
        return 1;
    }
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(image, 1, n, f) != n || fclose(f) != 0) {
        perror(path);
        return 1;
    }
    return 0;
}

int main(int argc, char **argv) {
    if (argc == 5 && argv[1][0] == '-') {
        return write_image(argv[2], (uint32_t)strtoul(argv[3], 0, 0),
                           (uint32_t)strtoul(argv[4], 0, 0));
    }
    if (argc != 2) {
        fprintf(stderr, "usage: %s RECORD.bin | --image OUT.bin ESTIMATOR PERIOD\n", argv[0]);
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
    int bad = replay_run(words, n, NULL, 0, print, &steps);
    printf("CFFI host replay bit_exact=%s steps=%u\n", bad == 0 ? "true" : "false", steps);
    return bad == 0 ? 0 : 1;
}
