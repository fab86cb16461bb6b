#include "light.h"

#include "config.h"

#include <avr/io.h>

#if LIGHT_CHANNELS < 1 || LIGHT_CHANNELS > 3
#error "LIGHT_CHANNELS must be 1..3 (timer 4 has three compare outputs)"
#endif

static uint16_t level[LIGHT_CHANNELS];
static uint32_t on_since_ms[LIGHT_CHANNELS];

/* Compare-output bits of each channel in TCCR4A (non-inverting), its OCR register and pin. */
static const uint8_t com_bits[3] = {_BV(COM4A1), _BV(COM4B1), _BV(COM4C1)};
static const uint8_t pin_bits[3] = {_BV(PH3), _BV(PH4), _BV(PH5)};

static volatile uint16_t *ocr(uint8_t channel)
{
    return channel == 0 ? &OCR4A : channel == 1 ? &OCR4B : &OCR4C;
}

void light_init(void)
{
    for (uint8_t c = 0; c < LIGHT_CHANNELS; c++) {
        PORTH &= (uint8_t)~pin_bits[c]; /* low (off) whenever the PWM is disconnected */
        DDRH |= pin_bits[c];
        level[c] = 0;
    }
    /* Fast PWM, TOP = ICR4 (mode 14), no prescaler. */
    ICR4 = LIGHT_PWM_TOP;
    TCCR4A = _BV(WGM41);
    TCCR4B = _BV(WGM43) | _BV(WGM42) | _BV(CS40);
}

void light_set(uint8_t channel, uint16_t lvl, uint32_t now_ms)
{
    if (channel >= LIGHT_CHANNELS) {
        return;
    }
    if (lvl == 0) {
        /* OCR = 0 still leaves a one-count spike each period: disconnect instead. */
        TCCR4A &= (uint8_t)~com_bits[channel];
    } else {
        /* Rounded to the PWM resolution; 65535 gives OCR = TOP, i.e. always on. */
        *ocr(channel) = (uint16_t)(((uint32_t)lvl * LIGHT_PWM_TOP + 32767UL) / 65535UL);
        TCCR4A |= com_bits[channel];
    }
    if (level[channel] == 0 && lvl != 0) {
        on_since_ms[channel] = now_ms;
    }
    level[channel] = lvl;
}

void light_all_off(void)
{
    for (uint8_t c = 0; c < LIGHT_CHANNELS; c++) {
        light_set(c, 0, 0);
    }
}

uint16_t light_level(uint8_t channel) { return channel < LIGHT_CHANNELS ? level[channel] : 0; }

uint8_t light_stable(uint8_t channel, uint32_t now_ms)
{
    return channel < LIGHT_CHANNELS && level[channel] != 0 &&
           now_ms - on_since_ms[channel] >= LIGHT_SETTLE_MS;
}
