/* The real clock of the QEMU board: CMSDK APB timer 0 free-running at the 25 MHz APB clock. */
#ifndef QEMU_TIMER_H
#define QEMU_TIMER_H

#include <stdint.h>

#define TIMER_TICKS_PER_US 25u  /* QEMU's mps2 SYSCLK / PCLK: 25 MHz */

void     timer_init(void);
uint32_t timer_raw(void);      /* counts up, wraps every 171 s */
uint64_t timer_real_us(void);  /* since boot; must be read at least once per wrap (the main loop does) */

#endif
