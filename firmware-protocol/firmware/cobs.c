#include "cobs.h"

size_t cobs_encode(const uint8_t *in, size_t len, uint8_t *out)
{
    size_t code_at = 0; /* where the current run's code byte goes */
    size_t o = 1;
    uint8_t code = 1;
    for (size_t i = 0; i < len; i++) {
        if (in[i] == 0) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
        } else {
            out[o++] = in[i];
            code++;
            if (code == 0xFF) {
                /* A full run of 254 non-zero bytes carries no implied zero. */
                out[code_at] = code;
                code_at = o++;
                code = 1;
            }
        }
    }
    out[code_at] = code;
    return o;
}

int cobs_decode(const uint8_t *in, size_t len, uint8_t *out, size_t cap)
{
    size_t i = 0;
    size_t o = 0;
    while (i < len) {
        uint8_t code = in[i++];
        if (code == 0) {
            return -1;
        }
        for (uint8_t k = 1; k < code; k++) {
            if (i >= len || in[i] == 0 || (out && o >= cap)) {
                return -1;
            }
            if (out) {
                out[o] = in[i];
            }
            o++;
            i++;
        }
        /* Every run but a full one (0xFF) and the last one ends in an implied zero. */
        if (code != 0xFF && i < len) {
            if (out && o >= cap) {
                return -1;
            }
            if (out) {
                out[o] = 0;
            }
            o++;
        }
    }
    return (int)o;
}
