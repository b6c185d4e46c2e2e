/* Cortex-M4 replay (QEMU mps2-an386): the recording is linked into the image (record.S),
 * replayed through the thumbv7em libpmsm_ffi.a; the result goes out through semihosting:
 * `CFFI cortex-m4 replay bit_exact=<true|false> steps=<n>`, exit status 0 when bit exact.
 * With -DWITH_IMAGE the drive is loaded from a drive image written on the host (image.S)
 * instead of being designed on the target: `CFFI cortex-m4 image replay ...`. */
#include <stdint.h>
#include "replay.h"
#include "semihosting.h"

extern const int32_t pmsm_record[];
extern const int32_t pmsm_record_end[];
#ifdef WITH_IMAGE
extern const unsigned char pmsm_image[];
extern const unsigned char pmsm_image_end[];
#define IMAGE pmsm_image, (size_t)(pmsm_image_end - pmsm_image)
#define LABEL "CFFI cortex-m4 image replay bit_exact="
#else
#define IMAGE 0, 0
#define LABEL "CFFI cortex-m4 replay bit_exact="
#endif

int main(void) {
    uint32_t steps = 0;
    size_t n = (size_t)(pmsm_record_end - pmsm_record);
    int bad = replay_run(pmsm_record, n, IMAGE, sh_write0, &steps);
    char b[12];
    sh_write0(LABEL);
    sh_write0(bad == 0 ? "true" : "false");
    sh_write0(" steps=");
    sh_write0(replay_itoa((int32_t)steps, b));
    sh_write0("\n");
    return bad == 0 ? 0 : 1;
}
