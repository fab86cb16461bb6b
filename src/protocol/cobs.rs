//! Consistent Overhead Byte Stuffing (Cheshire & Baker 1999): turns any byte string into one
//! without zero bytes, so that a single `0x00` can end each frame on the wire.
//!
//! Pure: no I/O, no knowledge of frames or CRCs (that is `frame.rs`).

use super::error::CobsError;

/// Encodes `input`; the result contains no zero byte and does not include the final `0x00`.
pub fn encode(input: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(input.len() + input.len() / 254 + 2);
    let mut code_idx = 0;
    out.push(0);
    let mut code: u8 = 1;
    for &b in input {
        if b == 0 {
            out[code_idx] = code;
            code_idx = out.len();
            out.push(0);
            code = 1;
        } else {
            out.push(b);
            code += 1;
            if code == 0xFF {
                out[code_idx] = code;
                code_idx = out.len();
                out.push(0);
                code = 1;
            }
        }
    }
    out[code_idx] = code;
    out
}

/// Decodes a COBS block (without its final `0x00`).
pub fn decode(input: &[u8]) -> Result<Vec<u8>, CobsError> {
    let mut out = Vec::with_capacity(input.len());
    let mut i = 0;
    while i < input.len() {
        let code = input[i];
        if code == 0 {
            return Err(CobsError::ZeroByte { offset: i });
        }
        i += 1;
        let end = i + code as usize - 1;
        if end > input.len() {
            return Err(CobsError::Truncated {
                offset: i - 1,
                code,
                available: input.len() - i,
            });
        }
        if let Some(z) = input[i..end].iter().position(|&b| b == 0) {
            return Err(CobsError::ZeroByte { offset: i + z });
        }
        out.extend_from_slice(&input[i..end]);
        i = end;
        if code < 0xFF && i < input.len() {
            out.push(0);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Examples from the COBS literature (Wikipedia's table), checked by hand.
    #[test]
    fn known_encodings() {
        let cases: &[(&[u8], &[u8])] = &[
            (&[], &[0x01]),
            (&[0x00], &[0x01, 0x01]),
            (&[0x00, 0x00], &[0x01, 0x01, 0x01]),
            (&[0x00, 0x11, 0x00], &[0x01, 0x02, 0x11, 0x01]),
            (&[0x11, 0x22, 0x00, 0x33], &[0x03, 0x11, 0x22, 0x02, 0x33]),
            (&[0x11, 0x22, 0x33, 0x44], &[0x05, 0x11, 0x22, 0x33, 0x44]),
            (&[0x11, 0x00, 0x00, 0x00], &[0x02, 0x11, 0x01, 0x01, 0x01]),
        ];
        for (raw, enc) in cases {
            assert_eq!(encode(raw), *enc, "encode {raw:02x?}");
            assert_eq!(decode(enc).as_deref(), Ok(*raw), "decode {enc:02x?}");
        }
    }

    #[test]
    fn long_runs_use_0xff_blocks() {
        let raw: Vec<u8> = (1..=254u8).collect();
        let enc = encode(&raw);
        assert_eq!(enc[0], 0xFF);
        assert_eq!(enc.len(), 256);
        assert!(!enc.contains(&0));
        assert_eq!(decode(&enc), Ok(raw));
    }

    #[test]
    fn truncated_block_is_an_error() {
        assert!(matches!(
            decode(&[0x05, 0x11, 0x22]),
            Err(CobsError::Truncated { .. })
        ));
        assert!(matches!(
            decode(&[0x02, 0x00]),
            Err(CobsError::ZeroByte { .. })
        ));
    }
}
