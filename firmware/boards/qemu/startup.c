/* Vector table and reset handler of the QEMU mps2-an386 board: copy .data, zero .bss, run main. */
#include <stdint.h>

#include "uart.h"

extern uint32_t _data_load, _data_start, _data_end, _bss_start, _bss_end, _stack_top;
extern int main(void);

void reset_handler(void);
void fault_handler(void);
void default_handler(void);

#define CORE_VECTORS 16u
#define IRQ_VECTORS 1u  /* only UART0 RX is enabled */

void reset_handler(void)
{
    const uint32_t *src = &_data_load;
    for (uint32_t *dst = &_data_start; dst < &_data_end; dst++) {
        *dst = *src++;
    }
    for (uint32_t *dst = &_bss_start; dst < &_bss_end; dst++) {
        *dst = 0u;
    }
    (void)main();
    for (;;) {
    }
}

void fault_handler(void)
{
    /* A fault is a firmware bug: say so on the link's UART, then stop (QEMU keeps running idle). */
    uart_fault_message("FAULT\n");
    for (;;) {
    }
}

void default_handler(void)
{
    for (;;) {
    }
}

__attribute__((section(".vectors"), used))
static void (*const vectors[CORE_VECTORS + IRQ_VECTORS])(void) = {
    (void (*)(void))(uintptr_t)&_stack_top,
    reset_handler,
    fault_handler,  /* NMI */
    fault_handler,  /* HardFault */
    fault_handler,  /* MemManage */
    fault_handler,  /* BusFault */
    fault_handler,  /* UsageFault */
    0, 0, 0, 0,
    default_handler,  /* SVCall */
    default_handler,  /* DebugMon */
    0,
    default_handler,  /* PendSV */
    default_handler,  /* SysTick */
    uart0_rx_irq,     /* IRQ 0: UART0 RX */
};
