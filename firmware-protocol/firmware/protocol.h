/* brdf-rig wire protocol 1.0 (firmware-protocol/PROTOCOL.md): frame encoding/decoding and the
 * payload of every kind as a C struct. Pure: no I/O, no globals, no heap; compiles for the AVR and
 * for the host (where test/host_test.c checks it against the shared vectors).
 *
 * Conventions: multi-byte integers are little-endian on the wire; angles in millidegrees (i32),
 * speeds in millidegrees/s, accelerations in millidegrees/s^2, times in ms, light levels u16. */
#ifndef PROTOCOL_H
#define PROTOCOL_H

#include <stddef.h>
#include <stdint.h>

#define PROTO_MAJOR 1
#define PROTO_MINOR 0

#define PROTO_PAYLOAD_MIN 3   /* kind + request id */
#define PROTO_PAYLOAD_MAX 60
#define PROTO_DECODED_MAX 62  /* payload + CRC */
#define PROTO_RX_MAX 64       /* accumulated bytes without a 0x00 before discarding */
#define PROTO_NAME_MAX 16
#define PROTO_CHANNELS_MAX 18 /* 1 + 3*18 = 55 body bytes fit in the 57 a payload allows */
/* Longest frame on the wire: COBS of 62 bytes (63) plus the 0x00 delimiter. */
#define PROTO_FRAME_MAX (PROTO_DECODED_MAX + 2)

enum proto_kind {
    K_HELLO = 0x01,
    K_HEARTBEAT = 0x02,
    K_SET_WATCHDOG = 0x03,
    K_SET_LIMITS = 0x04,
    K_HOME = 0x10,
    K_MOVE_ABS = 0x11,
    K_MOVE_REL = 0x12,
    K_STOP = 0x13,
    K_STATUS = 0x14,
    K_LIGHT_ON = 0x20,
    K_LIGHT_OFF = 0x21,
    K_LIGHT_STATUS = 0x22,
    K_ACK = 0x80,
    K_NAK = 0x81,
    K_HELLO_REPLY = 0x82,
    K_STATUS_REPLY = 0x83,
    K_LIGHT_STATUS_REPLY = 0x84,
};

enum proto_error {
    E_UNKNOWN_KIND = 1,
    E_BAD_LENGTH = 2,
    E_OUT_OF_RANGE = 3,
    E_NOT_HOMED = 4,
    E_BUSY = 5,
    E_BAD_CHANNEL = 6,
    E_FAULT = 7,
};

/* HELLO_REPLY capability bits. */
#define CAP_TURNTABLE (1u << 0)
#define CAP_LIGHT (1u << 1)
#define CAP_HOME_SWITCH (1u << 2)
#define CAP_SIMULTANEOUS (1u << 3)
#define CAP_WARMUP_SENSING (1u << 4)

/* STATUS_REPLY fault bits. */
#define FAULT_WATCHDOG (1u << 0)
#define FAULT_HOME_FAILED (1u << 1)
#define FAULT_STALL (1u << 2)
#define FAULT_BROWN_OUT (1u << 3)
#define FAULT_RX_OVERFLOW (1u << 4)

/* STATUS_REPLY flag bits. */
#define STATUS_MOVING (1u << 0)
#define STATUS_HOMED (1u << 1)
#define STATUS_ENABLED (1u << 2)

#define LIGHT_FLAG_EXCLUSIVE (1u << 0)
#define LIGHT_STABLE (1u << 0)
#define LIGHT_ALL_CHANNELS 0xFF

#define WATCHDOG_MIN_MS 100u
#define WATCHDOG_MAX_MS 60000u

struct proto_hello_reply {
    uint8_t major, minor;
    uint16_t caps;
    uint32_t boot;
    uint8_t channels;
    int32_t min_angle, max_angle;
    uint32_t max_speed, max_accel;
    uint16_t watchdog_ms;
    uint8_t name_len;
    char name[PROTO_NAME_MAX];
};

struct proto_status_reply {
    int32_t angle, target;
    uint8_t flags; /* STATUS_* */
    uint16_t faults;
    uint32_t boot;
    uint32_t uptime_ms;
};

struct proto_light_status_reply {
    uint8_t channels;
    uint16_t level[PROTO_CHANNELS_MAX];
    uint8_t flags[PROTO_CHANNELS_MAX]; /* LIGHT_STABLE */
};

/* One decoded payload. Which union member is valid follows from `kind`. */
struct proto_msg {
    uint8_t kind;
    uint16_t id;
    union {
        uint16_t timeout_ms;                           /* SET_WATCHDOG */
        struct { uint32_t max_speed, max_accel; } limits; /* SET_LIMITS */
        int32_t angle;                                 /* MOVE_ABS */
        int32_t delta;                                 /* MOVE_REL */
        struct { uint8_t channel; uint16_t level; uint8_t flags; } light_on;
        uint8_t channel;                               /* LIGHT_OFF */
        struct { uint8_t code, detail; } nak;
        struct proto_hello_reply hello;
        struct proto_status_reply status;
        struct proto_light_status_reply light;
    } u;
};

/* Why a frame was not accepted; the names are those of PROTOCOL.md section 9 (REJECT reasons). */
enum proto_result {
    P_OK = 0,
    P_REJECT_COBS,   /* not valid COBS: dropped silently */
    P_REJECT_SHORT,  /* fewer than 5 decoded bytes: dropped silently */
    P_REJECT_LONG,   /* more than 62 decoded bytes (or 64 wire bytes): dropped silently */
    P_REJECT_CRC,    /* CRC mismatch: dropped silently */
    P_REJECT_KIND,   /* unknown kind: a firmware answers NAK UNKNOWN_KIND */
    P_REJECT_LENGTH, /* body length wrong for the kind: a firmware answers NAK BAD_LENGTH */
};

/* "cobs", "crc", ... as in the vectors; "ok" for P_OK. */
const char *proto_result_name(enum proto_result r);

/* Undoes the framing of one frame as received (without its 0x00): COBS, length bounds, CRC.
 * On P_OK the payload (CRC stripped) is in `payload` (room for PROTO_DECODED_MAX bytes) and its
 * length in `*payload_len`. */
enum proto_result proto_unframe(const uint8_t *wire, size_t wire_len, uint8_t *payload,
                                size_t *payload_len);

/* Frames a payload: COBS(payload || crc16 LE) followed by 0x00. `out` needs PROTO_FRAME_MAX bytes.
 * Returns the number of bytes written. */
size_t proto_frame(const uint8_t *payload, size_t len, uint8_t *out);

/* Decodes a payload into `msg`. `kind` and `id` are filled in whenever len >= 3, even on error,
 * so a firmware can address its NAK. On P_REJECT_LENGTH, `*expected` (if not NULL) is the body
 * length the kind requires (detail of the BAD_LENGTH NAK). */
enum proto_result proto_parse(const uint8_t *payload, size_t len, struct proto_msg *msg,
                              uint8_t *expected);

/* Encodes `msg` into a payload (room for PROTO_PAYLOAD_MAX bytes); returns its length, or 0 when
 * the message cannot be encoded (unknown kind, name or channel count too large). */
size_t proto_serialize(const struct proto_msg *msg, uint8_t *payload);

/* Stream receiver (PROTOCOL.md section 2, resynchronisation): feed it bytes one at a time. */
struct proto_rx {
    uint8_t buf[PROTO_RX_MAX];
    uint8_t len;
    uint8_t discarding; /* more than PROTO_RX_MAX bytes without a 0x00: drop until the next 0x00 */
    uint8_t overflowed; /* set when discarding starts; the owner clears it (RX_OVERFLOW fault) */
};

void proto_rx_init(struct proto_rx *rx);

/* Returns P_OK with the payload in `payload`/`*payload_len` when `byte` completes a valid frame
 * (COBS, length and CRC good; kind and body are not checked here), a P_REJECT_* reason when it
 * completes a frame that must be dropped, and -1 when no frame ended (including empty frames). */
int proto_rx_feed(struct proto_rx *rx, uint8_t byte, uint8_t *payload, size_t *payload_len);

#endif
