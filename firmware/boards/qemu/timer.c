/* CMSDK APB timer 0 as a free-running up-counter, extended to 64 bits in software. */
#include "timer.h"

#define TIMER0_BASE 0x40000000u
#define TIMER_CTRL 0x00u
#define TIMER_VALUE 0x04u
#define TIMER_RELOAD 0x08u
#define CTRL_ENABLE 0x1u
#define FULL_RANGE 0xFFFFFFFFu

#define SYST_CSR 0xE000E010u
#define SYST_RVR 0xE000E014u
#define SYST_CVR 0xE000E018u
#define SYST_ENABLE_TICKINT_CPUCLK 0x7u
#define TICKS_PER_WAKE (TIMER_TICKS_PER_US * 1000u)  /* SysTick wakes a waiting CPU every 1 ms */

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
    *(volatile uint32_t *)(uintptr_t)SYST_RVR = TICKS_PER_WAKE - 1u;
    *(volatile uint32_t *)(uintptr_t)SYST_CVR = 0u;
    *(volatile uint32_t *)(uintptr_t)SYST_CSR = SYST_ENABLE_TICKINT_CPUCLK;
}

void timer_systick_irq(void)
{
    /* Nothing to do: the interrupt only ends a WFI (timer_idle). */
}

void timer_idle(void)
{
    /* Sleep until an interrupt (UART0 receive, or the 1 ms SysTick). A CPU spinning on the timer and UART
       registers instead would keep QEMU's I/O thread from delivering received bytes for tens of ms. */
    __asm volatile("wfi" ::: "memory");
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
