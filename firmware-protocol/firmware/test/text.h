/* Canonical text form of a decoded frame (PROTOCOL.md section 9), host-side only: the firmware
 * never prints frames, so this stays out of the AVR build. */
#ifndef TEXT_H
#define TEXT_H

#include "../protocol.h"

/* Writes the canonical one-line form of `msg` into `out` (room for `cap`); returns 0 on success. */
int text_format(const struct proto_msg *msg, char *out, size_t cap);

/* Parses a canonical line (not a REJECT line) into `msg`; returns 0 on success, -1 with a reason
 * in `err` otherwise. */
int text_parse(const char *line, struct proto_msg *msg, char *err, size_t errcap);

#endif
