/* See replay.h. The drive's configuration is motor B on its inverter in SI units, the same
 * values as the Rust recorder's (which builds its drive with the Rust API). */
#include "replay.h"
#include "pmsm.h"

enum {
    MAGIC = 0x49464643, /* "CFFI" */
    VERSION = 1,
    WORDS = 17,
    CMD_START = 1,
    CMD_STOP = 2,
    CMD_CLEAR_FAULT = 4,
};

/* Word order of a step (scenario.rs `Word`). */
enum {
    W_CMD, W_SPEED_REF, W_IA, W_IB, W_IC, W_VDC, W_DUTY_A, W_DUTY_B, W_DUTY_C,
    W_CMP_A, W_CMP_B, W_CMP_C, W_PWM_ON, W_STATE, W_FAULT, W_THETA, W_OMEGA
};

/* The drive's storage: static, no allocation. */
static pmsm_storage_t storage;

char *replay_itoa(int32_t v, char *buf) {
    char tmp[12];
    int n = 0, i = 0;
    uint32_t u = v < 0 ? 0u - (uint32_t)v : (uint32_t)v;
    do {
        tmp[n++] = (char)('0' + u % 10u);
        u /= 10u;
    } while (u != 0u);
    if (v < 0) buf[i++] = '-';
    while (n > 0) buf[i++] = tmp[--n];
    buf[i] = '\0';
    return buf;
}

static void print_kv(replay_print_fn print, const char *k, int32_t v) {
    char b[12];
    print(k);
    print(replay_itoa(v, b));
}

void replay_config(pmsm_config_t *c, uint32_t period_ticks) {
    *c = (pmsm_config_t){0};
    c->pole_pairs = 3;
    c->estimator = PMSM_ESTIMATOR_MRAS_CURRENT;
    c->startup = PMSM_STARTUP_IPD;
    c->pwm_period_ticks = period_ticks;
    c->rs_ohm = 7.2;
    c->ld_h = 0.025025;
    c->lq_h = 0.04017;
    c->flux_wb = 0.305;
    c->j_kg_m2 = 0.0036;
    c->b_nm_s = 0.0011;
    c->rated_current_a = 2.53;
    c->rated_speed_rpm = 3000.0;
    c->vdc_v = 540.0;
    c->pwm_hz = 14000.0;
    c->dead_time_s = 2e-6;
}

int replay_run(const int32_t *words, size_t n_words, const void *image, size_t image_len,
               replay_print_fn print, uint32_t *steps) {
    *steps = 0;
    if (pmsm_version() != PMSM_VERSION) {
        print("replay: libpmsm_ffi.a is not the version of pmsm.h\n");
        return -1;
    }
    if (n_words < 5 || words[0] != MAGIC || words[1] != VERSION || words[3] != WORDS) {
        print("replay: not a recording (magic, version or word count)\n");
        return -1;
    }
    uint32_t n = (uint32_t)words[2];
    if (n_words < 5 + (size_t)n * WORDS) {
        print("replay: truncated recording\n");
        return -1;
    }

    pmsm_config_t c;
    replay_config(&c, (uint32_t)words[4]);
    pmsm_drive_t *drive = 0;
    pmsm_status_t st = image
        ? pmsm_drive_init_image(&storage, sizeof storage, image, image_len, &drive)
        : pmsm_drive_init(&storage, sizeof storage, &c, &drive);
    if (st != PMSM_OK) {
        char msg[160];
        pmsm_config_error_message(&c, msg, sizeof msg);
        print(image ? "replay: pmsm_drive_init_image: " : "replay: pmsm_drive_init: ");
        print(pmsm_status_message(st));
        print(": ");
        print(msg);
        print("\n");
        return -1;
    }

    int bad = 0;
    const int32_t *row = words + 5;
    for (uint32_t k = 0; k < n; k++, row += WORDS) {
        int32_t cmd = row[W_CMD];
        if (cmd & CMD_STOP) pmsm_stop(drive);
        if (cmd & CMD_CLEAR_FAULT) pmsm_clear_fault(drive);
        if (cmd & CMD_START) pmsm_start(drive);
        pmsm_set_speed_ref(drive, row[W_SPEED_REF]);

        pmsm_input_t in = {row[W_IA], row[W_IB], row[W_IC], row[W_VDC]};
        pmsm_output_t out;
        pmsm_state_info_t s;
        pmsm_estimate_t e;
        int ok = pmsm_step(drive, &in, &out) == PMSM_OK;
        /* The task, run here after the step that made it due (firmware pends it instead). */
        if (ok && out.task_due) ok = pmsm_task(drive) == PMSM_OK;
        ok = ok && pmsm_get_state(drive, &s) == PMSM_OK
            && pmsm_get_estimate(drive, &e) == PMSM_OK;
        int32_t got[WORDS];
        for (int w = 0; w < WORDS; w++) got[w] = row[w];
        got[W_DUTY_A] = out.duty[0];
        got[W_DUTY_B] = out.duty[1];
        got[W_DUTY_C] = out.duty[2];
        got[W_CMP_A] = out.compare[0];
        got[W_CMP_B] = out.compare[1];
        got[W_CMP_C] = out.compare[2];
        got[W_PWM_ON] = out.pwm_on;
        got[W_STATE] = (int32_t)s.state;
        got[W_FAULT] = (int32_t)s.fault;
        got[W_THETA] = e.theta;
        got[W_OMEGA] = e.omega;
        int same = ok && out.state == s.state;
        for (int w = 0; w < WORDS; w++) same = same && got[w] == row[w];
        if (!same) {
            if (bad < 5) {
                print_kv(print, "replay: step ", (int32_t)k);
                for (int w = W_DUTY_A; w < WORDS; w++) {
                    if (got[w] != row[w]) {
                        print_kv(print, " word ", w);
                        print_kv(print, " rust=", row[w]);
                        print_kv(print, " c=", got[w]);
                    }
                }
                print("\n");
            }
            bad++;
        }
    }
    *steps = n;
    return bad;
}
