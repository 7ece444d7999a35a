/* CMSDK APB UART driver: polled transmit, receive into a ring from the RX interrupt. */
#include "uart.h"

#define UART0_BASE 0x40004000u
#define UART1_BASE 0x40005000u
#define UART_DATA 0x00u
#define UART_STATE 0x04u
#define UART_CTRL 0x08u
#define UART_INTCLEAR 0x0Cu
#define UART_BAUDDIV 0x10u
#define STATE_TX_FULL 0x1u
#define STATE_RX_FULL 0x2u
#define CTRL_TX_EN 0x1u
#define CTRL_RX_EN 0x2u
#define CTRL_RX_IRQ_EN 0x8u
#define INT_RX 0x2u
#define BAUDDIV_MIN 16u           /* the smallest divider the CMSDK UART accepts */
#define NVIC_ISER0 0xE000E100u
#define UART0_RX_IRQ_BIT 0x1u
#define RX_RING_BYTES 1024u       /* two full frames and more: the core polls once per step */

static volatile uint8_t rx_ring[RX_RING_BYTES];
static volatile uint32_t rx_head;  /* written by the interrupt */
static volatile uint32_t rx_tail;  /* written by the main loop */

static volatile uint32_t *reg(uint32_t base, uint32_t offset)
{
    return (volatile uint32_t *)(uintptr_t)(base + offset);
}

void uart_init(void)
{
    *reg(UART0_BASE, UART_BAUDDIV) = BAUDDIV_MIN;
    *reg(UART0_BASE, UART_CTRL) = CTRL_TX_EN | CTRL_RX_EN | CTRL_RX_IRQ_EN;
    *reg(UART1_BASE, UART_BAUDDIV) = BAUDDIV_MIN;
    *reg(UART1_BASE, UART_CTRL) = CTRL_TX_EN;
    *(volatile uint32_t *)(uintptr_t)NVIC_ISER0 = UART0_RX_IRQ_BIT;
}

void uart0_rx_irq(void)
{
    while (*reg(UART0_BASE, UART_STATE) & STATE_RX_FULL) {
        uint8_t byte = (uint8_t)*reg(UART0_BASE, UART_DATA);
        uint32_t next = (rx_head + 1u) % RX_RING_BYTES;
        if (next != rx_tail) {  /* a full ring drops the byte: the frame's CRC then rejects it */
            rx_ring[rx_head] = byte;
            rx_head = next;
        }
    }
    *reg(UART0_BASE, UART_INTCLEAR) = INT_RX;
}

size_t uart0_read(uint8_t *buf, size_t cap)
{
    size_t n = 0u;
    while (n < cap && rx_tail != rx_head) {
        buf[n++] = rx_ring[rx_tail];
        rx_tail = (rx_tail + 1u) % RX_RING_BYTES;
    }
    return n;
}

static void write_bytes(uint32_t base, const uint8_t *buf, size_t n)
{
    for (size_t i = 0u; i < n; i++) {
        while (*reg(base, UART_STATE) & STATE_TX_FULL) {
        }
        *reg(base, UART_DATA) = buf[i];
    }
}

void uart0_write(const uint8_t *buf, size_t n)
{
    write_bytes(UART0_BASE, buf, n);
}

void uart1_write_text(const char *text)
{
    size_t n = 0u;
    while (text[n] != '\0') {
        n++;
    }
    write_bytes(UART1_BASE, (const uint8_t *)text, n);
}

void uart_fault_message(const char *text)
{
    uart1_write_text(text);
}
