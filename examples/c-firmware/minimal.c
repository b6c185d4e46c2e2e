/* The smallest firmware that uses the drive: init, then one pmsm_step per PWM interrupt
 * (here a loop over a volatile "ADC") and pmsm_task when a step says it is due. Built without -DWITH_PMSM, and with it, to measure the
 * flash and RAM the library adds (scripts/c-firmware.sh). The drive is designed on the target
 * from a configuration (pmsm_drive_init; -DESTIMATOR=<pmsm_estimator_t> picks the estimator),
 * or with -DFROM_IMAGE loaded from a drive image written on the host (image.S,
 * pmsm_drive_init_image), which links none of the design code. */
#include <stdint.h>
#ifdef WITH_PMSM
#include "pmsm.h"
static pmsm_storage_t storage;
static pmsm_drive_t *drive;
#ifdef FROM_IMAGE
extern const unsigned char pmsm_image[];
extern const unsigned char pmsm_image_end[];
#endif
#ifndef ESTIMATOR
#define ESTIMATOR PMSM_ESTIMATOR_MRAS_CURRENT
#endif
#endif

volatile int32_t adc[4];        /* stands for the ADC injected-conversion registers */
volatile uint16_t ccr[3];       /* stands for TIM1->CCR1..3 */

int main(void) {
#ifdef WITH_PMSM
    /* The library linked is the one the header describes. */
    if (pmsm_version() != PMSM_VERSION) return 1;
#ifdef FROM_IMAGE
    if (pmsm_drive_init_image(&storage, sizeof storage, pmsm_image,
                              (size_t)(pmsm_image_end - pmsm_image), &drive) != PMSM_OK)
        return 1;
#else
    pmsm_config_t c = {0};
    c.pole_pairs = 3;
    c.estimator = ESTIMATOR;
    c.rs_ohm = 7.2;
    c.ld_h = 0.025025;
    c.lq_h = 0.04017;
    c.flux_wb = 0.305;
    c.j_kg_m2 = 0.0036;
    c.b_nm_s = 0.0011;
    c.rated_current_a = 2.53;
    c.vdc_v = 540.0;
    c.pwm_hz = 14000.0;
    c.dead_time_s = 2e-6;
    c.pwm_period_ticks = 3000;
    if (pmsm_drive_init(&storage, sizeof storage, &c, &drive) != PMSM_OK) return 1;
#endif
    pmsm_start(drive);
#endif
    for (int k = 0; k < 100; k++) {
#ifdef WITH_PMSM
        /* the ISR body */
        pmsm_input_t in = {adc[0], adc[1], adc[2], adc[3]};
        pmsm_output_t out;
        pmsm_step(drive, &in, &out);
        ccr[0] = out.compare[0];
        ccr[1] = out.compare[1];
        ccr[2] = out.compare[2];
        /* the task, pended by the ISR in firmware */
        if (out.task_due) pmsm_task(drive);
#else
        ccr[0] = (uint16_t)adc[0];
        ccr[1] = (uint16_t)adc[1];
        ccr[2] = (uint16_t)adc[2];
#endif
    }
    return 0;
}
