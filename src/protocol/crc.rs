//! CRC-16/CCITT-FALSE (a.k.a. CRC-16/IBM-3740): polynomial 0x1021, init 0xFFFF, no reflection,
//! no final xor. Check value: `crc16(b"123456789") == 0x29B1` (PROTOCOL.md section 2).
//!
//! Pure: no I/O. The frame layer appends the CRC little-endian after the payload.

use crc::{CRC_16_IBM_3740, Crc};

const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// The CRC of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    CRC16.checksum(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bitwise reference implementation, independent of the `crc` crate's tables.
    fn crc16_bitwise(data: &[u8]) -> u16 {
        let mut crc: u16 = 0xFFFF;
        for &b in data {
            crc ^= (b as u16) << 8;
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 {
                    (crc << 1) ^ 0x1021
                } else {
                    crc << 1
                };
            }
        }
        crc
    }

    #[test]
    fn check_value_matches_the_spec() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc16_bitwise(b"123456789"), 0x29B1);
    }

    #[test]
    fn empty_input_is_the_init_value() {
        assert_eq!(crc16(&[]), 0xFFFF);
    }

    #[test]
    fn table_and_bitwise_agree() {
        let data: Vec<u8> = (0..=255u8).collect();
        for n in [1, 2, 3, 17, 60, 256] {
            assert_eq!(crc16(&data[..n]), crc16_bitwise(&data[..n]), "n = {n}");
        }
    }
}
