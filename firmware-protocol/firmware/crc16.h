/* CRC-16/CCITT-FALSE (a.k.a. CRC-16/IBM-3740): poly 0x1021, init 0xFFFF, no reflection, no final
 * xor. PROTOCOL.md section 2. Pure: compiles for the AVR and for the host. */
#ifndef CRC16_H
#define CRC16_H

#include <stddef.h>
#include <stdint.h>

#define CRC16_INIT 0xFFFFu

/* Folds one byte into a running CRC (start from CRC16_INIT). */
uint16_t crc16_update(uint16_t crc, uint8_t byte);

/* CRC of a whole buffer. crc16("123456789") == 0x29B1. */
uint16_t crc16(const uint8_t *data, size_t len);

#endif
