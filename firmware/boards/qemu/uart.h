/* CMSDK APB UART of the mps2 boards: UART0 carries the link (interrupt-driven receive ring), UART1 the
   board's own diagnostics (instruction counts for the resource benchmark). */
#ifndef QEMU_UART_H
#define QEMU_UART_H

#include <stddef.h>
#include <stdint.h>

void   uart_init(void);
size_t uart0_read(uint8_t *buf, size_t cap);
void   uart0_write(const uint8_t *buf, size_t n);
void   uart1_write_text(const char *text);
void   uart0_rx_irq(void);
void   uart_fault_message(const char *text);

#endif
