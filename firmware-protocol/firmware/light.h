/* Light channels as 16-bit timer-4 PWM outputs (OC4A/B/C = D6/D7/D8), one MOSFET or LED driver
 * each. Levels are the protocol's u16 (0 off, 65535 full). */
#ifndef LIGHT_H
#define LIGHT_H

#include <stdint.h>

void light_init(void);
void light_set(uint8_t channel, uint16_t level, uint32_t now_ms);
void light_all_off(void);
uint16_t light_level(uint8_t channel);
/* Lit and past the settle time (no warm-up sensor on this board). */
uint8_t light_stable(uint8_t channel, uint32_t now_ms);

#endif
