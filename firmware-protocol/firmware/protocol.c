/* Pure codec of the wire protocol; see protocol.h and PROTOCOL.md. */
#include "protocol.h"

#include "cobs.h"
#include "crc16.h"

#include <string.h>

/* Body length of the fixed-length kinds; -1 for unknown kinds, -2 for variable-length ones. */
static int body_len(uint8_t kind)
{
    switch (kind) {
    case K_HELLO:
    case K_HEARTBEAT:
    case K_HOME:
    case K_STOP:
    case K_STATUS:
    case K_LIGHT_STATUS:
    case K_ACK:
        return 0;
    case K_SET_WATCHDOG:
        return 2;
    case K_SET_LIMITS:
        return 8;
    case K_MOVE_ABS:
    case K_MOVE_REL:
        return 4;
    case K_LIGHT_ON:
        return 4;
    case K_LIGHT_OFF:
        return 1;
    case K_NAK:
        return 2;
    case K_STATUS_REPLY:
        return 4 + 4 + 1 + 2 + 4 + 4;
    case K_HELLO_REPLY:
    case K_LIGHT_STATUS_REPLY:
        return -2;
    default:
        return -1;
    }
}

/* HELLO_REPLY body without the name bytes. */
#define HELLO_FIXED (1 + 1 + 2 + 4 + 1 + 4 + 4 + 4 + 4 + 2 + 1)

static uint16_t get16(const uint8_t *p) { return (uint16_t)(p[0] | ((uint16_t)p[1] << 8)); }

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static uint8_t *put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    return p + 2;
}

static uint8_t *put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
    return p + 4;
}

const char *proto_result_name(enum proto_result r)
{
    switch (r) {
    case P_OK:
        return "ok";
    case P_REJECT_COBS:
        return "cobs";
    case P_REJECT_SHORT:
        return "short";
    case P_REJECT_LONG:
        return "long";
    case P_REJECT_CRC:
        return "crc";
    case P_REJECT_KIND:
        return "kind";
    case P_REJECT_LENGTH:
        return "length";
    }
    return "?";
}

enum proto_result proto_unframe(const uint8_t *wire, size_t wire_len, uint8_t *payload,
                                size_t *payload_len)
{
    /* Validate first, so a well-formed but oversized frame is "long", not "cobs". */
    int n = cobs_decode(wire, wire_len, NULL, 0);
    if (n < 0) {
        return P_REJECT_COBS;
    }
    if (n < PROTO_PAYLOAD_MIN + 2) {
        return P_REJECT_SHORT;
    }
    if (n > PROTO_DECODED_MAX) {
        return P_REJECT_LONG;
    }
    uint8_t dec[PROTO_DECODED_MAX];
    cobs_decode(wire, wire_len, dec, sizeof dec);
    size_t len = (size_t)n - 2;
    if (crc16(dec, len) != get16(dec + len)) {
        return P_REJECT_CRC;
    }
    memcpy(payload, dec, len);
    *payload_len = len;
    return P_OK;
}

size_t proto_frame(const uint8_t *payload, size_t len, uint8_t *out)
{
    uint8_t raw[PROTO_DECODED_MAX];
    if (len > PROTO_PAYLOAD_MAX) {
        return 0;
    }
    memcpy(raw, payload, len);
    put16(raw + len, crc16(payload, len));
    size_t n = cobs_encode(raw, len + 2, out);
    out[n++] = 0;
    return n;
}

enum proto_result proto_parse(const uint8_t *payload, size_t len, struct proto_msg *msg,
                              uint8_t *expected)
{
    memset(msg, 0, sizeof *msg);
    if (len < PROTO_PAYLOAD_MIN) {
        return P_REJECT_SHORT;
    }
    if (len > PROTO_PAYLOAD_MAX) {
        return P_REJECT_LONG;
    }
    msg->kind = payload[0];
    msg->id = get16(payload + 1);
    const uint8_t *b = payload + 3;
    size_t blen = len - 3;
    int want = body_len(msg->kind);
    if (want == -1) {
        return P_REJECT_KIND;
    }
    if (want == -2) {
        /* Variable length: the count inside the body fixes the length. */
        if (msg->kind == K_HELLO_REPLY) {
            want = HELLO_FIXED + (blen >= HELLO_FIXED ? b[HELLO_FIXED - 1] : 0);
            if (blen >= HELLO_FIXED && b[HELLO_FIXED - 1] > PROTO_NAME_MAX) {
                want = HELLO_FIXED + PROTO_NAME_MAX;
                if ((size_t)want == blen) {
                    want++; /* a name longer than 16 is never a valid length */
                }
            }
        } else {
            want = 1 + 3 * (blen >= 1 ? b[0] : 0);
            if (blen >= 1 && b[0] > PROTO_CHANNELS_MAX) {
                want = 1 + 3 * PROTO_CHANNELS_MAX;
                if ((size_t)want == blen) {
                    want++;
                }
            }
        }
    }
    if ((size_t)want != blen) {
        if (expected) {
            *expected = (uint8_t)want;
        }
        return P_REJECT_LENGTH;
    }
    switch (msg->kind) {
    case K_SET_WATCHDOG:
        msg->u.timeout_ms = get16(b);
        break;
    case K_SET_LIMITS:
        msg->u.limits.max_speed = get32(b);
        msg->u.limits.max_accel = get32(b + 4);
        break;
    case K_MOVE_ABS:
        msg->u.angle = (int32_t)get32(b);
        break;
    case K_MOVE_REL:
        msg->u.delta = (int32_t)get32(b);
        break;
    case K_LIGHT_ON:
        msg->u.light_on.channel = b[0];
        msg->u.light_on.level = get16(b + 1);
        msg->u.light_on.flags = b[3];
        break;
    case K_LIGHT_OFF:
        msg->u.channel = b[0];
        break;
    case K_NAK:
        msg->u.nak.code = b[0];
        msg->u.nak.detail = b[1];
        break;
    case K_HELLO_REPLY: {
        struct proto_hello_reply *h = &msg->u.hello;
        h->major = b[0];
        h->minor = b[1];
        h->caps = get16(b + 2);
        h->boot = get32(b + 4);
        h->channels = b[8];
        h->min_angle = (int32_t)get32(b + 9);
        h->max_angle = (int32_t)get32(b + 13);
        h->max_speed = get32(b + 17);
        h->max_accel = get32(b + 21);
        h->watchdog_ms = get16(b + 25);
        h->name_len = b[27];
        memcpy(h->name, b + 28, h->name_len);
        break;
    }
    case K_STATUS_REPLY: {
        struct proto_status_reply *s = &msg->u.status;
        s->angle = (int32_t)get32(b);
        s->target = (int32_t)get32(b + 4);
        s->flags = b[8];
        s->faults = get16(b + 9);
        s->boot = get32(b + 11);
        s->uptime_ms = get32(b + 15);
        break;
    }
    case K_LIGHT_STATUS_REPLY: {
        struct proto_light_status_reply *l = &msg->u.light;
        l->channels = b[0];
        for (uint8_t i = 0; i < l->channels; i++) {
            l->level[i] = get16(b + 1 + 3 * i);
            l->flags[i] = b[3 + 3 * i];
        }
        break;
    }
    default:
        break; /* empty bodies */
    }
    return P_OK;
}

size_t proto_serialize(const struct proto_msg *msg, uint8_t *payload)
{
    uint8_t *p = payload;
    *p++ = msg->kind;
    p = put16(p, msg->id);
    switch (msg->kind) {
    case K_HELLO:
    case K_HEARTBEAT:
    case K_HOME:
    case K_STOP:
    case K_STATUS:
    case K_LIGHT_STATUS:
    case K_ACK:
        break;
    case K_SET_WATCHDOG:
        p = put16(p, msg->u.timeout_ms);
        break;
    case K_SET_LIMITS:
        p = put32(p, msg->u.limits.max_speed);
        p = put32(p, msg->u.limits.max_accel);
        break;
    case K_MOVE_ABS:
        p = put32(p, (uint32_t)msg->u.angle);
        break;
    case K_MOVE_REL:
        p = put32(p, (uint32_t)msg->u.delta);
        break;
    case K_LIGHT_ON:
        *p++ = msg->u.light_on.channel;
        p = put16(p, msg->u.light_on.level);
        *p++ = msg->u.light_on.flags;
        break;
    case K_LIGHT_OFF:
        *p++ = msg->u.channel;
        break;
    case K_NAK:
        *p++ = msg->u.nak.code;
        *p++ = msg->u.nak.detail;
        break;
    case K_HELLO_REPLY: {
        const struct proto_hello_reply *h = &msg->u.hello;
        if (h->name_len > PROTO_NAME_MAX) {
            return 0;
        }
        *p++ = h->major;
        *p++ = h->minor;
        p = put16(p, h->caps);
        p = put32(p, h->boot);
        *p++ = h->channels;
        p = put32(p, (uint32_t)h->min_angle);
        p = put32(p, (uint32_t)h->max_angle);
        p = put32(p, h->max_speed);
        p = put32(p, h->max_accel);
        p = put16(p, h->watchdog_ms);
        *p++ = h->name_len;
        memcpy(p, h->name, h->name_len);
        p += h->name_len;
        break;
    }
    case K_STATUS_REPLY: {
        const struct proto_status_reply *s = &msg->u.status;
        p = put32(p, (uint32_t)s->angle);
        p = put32(p, (uint32_t)s->target);
        *p++ = s->flags;
        p = put16(p, s->faults);
        p = put32(p, s->boot);
        p = put32(p, s->uptime_ms);
        break;
    }
    case K_LIGHT_STATUS_REPLY: {
        const struct proto_light_status_reply *l = &msg->u.light;
        if (l->channels > PROTO_CHANNELS_MAX) {
            return 0;
        }
        *p++ = l->channels;
        for (uint8_t i = 0; i < l->channels; i++) {
            p = put16(p, l->level[i]);
            *p++ = l->flags[i];
        }
        break;
    }
    default:
        return 0;
    }
    return (size_t)(p - payload);
}

void proto_rx_init(struct proto_rx *rx)
{
    rx->len = 0;
    rx->discarding = 0;
    rx->overflowed = 0;
}

int proto_rx_feed(struct proto_rx *rx, uint8_t byte, uint8_t *payload, size_t *payload_len)
{
    if (byte != 0) {
        if (rx->discarding) {
            return -1;
        }
        if (rx->len >= PROTO_RX_MAX) {
            rx->discarding = 1;
            rx->overflowed = 1;
            rx->len = 0;
            return -1;
        }
        rx->buf[rx->len++] = byte;
        return -1;
    }
    if (rx->discarding) {
        /* The frame that overflowed the buffer ends here: it was too long. */
        rx->discarding = 0;
        rx->len = 0;
        return P_REJECT_LONG;
    }
    if (rx->len == 0) {
        return -1; /* empty frame: ignored */
    }
    uint8_t len = rx->len;
    rx->len = 0;
    return proto_unframe(rx->buf, len, payload, payload_len);
}
