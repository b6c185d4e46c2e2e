/* ARM semihosting (bkpt 0xab) for QEMU -semihosting: console output and exit. */
#ifndef SEMIHOSTING_H
#define SEMIHOSTING_H
#include <stdint.h>

static inline int32_t sh_call(int32_t op, const void *arg) {
    register int32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

/* SYS_WRITE0: a NUL-terminated string to the debug console. */
static inline void sh_write0(const char *s) { sh_call(0x04, s); }

/* SYS_EXIT_EXTENDED with ADP_Stopped_ApplicationExit and a status, which QEMU makes its own
 * exit status. */
static inline void __attribute__((noreturn)) sh_exit(int32_t status) {
    uint32_t block[2] = {0x20026u, (uint32_t)status};
    sh_call(0x20, block);
    for (;;) {
    }
}
#endif
