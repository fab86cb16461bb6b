/* Pin map of the Arduino Mega 2560 (ATmega2560) board; README.md has the wiring.
 *
 *   D22 PA0  STEP    -> driver STEP
 *   D23 PA1  DIR     -> driver DIR
 *   D24 PA2  ENABLE  -> driver EN (active low)
 *   D25 PA3  HOME    <- switch to GND, internal pull-up (active low)
 *   D6  PH3  OC4A    -> light channel 0 (MOSFET gate / LED driver PWM input)
 *   D7  PH4  OC4B    -> light channel 1
 *   D8  PH5  OC4C    -> light channel 2
 *   D0/D1 PE0/PE1    UART0 (USB serial via the 16U2)
 *
 * Timers: timer 1 (16-bit, CTC) ticks the stepper, timer 3 (16-bit, CTC) counts milliseconds,
 * timer 4 (16-bit, fast PWM) drives the lights. Only 16-bit timers are used because QEMU's mega2560
 * model emulates those and not the 8-bit timers 0 and 2. */
#ifndef BOARD_H
#define BOARD_H

#include <avr/io.h>

#define STEPPER_DDR DDRA
#define STEPPER_PORT PORTA
#define STEPPER_PIN PINA
#define STEP_BIT PA0
#define DIR_BIT PA1
#define ENABLE_BIT PA2
#define HOME_BIT PA3

#endif
