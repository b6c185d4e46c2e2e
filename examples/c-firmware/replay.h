/* Replays a recorded scenario (crates/pmsm-ffi/tests/common/scenario.rs) through the C API
 * of pmsm-ffi and compares every output word with the Rust drive's. Shared by the host
 * program (host_main.c) and the Cortex-M4 firmware (m4_main.c). No libc. */
#ifndef REPLAY_H
#define REPLAY_H
#include <stddef.h>
#include <stdint.h>

/* Writes one NUL-terminated string (no newline added). */
typedef void (*replay_print_fn)(const char *s);

/* Replays `n_words` little-endian words of a recording. Returns the number of differing
 * steps (0: bit exact), or -1 if the recording or the drive set-up is invalid; `*steps` gets
 * the number of steps replayed. Prints the first few differences. */
int replay_run(const int32_t *words, size_t n_words, replay_print_fn print, uint32_t *steps);

/* Decimal of `v` into `buf` (at least 12 bytes); returns buf. */
char *replay_itoa(int32_t v, char *buf);

#endif
