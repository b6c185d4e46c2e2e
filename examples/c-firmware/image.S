/* A drive image written on the host (replay-host --image), linked into the Cortex-M4 image
 * (IMAGE_PATH from the command line) for pmsm_drive_init_image. */
    .section .rodata.pmsm_image, "a"
    .balign 8
    .global pmsm_image
pmsm_image:
    .incbin IMAGE_PATH
    .global pmsm_image_end
pmsm_image_end:
    .section .note.GNU-stack, "", %progbits
