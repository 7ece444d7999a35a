/* Per-mode step statistics, printed on UART1 after every episode as `BENCH ...` lines. */
#include "bench.h"

#include "learner.h"
#include "modes.h"
#include "timer.h"
#include "uart.h"

#define MODES 8u
#define CAL_LOOPS 1000000u       /* 2 instructions per loop (subs, bne) */
#define DECIMAL_DIGITS 21u
#define STACK_PAINT_BYTES 16384u  /* painted below the stack top at boot; the untouched rest shows the peak */
#define STACK_PAINT_WORD 0xA5C3A5C3u
#define INSTRUCTIONS_PER_TICK 40u  /* -icount shift=0 (1 ns each) on the 25 MHz timer; the CAL line checks it */
#define CPU_MHZ 72u                /* the MK20DX256's clock, one instruction per cycle assumed */

extern uint32_t _stack_top;

typedef struct {
    uint32_t count;
    uint32_t max_ticks;
    uint64_t sum_ticks;
} step_stats_t;

static step_stats_t stats[MODES][2];
static uint32_t printed_episode;
static uint32_t max_sweeps_per_episode;
static uint32_t late_steps;          /* steps longer than their period at 72 MHz, since boot */
static uint64_t plan_ticks;          /* ticks of the steps that ran planning, since the last print */
static uint32_t plan_steps;

static void put_u64(uint64_t v)
{
    char buf[DECIMAL_DIGITS];
    uint32_t i = DECIMAL_DIGITS - 1u;
    buf[i] = '\0';
    do {
        buf[--i] = (char)('0' + (char)(v % 10u));
        v /= 10u;
    } while (v != 0u && i > 0u);
    uart1_write_text(&buf[i]);
}

static void put_field(const char *name, uint64_t v)
{
    uart1_write_text(" ");
    uart1_write_text(name);
    uart1_write_text("=");
    put_u64(v);
}

void bench_paint_stack(void)
{
    /* Paint from the bottom of the window up to a little below the current stack pointer. */
    uint32_t *bottom = &_stack_top - STACK_PAINT_BYTES / sizeof(uint32_t);
    uintptr_t sp;
    __asm volatile("mov %0, sp" : "=r"(sp));
    for (volatile uint32_t *w = bottom; (uintptr_t)w < sp - 64u; w++) {
        *w = STACK_PAINT_WORD;
    }
}

static uint32_t stack_peak_bytes(void)
{
    const uint32_t *bottom = &_stack_top - STACK_PAINT_BYTES / sizeof(uint32_t);
    const volatile uint32_t *w = bottom;
    while (w < &_stack_top && *w == STACK_PAINT_WORD) {
        w++;
    }
    return (uint32_t)((uintptr_t)&_stack_top - (uintptr_t)w);
}

void bench_calibrate(void)
{
    uint32_t n = CAL_LOOPS;
    uint32_t start = timer_raw();
    __asm volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
    uint32_t ticks = timer_raw() - start;
    uart1_write_text("CAL");
    put_field("instructions", 2u * (uint64_t)CAL_LOOPS);
    put_field("ticks", ticks);
    uart1_write_text("\n");
}

static void print_stats(void)
{
    for (uint32_t m = 0u; m < MODES; m++) {
        for (uint32_t p = 0u; p < 2u; p++) {
            const step_stats_t *s = &stats[m][p];
            if (s->count == 0u) {
                continue;
            }
            uart1_write_text("BENCH");
            put_field("episode", printed_episode);
            put_field("mode", m);
            put_field("planning", p);
            put_field("steps", s->count);
            put_field("sum_ticks", s->sum_ticks);
            put_field("max_ticks", s->max_ticks);
            uart1_write_text("\n");
        }
    }
    uart1_write_text("SWEEPS");
    put_field("episode", printed_episode);
    put_field("last", learner_last_sweeps());
    put_field("max", max_sweeps_per_episode);
    put_field("states", learner_n_states());
    put_field("learner_bytes", learner_used_bytes());
    put_field("stack_peak_bytes", stack_peak_bytes());
    put_field("late_steps", late_steps);
    put_field("plan_ticks", plan_ticks);
    put_field("plan_steps", plan_steps);
    put_field("plan_waits", modes_plan_waits());
    put_field("forced_plans", modes_forced_plans());
    uart1_write_text("\n");
    plan_ticks = 0u;
    plan_steps = 0u;
}

void bench_record(uint8_t mode, bool planning, uint32_t ticks, uint32_t period_us)
{
    if ((uint64_t)ticks * INSTRUCTIONS_PER_TICK > (uint64_t)period_us * CPU_MHZ) {
        late_steps++;
    }
    if (planning) {
        plan_ticks += ticks;
        plan_steps++;
    }
    step_stats_t *s = &stats[mode < MODES ? mode : MODES - 1u][planning ? 1u : 0u];
    s->count++;
    s->sum_ticks += ticks;
    s->max_ticks = ticks > s->max_ticks ? ticks : s->max_ticks;
    if (!learner_planning() && learner_episode() != printed_episode) {
        /* planning of the episode just ended is complete: its sweep count is final */
        uint32_t sweeps = learner_last_sweeps();
        max_sweeps_per_episode = sweeps > max_sweeps_per_episode ? sweeps : max_sweeps_per_episode;
        printed_episode = learner_episode();
        print_stats();
    }
}
