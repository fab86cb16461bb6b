/* Host test of the pure firmware parts (cobs.c, crc16.c, protocol.c): checks from the spec, then
 * every vector file named on the command line (PROTOCOL.md sections 9-10): each line's wire bytes
 * must decode to its canonical text, and each canonical text must encode to exactly those bytes.
 * Exit status 0 only when everything passed and at least one vector was checked. */
#include "../cobs.h"
#include "../crc16.h"
#include "../protocol.h"
#include "text.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures;
static int checks;

#define CHECK(cond, ...)                                                                          \
    do {                                                                                          \
        checks++;                                                                                 \
        if (!(cond)) {                                                                            \
            failures++;                                                                           \
            fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__);                                  \
            fprintf(stderr, __VA_ARGS__);                                                         \
            fprintf(stderr, "\n");                                                                \
        }                                                                                         \
    } while (0)

static void hexstr(const uint8_t *b, size_t n, char *out)
{
    for (size_t i = 0; i < n; i++) {
        sprintf(out + 2 * i, "%02x", b[i]);
    }
    out[2 * n] = 0;
}

static int unhex(const char *s, size_t slen, uint8_t *out, size_t cap, size_t *n)
{
    if (slen % 2 || slen / 2 > cap) {
        return -1;
    }
    for (size_t i = 0; i < slen / 2; i++) {
        unsigned v;
        if (sscanf(s + 2 * i, "%2x", &v) != 1) {
            return -1;
        }
        out[i] = (uint8_t)v;
    }
    *n = slen / 2;
    return 0;
}

/* ---- checks from the spec, independent of any vector file ---- */

static void test_crc(void)
{
    CHECK(crc16((const uint8_t *)"123456789", 9) == 0x29B1, "CRC check value");
    CHECK(crc16(NULL, 0) == 0xFFFF, "CRC of nothing is the init value");
}

static void test_cobs_case(const uint8_t *raw, size_t n, const uint8_t *enc, size_t m)
{
    uint8_t out[600];
    uint8_t back[600];
    size_t e = cobs_encode(raw, n, out);
    CHECK(e == m && memcmp(out, enc, m) == 0, "COBS encode of %zu bytes", n);
    int d = cobs_decode(enc, m, back, sizeof back);
    CHECK(d == (int)n && memcmp(back, raw, n) == 0, "COBS decode of %zu bytes", n);
    CHECK(cobs_decode(enc, m, NULL, 0) == (int)n, "COBS validate-only length");
}

static void test_cobs(void)
{
    /* The examples of Cheshire & Baker / the usual reference table. */
    test_cobs_case((const uint8_t[]){0x00}, 1, (const uint8_t[]){0x01, 0x01}, 2);
    test_cobs_case((const uint8_t[]){0x00, 0x00}, 2, (const uint8_t[]){0x01, 0x01, 0x01}, 3);
    test_cobs_case((const uint8_t[]){0x11, 0x22, 0x00, 0x33}, 4,
                   (const uint8_t[]){0x03, 0x11, 0x22, 0x02, 0x33}, 5);
    test_cobs_case((const uint8_t[]){0x11, 0x22, 0x33, 0x44}, 4,
                   (const uint8_t[]){0x05, 0x11, 0x22, 0x33, 0x44}, 5);
    test_cobs_case((const uint8_t[]){0x11, 0x00, 0x00, 0x00}, 4,
                   (const uint8_t[]){0x02, 0x11, 0x01, 0x01, 0x01}, 5);
    /* 254 non-zero bytes: one full run, then the closing empty run. */
    uint8_t raw[254];
    uint8_t enc[256];
    for (int i = 0; i < 254; i++) {
        raw[i] = (uint8_t)(i + 1);
    }
    enc[0] = 0xFF;
    memcpy(enc + 1, raw, 254);
    enc[255] = 0x01;
    test_cobs_case(raw, 254, enc, 256);
    uint8_t out[8];
    CHECK(cobs_decode((const uint8_t[]){0x05, 0x11}, 2, out, sizeof out) == -1, "overrun run");
    CHECK(cobs_decode((const uint8_t[]){0x02, 0x00}, 2, out, sizeof out) == -1, "zero inside");
    CHECK(cobs_decode((const uint8_t[]){0x03, 0x11, 0x22}, 3, out, 1) == -1, "too small output");
}

/* Every kind survives serialize -> frame -> receiver -> parse unchanged. */
static void test_round_trip(void)
{
    struct proto_msg msgs[8];
    memset(msgs, 0, sizeof msgs);
    msgs[0].kind = K_MOVE_REL, msgs[0].id = 0x0100, msgs[0].u.delta = -1;
    msgs[1].kind = K_SET_LIMITS, msgs[1].id = 2, msgs[1].u.limits.max_speed = 0xFFFFFFFFu,
    msgs[1].u.limits.max_accel = 1;
    msgs[2].kind = K_LIGHT_ON, msgs[2].id = 3, msgs[2].u.light_on.channel = 2,
    msgs[2].u.light_on.level = 0x1234, msgs[2].u.light_on.flags = 1;
    msgs[3].kind = K_HELLO_REPLY, msgs[3].id = 4, msgs[3].u.hello.name_len = 16;
    memcpy(msgs[3].u.hello.name, "0123456789abcdef", 16);
    msgs[3].u.hello.min_angle = -5;
    msgs[4].kind = K_LIGHT_STATUS_REPLY, msgs[4].id = 5, msgs[4].u.light.channels = PROTO_CHANNELS_MAX;
    for (int i = 0; i < PROTO_CHANNELS_MAX; i++) {
        msgs[4].u.light.level[i] = (uint16_t)(i * 1000);
        msgs[4].u.light.flags[i] = (uint8_t)(i & 1);
    }
    msgs[5].kind = K_STATUS_REPLY, msgs[5].id = 6, msgs[5].u.status.angle = -3600000,
    msgs[5].u.status.flags = 7, msgs[5].u.status.faults = 0x1F, msgs[5].u.status.uptime_ms = 99;
    msgs[6].kind = K_NAK, msgs[6].id = 7, msgs[6].u.nak.code = 2, msgs[6].u.nak.detail = 4;
    msgs[7].kind = K_SET_WATCHDOG, msgs[7].id = 0, msgs[7].u.timeout_ms = 60000;
    for (size_t i = 0; i < sizeof msgs / sizeof msgs[0]; i++) {
        uint8_t payload[PROTO_PAYLOAD_MAX];
        uint8_t wire[PROTO_FRAME_MAX];
        size_t n = proto_serialize(&msgs[i], payload);
        CHECK(n >= 3 && n <= PROTO_PAYLOAD_MAX, "serialize kind 0x%02x", msgs[i].kind);
        size_t w = proto_frame(payload, n, wire);
        CHECK(w <= PROTO_FRAME_MAX && wire[w - 1] == 0, "frame kind 0x%02x", msgs[i].kind);
        CHECK(memchr(wire, 0, w - 1) == NULL, "no zero inside the frame");
        struct proto_rx rx;
        proto_rx_init(&rx);
        uint8_t got[PROTO_DECODED_MAX];
        size_t glen = 0;
        int r = -1;
        for (size_t k = 0; k < w; k++) {
            r = proto_rx_feed(&rx, wire[k], got, &glen);
            if (k + 1 < w) {
                CHECK(r == -1, "frame ended early");
            }
        }
        CHECK(r == P_OK && glen == n && memcmp(got, payload, n) == 0, "receive kind 0x%02x",
              msgs[i].kind);
        struct proto_msg back;
        CHECK(proto_parse(got, glen, &back, NULL) == P_OK, "parse kind 0x%02x", msgs[i].kind);
        char a[400], b[400];
        text_format(&msgs[i], a, sizeof a);
        text_format(&back, b, sizeof b);
        CHECK(strcmp(a, b) == 0, "round trip: %s != %s", a, b);
    }
}

/* Section 2: more than 64 bytes without a 0x00 are discarded up to the next 0x00, after which the
 * receiver works again; empty frames are ignored. */
static void test_rx_resync(void)
{
    struct proto_rx rx;
    proto_rx_init(&rx);
    uint8_t got[PROTO_DECODED_MAX];
    size_t glen;
    CHECK(proto_rx_feed(&rx, 0, got, &glen) == -1, "empty frame ignored");
    for (int i = 0; i < 64; i++) {
        CHECK(proto_rx_feed(&rx, 0x41, got, &glen) == -1, "accumulating");
    }
    CHECK(!rx.overflowed, "64 bytes fit");
    CHECK(proto_rx_feed(&rx, 0x41, got, &glen) == -1, "65th byte starts discarding");
    CHECK(rx.overflowed, "overflow reported to the owner");
    /* A valid frame's bytes while discarding are swallowed... */
    const uint8_t hello[] = {0x03, 0x01, 0x01, 0x03, 0x9d, 0xc8, 0x00};
    int r = 0;
    for (size_t k = 0; k < sizeof hello; k++) {
        r = proto_rx_feed(&rx, hello[k], got, &glen);
    }
    CHECK(r == P_REJECT_LONG, "overflowed frame reported long, got %d", r);
    /* ...and the next one is received. */
    for (size_t k = 0; k < sizeof hello; k++) {
        r = proto_rx_feed(&rx, hello[k], got, &glen);
    }
    CHECK(r == P_OK && glen == 3 && got[0] == K_HELLO, "frame after resync");
}

/* ---- vector files ---- */

struct event {
    char text[400];
};

/* Feeds `wire` to a fresh receiver; writes one text per frame that ended (canonical text, or
 * "REJECT <reason>"). Returns the number of events. */
static int decode_stream(const uint8_t *wire, size_t n, struct event *ev, int max)
{
    struct proto_rx rx;
    proto_rx_init(&rx);
    int count = 0;
    for (size_t i = 0; i < n && count < max; i++) {
        uint8_t payload[PROTO_DECODED_MAX];
        size_t plen = 0;
        int r = proto_rx_feed(&rx, wire[i], payload, &plen);
        if (r == -1) {
            continue;
        }
        if (r == P_OK) {
            struct proto_msg m;
            uint8_t expected = 0;
            r = proto_parse(payload, plen, &m, &expected);
            if (r == P_OK && text_format(&m, ev[count].text, sizeof ev[count].text) != 0) {
                snprintf(ev[count].text, sizeof ev[count].text, "UNFORMATTABLE");
            }
        }
        if (r != P_OK) {
            snprintf(ev[count].text, sizeof ev[count].text, "REJECT %s",
                     proto_result_name((enum proto_result)r));
        }
        count++;
    }
    return count;
}

static int vectors_checked;

static void check_line(const char *file, int lineno, char *line)
{
    line[strcspn(line, "\r\n")] = 0;
    if (line[0] == '#' || line[0] == 0) {
        return;
    }
    uint8_t wire[4096];
    size_t wlen = 0;
    struct event ev[32];
    vectors_checked++;
    if (strncmp(line, "stream\t", 7) == 0) {
        char *hex = line + 7;
        char *tab = strchr(hex, '\t');
        CHECK(tab != NULL, "%s:%d: stream line without texts", file, lineno);
        if (!tab) {
            return;
        }
        *tab = 0;
        CHECK(unhex(hex, strlen(hex), wire, sizeof wire, &wlen) == 0, "%s:%d: bad hex", file,
              lineno);
        int n = decode_stream(wire, wlen, ev, 32);
        /* The frames a receiver must extract: the dropped ones (cobs, crc, ...) produce nothing
         * a receiver reports, unless the vector lists them. */
        char *want = tab + 1;
        int k = 0;
        char *save = NULL;
        for (char *t = strtok_r(want, "|", &save); t; t = strtok_r(NULL, "|", &save)) {
            int listed_reject = strncmp(t, "REJECT ", 7) == 0;
            while (k < n && strncmp(ev[k].text, "REJECT ", 7) == 0 && !listed_reject) {
                k++;
            }
            CHECK(k < n && strcmp(ev[k].text, t) == 0, "%s:%d: stream wants '%s', got '%s'", file,
                  lineno, t, k < n ? ev[k].text : "(nothing)");
            k++;
        }
        while (k < n && strncmp(ev[k].text, "REJECT ", 7) == 0) {
            k++;
        }
        CHECK(k >= n, "%s:%d: stream yields extra frame '%s'", file, lineno, ev[k < n ? k : 0].text);
        return;
    }
    char *tab = strchr(line, '\t');
    CHECK(tab != NULL, "%s:%d: line without a tab", file, lineno);
    if (!tab) {
        return;
    }
    *tab = 0;
    const char *want = tab + 1;
    CHECK(unhex(line, strlen(line), wire, sizeof wire, &wlen) == 0, "%s:%d: bad hex", file, lineno);
    int n = decode_stream(wire, wlen, ev, 32);
    CHECK(n == 1 && strcmp(ev[0].text, want) == 0, "%s:%d: decode wants '%s', got '%s' (%d frames)",
          file, lineno, want, n > 0 ? ev[0].text : "(nothing)", n);
    if (strncmp(want, "REJECT ", 7) == 0) {
        return;
    }
    struct proto_msg m;
    char err[100];
    int pr = text_parse(want, &m, err, sizeof err);
    CHECK(pr == 0, "%s:%d: cannot parse '%s': %s", file, lineno, want, err);
    if (pr != 0) {
        return;
    }
    uint8_t payload[PROTO_PAYLOAD_MAX];
    uint8_t out[PROTO_FRAME_MAX];
    size_t plen = proto_serialize(&m, payload);
    size_t olen = plen ? proto_frame(payload, plen, out) : 0;
    char got_hex[2 * PROTO_FRAME_MAX + 1];
    hexstr(out, olen, got_hex);
    CHECK(olen == wlen && memcmp(out, wire, wlen) == 0, "%s:%d: encode of '%s' gives %s, want %s",
          file, lineno, want, got_hex, line);
}

static void check_file(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        CHECK(0, "cannot open vector file %s", path);
        return;
    }
    char line[8192];
    int lineno = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        check_line(path, lineno, line);
    }
    fclose(f);
}

static int ends_with(const char *s, const char *suffix)
{
    size_t a = strlen(s), b = strlen(suffix);
    return a >= b && strcmp(s + a - b, suffix) == 0;
}

/* A directory: every *.txt in it, in name order. A file: that file. */
static void check_path(const char *path)
{
    struct dirent **list;
    int n = scandir(path, &list, NULL, alphasort);
    if (n < 0) {
        check_file(path);
        return;
    }
    for (int i = 0; i < n; i++) {
        if (ends_with(list[i]->d_name, ".txt")) {
            char full[4096];
            snprintf(full, sizeof full, "%s/%s", path, list[i]->d_name);
            int before = vectors_checked;
            check_file(full);
            printf("  %s: %d vectors\n", full, vectors_checked - before);
        }
        free(list[i]);
    }
    free(list);
}

int main(int argc, char **argv)
{
    test_crc();
    test_cobs();
    test_round_trip();
    test_rx_resync();
    for (int i = 1; i < argc; i++) {
        check_path(argv[i]);
    }
    printf("host-test: %d checks, %d vectors, %d failures\n", checks, vectors_checked, failures);
    if (vectors_checked == 0) {
        fprintf(stderr, "host-test: no vectors were checked (give vector files or directories)\n");
        return 1;
    }
    return failures ? 1 : 0;
}
