/* brdf-rig reference firmware for the Arduino Mega 2560: the main loop receives frames, executes
 * requests (PROTOCOL.md section 4), runs the host watchdog (section 7) and keeps the boot counter
 * (section 8). Motion runs in the timer-1 interrupt (stepper.c), reception in the UART interrupt
 * (uart.c); everything protocol-shaped is in the pure protocol.c. */
#include "config.h"
#include "light.h"
#include "protocol.h"
#include "stepper.h"
#include "uart.h"

#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/wdt.h>
#include <string.h>
#include <util/atomic.h>

_Static_assert(sizeof(FW_NAME) - 1 <= PROTO_NAME_MAX, "FW_NAME longer than 16 characters");
_Static_assert(ANGLE_MIN_MDEG <= 0 && ANGLE_MAX_MDEG >= 0, "home (0) must lie in the angle range");

#define CAPABILITIES (CAP_TURNTABLE | CAP_LIGHT | CAP_HOME_SWITCH | CAP_SIMULTANEOUS)

/* The boot counter lives in the first EEPROM word; erased EEPROM reads 0xFFFFFFFF. */
static uint32_t EEMEM ee_boot_count;

static uint32_t boot_count;
static uint16_t faults;        /* latched until reported by STATUS */
static uint8_t homed;
static uint16_t watchdog_ms = WATCHDOG_DEFAULT_MS;
static uint32_t last_rx_ms;
/* Armed by the first valid frame and after each trip, so an unconnected board does not latch
 * WATCHDOG, and a silent host trips it once, not every timeout. */
static uint8_t watchdog_armed;
static uint32_t limit_speed = MAX_SPEED_MDEG_S;
static uint32_t limit_accel = MAX_ACCEL_MDEG_S2;

/* The last executed request's id and reply payload (section 4, "Retries are safe"). */
static uint16_t last_id;
static uint8_t last_len; /* 0: nothing remembered */
static uint8_t last_reply[PROTO_PAYLOAD_MAX];

static volatile uint32_t ms;

/* The turntable's motion as seen at the start of the request being answered (handle_frame). */
static uint8_t moving;

ISR(TIMER3_COMPA_vect) { ms++; }

static uint32_t millis(void)
{
    uint32_t m;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { m = ms; }
    return m;
}

/* The reset cause must be read and the watchdog disabled before anything else runs, or a watchdog
 * reset would repeat forever. */
static uint8_t reset_flags __attribute__((section(".noinit")));
void early_init(void) __attribute__((naked, used, section(".init3")));
void early_init(void)
{
    reset_flags = MCUSR;
    MCUSR = 0;
    wdt_disable();
}

static void boot_counter_init(void)
{
    uint32_t n = eeprom_read_dword(&ee_boot_count);
    if (n == 0xFFFFFFFFUL) {
        n = 0;
    }
    boot_count = n + 1;
    eeprom_update_dword(&ee_boot_count, boot_count);
}

static void millis_init(void)
{
    /* Timer 3, CTC on OCR3A, prescaler 64: 250 kHz counts, 1 kHz interrupts. */
    TCCR3A = 0;
    TCCR3B = _BV(WGM32) | _BV(CS31) | _BV(CS30);
    OCR3A = (uint16_t)(F_CPU / 64UL / 1000UL - 1UL);
    TIMSK3 = _BV(OCIE3A);
}

static void nak(struct proto_msg *rep, uint8_t code, uint8_t detail)
{
    rep->kind = K_NAK;
    rep->u.nak.code = code;
    rep->u.nak.detail = detail;
}

static uint8_t in_range(int64_t angle)
{
    return angle >= ANGLE_MIN_MDEG && angle <= ANGLE_MAX_MDEG;
}

static void do_hello(struct proto_msg *rep)
{
    struct proto_hello_reply *h = &rep->u.hello;
    rep->kind = K_HELLO_REPLY;
    h->major = PROTO_MAJOR;
    h->minor = PROTO_MINOR;
    h->caps = CAPABILITIES;
    h->boot = boot_count;
    h->channels = LIGHT_CHANNELS;
    h->min_angle = ANGLE_MIN_MDEG;
    h->max_angle = ANGLE_MAX_MDEG;
    h->max_speed = MAX_SPEED_MDEG_S;
    h->max_accel = MAX_ACCEL_MDEG_S2;
    h->watchdog_ms = watchdog_ms;
    h->name_len = sizeof(FW_NAME) - 1;
    memcpy(h->name, FW_NAME, sizeof(FW_NAME) - 1);
}

static void do_status(struct proto_msg *rep, uint32_t now)
{
    struct proto_status_reply *s = &rep->u.status;
    rep->kind = K_STATUS_REPLY;
    s->angle = stepper_angle_mdeg();
    s->target = stepper_target_mdeg();
    s->flags = (uint8_t)((moving ? STATUS_MOVING : 0) | (homed ? STATUS_HOMED : 0) |
                         (stepper_enabled() ? STATUS_ENABLED : 0));
    s->faults = faults;
    faults = 0;
    s->boot = boot_count;
    s->uptime_ms = now;
}

static void do_light_status(struct proto_msg *rep, uint32_t now)
{
    rep->kind = K_LIGHT_STATUS_REPLY;
    rep->u.light.channels = LIGHT_CHANNELS;
    for (uint8_t c = 0; c < LIGHT_CHANNELS; c++) {
        rep->u.light.level[c] = light_level(c);
        rep->u.light.flags[c] = light_stable(c, now) ? LIGHT_STABLE : 0;
    }
}

/* Executes a well-formed request; `rep` starts as an ACK with the request's id. */
static void execute(const struct proto_msg *req, struct proto_msg *rep, uint32_t now)
{
    switch (req->kind) {
    case K_HELLO:
        do_hello(rep);
        break;
    case K_HEARTBEAT:
        break;
    case K_SET_WATCHDOG:
        if (req->u.timeout_ms < WATCHDOG_MIN_MS || req->u.timeout_ms > WATCHDOG_MAX_MS) {
            nak(rep, E_OUT_OF_RANGE, 0);
        } else {
            watchdog_ms = req->u.timeout_ms;
        }
        break;
    case K_SET_LIMITS:
        if (req->u.limits.max_speed == 0 || req->u.limits.max_speed > MAX_SPEED_MDEG_S ||
            req->u.limits.max_accel == 0 || req->u.limits.max_accel > MAX_ACCEL_MDEG_S2) {
            nak(rep, E_OUT_OF_RANGE, 0);
        } else {
            limit_speed = req->u.limits.max_speed;
            limit_accel = req->u.limits.max_accel;
            stepper_set_limits(limit_speed, limit_accel);
        }
        break;
    case K_HOME:
        if (moving) {
            nak(rep, E_BUSY, 0);
        } else {
            homed = 0;
            stepper_home();
        }
        break;
    case K_MOVE_ABS:
    case K_MOVE_REL: {
        /* Relative moves add to the last target, not to the rounded step position, so a scan of
         * relative moves does not accumulate rounding. */
        int64_t target = req->kind == K_MOVE_ABS
                             ? (int64_t)req->u.angle
                             : (int64_t)stepper_target_mdeg() + (int64_t)req->u.delta;
        if (moving) {
            nak(rep, E_BUSY, 0);
        } else if (!homed) {
            nak(rep, E_NOT_HOMED, 0);
        } else if (!in_range(target)) {
            nak(rep, E_OUT_OF_RANGE, 0);
        } else {
            stepper_move_to((int32_t)target);
        }
        break;
    }
    case K_STOP:
        stepper_stop();
        break;
    case K_STATUS:
        do_status(rep, now);
        break;
    case K_LIGHT_ON: {
        uint8_t ch = req->u.light_on.channel;
        if (ch >= LIGHT_CHANNELS) {
            nak(rep, E_BAD_CHANNEL, LIGHT_CHANNELS);
            break;
        }
        if (req->u.light_on.level != 0 && (req->u.light_on.flags & LIGHT_FLAG_EXCLUSIVE)) {
            for (uint8_t c = 0; c < LIGHT_CHANNELS; c++) {
                if (c != ch) {
                    light_set(c, 0, now);
                }
            }
        }
        light_set(ch, req->u.light_on.level, now);
        break;
    }
    case K_LIGHT_OFF:
        if (req->u.channel == LIGHT_ALL_CHANNELS) {
            light_all_off();
        } else if (req->u.channel >= LIGHT_CHANNELS) {
            nak(rep, E_BAD_CHANNEL, LIGHT_CHANNELS);
        } else {
            light_set(req->u.channel, 0, now);
        }
        break;
    case K_LIGHT_STATUS:
        do_light_status(rep, now);
        break;
    default:
        nak(rep, E_UNKNOWN_KIND, 0);
        break;
    }
}

static void send(const uint8_t *payload, uint8_t len)
{
    uint8_t wire[PROTO_FRAME_MAX];
    size_t n = proto_frame(payload, len, wire);
    uart_write(wire, (uint8_t)n);
}

/* Takes the outcome of a finished home search into `homed` and the faults. Called before every
 * request too: the search can end between two passes of the main loop, and a STATUS must never
 * show "at rest" together with the `homed` of before the search ended. */
static void poll_home(void)
{
    switch (stepper_take_home_result()) {
    case HOME_FOUND:
        homed = 1;
        break;
    case HOME_FAILED:
        faults |= FAULT_HOME_FAILED;
        break;
    case HOME_NONE:
        break;
    }
}

/* One frame that passed COBS, length and CRC checks. */
static void handle_frame(const uint8_t *payload, size_t len, uint32_t now)
{
    struct proto_msg req;
    struct proto_msg rep;
    uint8_t expected = 0;
    enum proto_result r = proto_parse(payload, len, &req, &expected);

    last_rx_ms = now;
    watchdog_armed = 1;
    /* Motion state first, then the home outcome: a search that ends in between is then seen
     * as "moving" (still true a moment ago), never as "at rest and not homed". */
    moving = stepper_moving();
    poll_home();

    if (req.id != 0 && last_len != 0 && req.id == last_id) {
        send(last_reply, last_len); /* a retry: answer again, never execute twice */
        return;
    }
    memset(&rep, 0, sizeof rep);
    rep.kind = K_ACK;
    rep.id = req.id;
    if (r == P_REJECT_KIND || req.kind >= 0x80) {
        nak(&rep, E_UNKNOWN_KIND, 0); /* replies are not requests */
    } else if (r == P_REJECT_LENGTH) {
        nak(&rep, E_BAD_LENGTH, expected);
    } else {
        execute(&req, &rep, now);
    }
    uint8_t out[PROTO_PAYLOAD_MAX];
    uint8_t n = (uint8_t)proto_serialize(&rep, out);
    if (req.id != 0) {
        last_id = req.id;
        last_len = n;
        memcpy(last_reply, out, n);
    }
    send(out, n);
}

int main(void)
{
    if ((reset_flags & _BV(BORF)) && !(reset_flags & _BV(PORF))) {
        faults |= FAULT_BROWN_OUT;
    }
    boot_counter_init();
    light_init();
    stepper_init();
    millis_init();
    uart_init();
    wdt_enable(WDTO_500MS);
    sei();
#if BOOT_DELAY_MS > 0
    /* A bootloader's window: whatever arrives now is read and lost. */
    while (millis() < BOOT_DELAY_MS) {
        uint8_t c;
        wdt_reset();
        while (uart_getc(&c)) {
        }
    }
    (void)uart_take_overflow();
#endif

    struct proto_rx rx;
    proto_rx_init(&rx);
    for (;;) {
        wdt_reset();
        uint32_t now = millis();
        uint8_t c;
        while (uart_getc(&c)) {
            uint8_t payload[PROTO_DECODED_MAX];
            size_t len = 0;
            if (proto_rx_feed(&rx, c, payload, &len) == P_OK) {
                handle_frame(payload, len, now);
            }
        }
        /* Frames lost to the UART ring buffer, or to 64 bytes without a delimiter. */
        if (uart_take_overflow() || rx.overflowed) {
            rx.overflowed = 0;
            faults |= FAULT_RX_OVERFLOW;
        }
        poll_home();
        if (watchdog_armed && now - last_rx_ms >= watchdog_ms) {
            light_all_off();
            stepper_stop();
            faults |= FAULT_WATCHDOG;
            watchdog_armed = 0;
        }
    }
}
