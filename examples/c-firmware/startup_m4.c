/* Minimal Cortex-M4F start-up for QEMU mps2-an386: vector table, FPU on (the library is
 * built for the hard-float ABI), .data copied from flash, .bss zeroed, main, semihosting exit
 * with main's status. */
#include <stdint.h>
#include "semihosting.h"

extern uint32_t _sidata[], _sdata[], _edata[], _sbss[], _ebss[], _estack[];
int main(void);

void Reset_Handler(void) {
    /* CPACR: full access to CP10 and CP11 (the FPU) before any floating-point instruction. */
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20;
    __asm__ volatile("dsb\n isb" ::: "memory");
    for (uint32_t *s = _sidata, *d = _sdata; d < _edata;) *d++ = *s++;
    for (uint32_t *d = _sbss; d < _ebss;) *d++ = 0;
    sh_exit(main());
}

void Default_Handler(void) {
    sh_write0("CFFI cortex-m4 fault: unexpected exception\n");
    sh_exit(3);
}

__attribute__((section(".isr_vector"), used)) const void *const vectors[16] = {
    _estack,                       /* initial stack pointer */
    (const void *)Reset_Handler,   /* reset */
    (const void *)Default_Handler, /* NMI */
    (const void *)Default_Handler, /* HardFault */
    (const void *)Default_Handler, /* MemManage */
    (const void *)Default_Handler, /* BusFault */
    (const void *)Default_Handler, /* UsageFault */
};
