/* Replays a recorded scenario (crates/pmsm-ffi/tests/common/scenario.rs) through the C API
 * of pmsm-ffi and compares every output word with the Rust drive's. Shared by the host
 * program (host_main.c) and the Cortex-M4 firmware (m4_main.c). No libc. */
#ifndef REPLAY_H
#define REPLAY_H
#include <stddef.h>
#include <stdint.h>

/* Writes one NUL-terminated string (no newline added). */
typedef void (*replay_print_fn)(const char *s);

#include "pmsm.h"

/* The configuration of the recorded drive (motor B on its 540 V inverter, current-model MRAS,
 * IPD start) with the PWM timer period `period_ticks`. */
void replay_config(pmsm_config_t *c, uint32_t period_ticks);

/* Replays `n_words` little-endian words of a recording. The drive is built from
 * replay_config() by pmsm_drive_init when `image` is NULL, else loaded from the `image_len`
 * bytes of a drive image (pmsm_drive_init_image). Returns the number of differing steps
 * (0: bit exact), or -1 if the recording or the drive set-up is invalid; `*steps` gets the
 * number of steps replayed. Prints the first few differences. */
int replay_run(const int32_t *words, size_t n_words, const void *image, size_t image_len,
               replay_print_fn print, uint32_t *steps);

/* Decimal of `v` into `buf` (at least 12 bytes); returns buf. */
char *replay_itoa(int32_t v, char *buf);

#endif
