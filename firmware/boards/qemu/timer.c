/* CMSDK APB timer 0 as a free-running up-counter, extended to 64 bits in software. */
#include "timer.h"

#define TIMER0_BASE 0x40000000u
#define TIMER_CTRL 0x00u
#define TIMER_VALUE 0x04u
#define TIMER_RELOAD 0x08u
#define CTRL_ENABLE 0x1u
#define FULL_RANGE 0xFFFFFFFFu

static uint32_t last_raw;
static uint64_t ticks_high;  /* ticks before the last wrap seen */

static volatile uint32_t *reg(uint32_t offset)
{
    return (volatile uint32_t *)(uintptr_t)(TIMER0_BASE + offset);
}

void timer_init(void)
{
    *reg(TIMER_RELOAD) = FULL_RANGE;
    *reg(TIMER_VALUE) = FULL_RANGE;
    *reg(TIMER_CTRL) = CTRL_ENABLE;
    last_raw = timer_raw();
    ticks_high = 0u;
}

uint32_t timer_raw(void)
{
    return FULL_RANGE - *reg(TIMER_VALUE);
}

uint64_t timer_real_us(void)
{
    uint32_t raw = timer_raw();
    if (raw < last_raw) {
        ticks_high += (uint64_t)FULL_RANGE + 1u;
    }
    last_raw = raw;
    return (ticks_high + raw) / TIMER_TICKS_PER_US;
}
