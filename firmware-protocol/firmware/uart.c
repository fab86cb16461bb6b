#include "uart.h"

#include "config.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#define BAUD 115200UL
/* Double speed (U2X): 16 MHz / (8 * (16 + 1)) = 117647 baud, 2.1 % off, the Arduino setting. */
#define UBRR_VALUE ((F_CPU + 4UL * BAUD) / (8UL * BAUD) - 1UL)

/* 256 bytes: four whole frames, 22 ms of line time at full rate; indexes wrap for free. */
static volatile uint8_t rx_buf[256];
static volatile uint8_t rx_head; /* written by the ISR */
static volatile uint8_t rx_tail; /* written by the main loop */
static volatile uint8_t rx_overflow;

ISR(USART0_RX_vect)
{
    uint8_t c = UDR0;
    uint8_t next = (uint8_t)(rx_head + 1);
    if (next == rx_tail) {
        rx_overflow = 1;
        return;
    }
    rx_buf[rx_head] = c;
    rx_head = next;
}

void uart_init(void)
{
    UBRR0 = (uint16_t)UBRR_VALUE;
    UCSR0A = _BV(U2X0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

uint8_t uart_getc(uint8_t *c)
{
    uint8_t tail = rx_tail;
    if (tail == rx_head) {
        return 0;
    }
    *c = rx_buf[tail];
    rx_tail = (uint8_t)(tail + 1);
    return 1;
}

uint8_t uart_take_overflow(void)
{
    uint8_t o;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        o = rx_overflow;
        rx_overflow = 0;
    }
    return o;
}

void uart_write(const uint8_t *data, uint8_t len)
{
    for (uint8_t i = 0; i < len; i++) {
        while (!(UCSR0A & _BV(UDRE0))) {
        }
        UDR0 = data[i];
    }
}
