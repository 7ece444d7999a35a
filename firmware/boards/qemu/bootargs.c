/* Reads the boot arguments block the linker script reserves below the stack. */
#include "bootargs.h"

extern const bootargs_raw_t BOOTARGS_ADDR;

static bootargs_t args;
static int loaded;

const bootargs_t *bootargs(void)
{
    if (!loaded) {
        const volatile bootargs_raw_t *raw = &BOOTARGS_ADDR;
        if (raw->magic == BOOTARGS_MAGIC) {
            args.node_id = raw->node_id;
            args.seed = ((uint64_t)raw->seed_hi << 32) | raw->seed_lo;
            args.speed_milli = raw->speed_milli;
            args.bench = raw->bench;
            args.has_key = raw->has_key == 1u;
            for (uint32_t i = 0u; i < BOOTARGS_KEY_BYTES; i++) {
                args.key[i] = raw->key[i];
            }
        } else {
            args.seed = 1u;
        }
        loaded = 1;
    }
    return &args;
}
