#include "text.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct kind_name {
    uint8_t kind;
    const char *name;
};

static const struct kind_name NAMES[] = {
    {K_HELLO, "HELLO"},
    {K_HEARTBEAT, "HEARTBEAT"},
    {K_SET_WATCHDOG, "SET_WATCHDOG"},
    {K_SET_LIMITS, "SET_LIMITS"},
    {K_HOME, "HOME"},
    {K_MOVE_ABS, "MOVE_ABS"},
    {K_MOVE_REL, "MOVE_REL"},
    {K_STOP, "STOP"},
    {K_STATUS, "STATUS"},
    {K_LIGHT_ON, "LIGHT_ON"},
    {K_LIGHT_OFF, "LIGHT_OFF"},
    {K_LIGHT_STATUS, "LIGHT_STATUS"},
    {K_ACK, "ACK"},
    {K_NAK, "NAK"},
    {K_HELLO_REPLY, "HELLO_REPLY"},
    {K_STATUS_REPLY, "STATUS_REPLY"},
    {K_LIGHT_STATUS_REPLY, "LIGHT_STATUS_REPLY"},
};

static const char *kind_name(uint8_t kind)
{
    for (size_t i = 0; i < sizeof NAMES / sizeof NAMES[0]; i++) {
        if (NAMES[i].kind == kind) {
            return NAMES[i].name;
        }
    }
    return NULL;
}

struct sink {
    char *p;
    size_t left;
    int overflow;
};

static void put(struct sink *s, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(s->p, s->left, fmt, ap);
    va_end(ap);
    if (n < 0 || (size_t)n >= s->left) {
        s->overflow = 1;
        return;
    }
    s->p += n;
    s->left -= (size_t)n;
}

int text_format(const struct proto_msg *m, char *out, size_t cap)
{
    const char *name = kind_name(m->kind);
    if (!name || cap == 0) {
        return -1;
    }
    struct sink s = {out, cap, 0};
    out[0] = 0;
    put(&s, "%s id=%u", name, (unsigned)m->id);
    switch (m->kind) {
    case K_SET_WATCHDOG:
        put(&s, " timeout=%u", (unsigned)m->u.timeout_ms);
        break;
    case K_SET_LIMITS:
        put(&s, " max_speed=%lu max_accel=%lu", (unsigned long)m->u.limits.max_speed,
            (unsigned long)m->u.limits.max_accel);
        break;
    case K_MOVE_ABS:
        put(&s, " angle=%ld", (long)m->u.angle);
        break;
    case K_MOVE_REL:
        put(&s, " delta=%ld", (long)m->u.delta);
        break;
    case K_LIGHT_ON:
        put(&s, " channel=%u level=%u exclusive=%u", (unsigned)m->u.light_on.channel,
            (unsigned)m->u.light_on.level, (unsigned)(m->u.light_on.flags & LIGHT_FLAG_EXCLUSIVE));
        break;
    case K_LIGHT_OFF:
        put(&s, " channel=%u", (unsigned)m->u.channel);
        break;
    case K_NAK:
        put(&s, " code=%u detail=%u", (unsigned)m->u.nak.code, (unsigned)m->u.nak.detail);
        break;
    case K_HELLO_REPLY: {
        const struct proto_hello_reply *h = &m->u.hello;
        put(&s,
            " major=%u minor=%u caps=%u boot=%lu channels=%u min_angle=%ld max_angle=%ld"
            " max_speed=%lu max_accel=%lu watchdog=%u name=%.*s",
            (unsigned)h->major, (unsigned)h->minor, (unsigned)h->caps, (unsigned long)h->boot,
            (unsigned)h->channels, (long)h->min_angle, (long)h->max_angle,
            (unsigned long)h->max_speed, (unsigned long)h->max_accel, (unsigned)h->watchdog_ms,
            (int)h->name_len, h->name);
        break;
    }
    case K_STATUS_REPLY: {
        const struct proto_status_reply *st = &m->u.status;
        put(&s, " angle=%ld target=%ld moving=%u homed=%u enabled=%u faults=%u boot=%lu uptime=%lu",
            (long)st->angle, (long)st->target, (unsigned)!!(st->flags & STATUS_MOVING),
            (unsigned)!!(st->flags & STATUS_HOMED), (unsigned)!!(st->flags & STATUS_ENABLED),
            (unsigned)st->faults, (unsigned long)st->boot, (unsigned long)st->uptime_ms);
        break;
    }
    case K_LIGHT_STATUS_REPLY: {
        const struct proto_light_status_reply *l = &m->u.light;
        put(&s, " channels=%u", (unsigned)l->channels);
        for (unsigned i = 0; i < l->channels; i++) {
            put(&s, " level%u=%u stable%u=%u", i, (unsigned)l->level[i], i,
                (unsigned)(l->flags[i] & LIGHT_STABLE));
        }
        break;
    }
    default:
        break;
    }
    return s.overflow ? -1 : 0;
}

/* Finds `key=` as a whole token in `line`; returns a pointer to the value or NULL. */
static const char *find_key(const char *line, const char *key)
{
    size_t klen = strlen(key);
    const char *p = line;
    while ((p = strstr(p, key)) != NULL) {
        int starts = (p == line || p[-1] == ' ');
        if (starts && p[klen] == '=') {
            return p + klen + 1;
        }
        p += klen;
    }
    return NULL;
}

struct parser {
    const char *line;
    char *err;
    size_t errcap;
    int failed;
};

static long long field(struct parser *ps, const char *key, long long lo, long long hi)
{
    const char *v = find_key(ps->line, key);
    if (!v) {
        if (!ps->failed) {
            snprintf(ps->err, ps->errcap, "missing field %s", key);
        }
        ps->failed = 1;
        return 0;
    }
    char *end;
    long long x = strtoll(v, &end, 10);
    if (end == v || (*end != ' ' && *end != 0 && *end != '\n' && *end != '\r') || x < lo ||
        x > hi) {
        if (!ps->failed) {
            snprintf(ps->err, ps->errcap, "bad value for %s", key);
        }
        ps->failed = 1;
        return 0;
    }
    return x;
}

#define U8(k) ((uint8_t)field(&ps, k, 0, 0xFF))
#define U16(k) ((uint16_t)field(&ps, k, 0, 0xFFFF))
#define U32(k) ((uint32_t)field(&ps, k, 0, 0xFFFFFFFFll))
#define I32(k) ((int32_t)field(&ps, k, -2147483648ll, 2147483647ll))
#define BIT(k) ((uint8_t)field(&ps, k, 0, 1))

int text_parse(const char *line, struct proto_msg *m, char *err, size_t errcap)
{
    struct parser ps = {line, err, errcap, 0};
    memset(m, 0, sizeof *m);
    size_t nlen = strcspn(line, " ");
    int found = 0;
    for (size_t i = 0; i < sizeof NAMES / sizeof NAMES[0]; i++) {
        if (strlen(NAMES[i].name) == nlen && strncmp(NAMES[i].name, line, nlen) == 0) {
            m->kind = NAMES[i].kind;
            found = 1;
        }
    }
    if (!found) {
        snprintf(err, errcap, "unknown kind name");
        return -1;
    }
    m->id = U16("id");
    switch (m->kind) {
    case K_SET_WATCHDOG:
        m->u.timeout_ms = U16("timeout");
        break;
    case K_SET_LIMITS:
        m->u.limits.max_speed = U32("max_speed");
        m->u.limits.max_accel = U32("max_accel");
        break;
    case K_MOVE_ABS:
        m->u.angle = I32("angle");
        break;
    case K_MOVE_REL:
        m->u.delta = I32("delta");
        break;
    case K_LIGHT_ON:
        m->u.light_on.channel = U8("channel");
        m->u.light_on.level = U16("level");
        m->u.light_on.flags = BIT("exclusive") ? LIGHT_FLAG_EXCLUSIVE : 0;
        break;
    case K_LIGHT_OFF:
        m->u.channel = U8("channel");
        break;
    case K_NAK:
        m->u.nak.code = U8("code");
        m->u.nak.detail = U8("detail");
        break;
    case K_HELLO_REPLY: {
        struct proto_hello_reply *h = &m->u.hello;
        h->major = U8("major");
        h->minor = U8("minor");
        h->caps = U16("caps");
        h->boot = U32("boot");
        h->channels = U8("channels");
        h->min_angle = I32("min_angle");
        h->max_angle = I32("max_angle");
        h->max_speed = U32("max_speed");
        h->max_accel = U32("max_accel");
        h->watchdog_ms = U16("watchdog");
        const char *name = find_key(line, "name");
        if (!name) {
            snprintf(err, errcap, "missing field name");
            return -1;
        }
        size_t len = strcspn(name, "\r\n");
        if (len > PROTO_NAME_MAX) {
            snprintf(err, errcap, "name longer than %d", PROTO_NAME_MAX);
            return -1;
        }
        h->name_len = (uint8_t)len;
        memcpy(h->name, name, len);
        break;
    }
    case K_STATUS_REPLY: {
        struct proto_status_reply *s = &m->u.status;
        s->angle = I32("angle");
        s->target = I32("target");
        s->flags = (uint8_t)((BIT("moving") ? STATUS_MOVING : 0) | (BIT("homed") ? STATUS_HOMED : 0) |
                             (BIT("enabled") ? STATUS_ENABLED : 0));
        s->faults = U16("faults");
        s->boot = U32("boot");
        s->uptime_ms = U32("uptime");
        break;
    }
    case K_LIGHT_STATUS_REPLY: {
        struct proto_light_status_reply *l = &m->u.light;
        l->channels = (uint8_t)field(&ps, "channels", 0, PROTO_CHANNELS_MAX);
        for (unsigned i = 0; i < l->channels && !ps.failed; i++) {
            char k[16];
            snprintf(k, sizeof k, "level%u", i);
            l->level[i] = U16(k);
            snprintf(k, sizeof k, "stable%u", i);
            l->flags[i] = BIT(k) ? LIGHT_STABLE : 0;
        }
        break;
    }
    default:
        break;
    }
    return ps.failed ? -1 : 0;
}
