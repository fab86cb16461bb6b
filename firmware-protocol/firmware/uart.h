/* UART0 at 115200 8N1: interrupt-driven receive into a ring buffer, blocking transmit (a reply is
 * at most 64 bytes, 5.6 ms; stepping runs in its own interrupt meanwhile). */
#ifndef UART_H
#define UART_H

#include <stdint.h>

void uart_init(void);
/* Takes one received byte into *c; returns 0 when none is waiting. */
uint8_t uart_getc(uint8_t *c);
/* Returns 1 once after bytes were lost to a full ring buffer. */
uint8_t uart_take_overflow(void);
void uart_write(const uint8_t *data, uint8_t len);

#endif
