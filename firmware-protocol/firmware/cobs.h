/* Consistent Overhead Byte Stuffing (Cheshire & Baker 1999), PROTOCOL.md section 2.
 * The encoded form contains no 0x00, so 0x00 can delimit frames. Pure: compiles for the AVR and
 * for the host. Neither function writes the 0x00 delimiter. */
#ifndef COBS_H
#define COBS_H

#include <stddef.h>
#include <stdint.h>

/* Longest encoding of `len` bytes: one code byte per started run of 254 plus the leading one. */
#define COBS_MAX_ENCODED(len) ((len) + (len) / 254u + 1u)

/* Encodes `len` bytes of `in` into `out` (room for COBS_MAX_ENCODED(len)); returns the encoded
 * length. */
size_t cobs_encode(const uint8_t *in, size_t len, uint8_t *out);

/* Decodes `len` encoded bytes (no delimiter) into `out` (room for `cap` bytes). Returns the decoded
 * length, or -1 when the input is not valid COBS (a zero byte, a run that overruns the input) or
 * does not fit in `cap`. With `out` NULL it only validates and returns the decoded length. */
int cobs_decode(const uint8_t *in, size_t len, uint8_t *out, size_t cap);

#endif
