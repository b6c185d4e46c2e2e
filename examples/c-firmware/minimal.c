/* The smallest firmware that uses the drive: init from a configuration, then one pmsm_step
 * per PWM interrupt (here a loop over a volatile "ADC"). Built with and without
 * -DWITH_PMSM to measure the flash and RAM the library adds (scripts/c-firmware.sh). */
#include <stdint.h>
#ifdef WITH_PMSM
#include "pmsm.h"
static pmsm_storage_t storage;
static pmsm_drive_t *drive;
#endif

volatile int32_t adc[4];        /* stands for the ADC injected-conversion registers */
volatile uint16_t ccr[3];       /* stands for TIM1->CCR1..3 */

int main(void) {
#ifdef WITH_PMSM
    pmsm_config_t c = {0};
    c.pole_pairs = 3;
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
#else
        ccr[0] = (uint16_t)adc[0];
        ccr[1] = (uint16_t)adc[1];
        ccr[2] = (uint16_t)adc[2];
#endif
    }
    return 0;
}
