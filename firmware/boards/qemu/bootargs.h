/* Boot arguments that simulator/firmware_qemu.py writes into RAM with QEMU's generic loader. */
#ifndef QEMU_BOOTARGS_H
#define QEMU_BOOTARGS_H

#include <stdbool.h>
#include <stdint.h>

#define BOOTARGS_MAGIC 0x41524753u  /* "ARGS" */
#define BOOTARGS_KEY_BYTES 32u      /* HMAC-SHA256 key */

typedef struct {
    uint32_t magic;
    uint32_t node_id;      /* 0: the board's default */
    uint32_t seed_lo;      /* sensor noise and entropy stream */
    uint32_t seed_hi;
    uint32_t speed_milli;  /* agent time per real time x 1000; 0 = as fast as the CPU goes */
    uint32_t bench;        /* 1: print instruction counts on UART1 (run with -icount shift=0) */
    uint32_t has_key;      /* 1: key holds the signing key, commands must be signed */
    uint8_t  key[BOOTARGS_KEY_BYTES];
} bootargs_raw_t;

typedef struct {
    uint32_t node_id;
    uint64_t seed;
    uint32_t speed_milli;
    uint32_t bench;
    bool has_key;
    uint8_t key[BOOTARGS_KEY_BYTES];
} bootargs_t;

/* The arguments, or defaults (seed 1, full speed, no bench) when QEMU wrote none. */
const bootargs_t *bootargs(void);

#endif
