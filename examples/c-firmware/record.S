/* The recording, linked into the Cortex-M4 image (RECORD_PATH from the command line). */
    .section .rodata.pmsm_record, "a"
    .balign 4
    .global pmsm_record
pmsm_record:
    .incbin RECORD_PATH
    .global pmsm_record_end
pmsm_record_end:
    .section .note.GNU-stack, "", %progbits
