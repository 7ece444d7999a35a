/* Instruction counts of the agent's steps for the resource benchmark (QEMU run with -icount shift=0:
   one instruction is one nanosecond of virtual time, read on the 25 MHz timer). */
#ifndef QEMU_BENCH_H
#define QEMU_BENCH_H

#include <stdbool.h>
#include <stdint.h>

/* Paint the stack window at boot, so the peak use can be read later (printed with the SWEEPS line). */
void bench_paint_stack(void);
/* Calibration: timer ticks of a loop of a known instruction count, printed on UART1. */
void bench_calibrate(void);
/* One agent step of mode (planning: a planning run was in progress before the step) took ticks; its period
   was period_us (a step is late when it takes longer at 72 MHz, one instruction per cycle). */
void bench_record(uint8_t mode, bool planning, uint32_t ticks, uint32_t period_us);

#endif
