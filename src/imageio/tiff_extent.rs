//! Does a TIFF-structured file hold all the data its directories point to? Most camera RAW
//! formats (DNG, CR2, NEF, ARW, ORF, PEF, RW2, ...) are TIFF inside, and a file cut short (an
//! interrupted copy or download) can still decode: rawloader's uncompressed decoders stop at the
//! end of the data and leave the missing rows zero. This check finds that before decoding.
//!
//! It walks the directory chain and the SubIFDs (tag 330, where DNG and NEF keep the raw image),
//! and checks that every directory, every out-of-line value it reads and every strip or tile
//! (offsets 273/324 with byte counts 279/325) ends inside the file. Classic TIFF only, in either
//! byte order, with the magic numbers of TIFF (42), Panasonic RW2 (0x55) and Olympus ORF
//! (0x4f52, 0x5352); other files (RAF, CRW, MRW, BigTIFF) are not checked. Written here rather
//! than with the `tiff` crate, whose decoder insists on understanding the first image (it refuses
//! a CFA photometric interpretation) where this needs only the directory structure. Pure: bytes
//! in, a message out.

/// At most this many directories are visited (a loop in a corrupt file ends here).
const MAX_DIRECTORIES: usize = 64;

const STRIP_OFFSETS: usize = 273;
const STRIP_BYTE_COUNTS: usize = 279;
const TILE_OFFSETS: usize = 324;
const TILE_BYTE_COUNTS: usize = 325;
const SUB_IFDS: usize = 330;

/// A part of the file (`what`: a directory, the values of a tag, a strip or tile, with its
/// byte offsets) that ends beyond the file's `len` bytes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{what} ends beyond the file's {len} bytes: the file is truncated or corrupt")]
pub struct Truncated {
    pub what: String,
    pub len: usize,
}

/// `Err(what)` when a directory, a value or a data chunk of the file ends beyond its last byte;
/// `Ok(())` when all lie inside, or the file is not classic TIFF.
pub fn check(bytes: &[u8]) -> Result<(), Truncated> {
    let big_endian = match bytes.get(..2) {
        Some(b"II") => false,
        Some(b"MM") => true,
        _ => return Ok(()),
    };
    // The unsigned integer of `n` bytes at `at`, in the file's byte order.
    let uint_at = |at: usize, n: usize| -> Option<usize> {
        let b = bytes.get(at..at.checked_add(n)?)?;
        let digits = |acc: usize, &x: &u8| (acc << 8) | usize::from(x);
        Some(if big_endian {
            b.iter().fold(0, digits)
        } else {
            b.iter().rev().fold(0, digits)
        })
    };
    let u16_at = |at: usize| uint_at(at, 2);
    let u32_at = |at: usize| uint_at(at, 4);
    if !matches!(u16_at(2), Some(42 | 0x55 | 0x4f52 | 0x5352)) {
        return Ok(());
    }
    let len = bytes.len();
    let short = |what: String| Truncated { what, len };
    let first = u32_at(4).ok_or_else(|| short("the header".into()))?;
    let mut queue = vec![first];
    let mut seen = Vec::new();
    while let Some(ifd) = queue.pop() {
        if ifd == 0 || seen.contains(&ifd) {
            continue;
        }
        if seen.len() >= MAX_DIRECTORIES {
            break;
        }
        seen.push(ifd);
        let directory = || short(format!("the directory at byte {ifd}"));
        let n = u16_at(ifd).ok_or_else(directory)?;
        let entries = ifd + 2;
        let next = u32_at(entries + 12 * n).ok_or_else(directory)?;
        queue.push(next);
        // The unsigned values of an entry (SHORT, LONG or IFD), read where they are stored.
        let values = |at: usize| -> Result<Vec<usize>, Truncated> {
            let (Some(tag), Some(typ), Some(count)) = (u16_at(at), u16_at(at + 2), u32_at(at + 4))
            else {
                return Err(directory());
            };
            let size = match typ {
                3 => 2,
                4 | 13 => 4,
                _ => return Ok(Vec::new()),
            };
            let total = count.saturating_mul(size);
            let start = if total <= 4 {
                at + 8
            } else {
                u32_at(at + 8).ok_or_else(directory)?
            };
            (0..count)
                .map(|i| {
                    uint_at(start + size * i, size)
                        .ok_or_else(|| short(format!("the values of tag {tag} at byte {start}")))
                })
                .collect()
        };
        let mut found = [const { Vec::new() }; 4];
        for i in 0..n {
            let at = entries + 12 * i;
            let tag = u16_at(at).ok_or_else(directory)?;
            let slot = match tag {
                STRIP_OFFSETS => 0,
                STRIP_BYTE_COUNTS => 1,
                TILE_OFFSETS => 2,
                TILE_BYTE_COUNTS => 3,
                SUB_IFDS => {
                    queue.extend(values(at)?);
                    continue;
                }
                _ => continue,
            };
            found[slot] = values(at)?;
        }
        for (kind, offsets, counts) in [
            ("strip", &found[0], &found[1]),
            ("tile", &found[2], &found[3]),
        ] {
            for (k, (&offset, &count)) in offsets.iter().zip(counts.iter()).enumerate() {
                if offset.saturating_add(count) > len {
                    return Err(short(format!(
                        "{kind} {k} of the directory at byte {ifd} (bytes {offset} to {})",
                        offset.saturating_add(count)
                    )));
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use crate::imageio::dng::write_minimal_dng;

    #[test]
    fn a_whole_file_passes_and_every_cut_fails() {
        let dng = write_minimal_dng(6, 4, &[1000; 24], 0, 4000, [1.0, 1.0, 1.0]);
        assert_eq!(check(&dng), Ok(()));
        // cut in the header, the directory, the values after it and the pixels
        for cut in [5, 7, 20, 200, 240, dng.len() - 48, dng.len() - 1] {
            let e = check(&dng[..cut]).unwrap_err().to_string();
            assert!(e.contains("truncated"), "cut at {cut}: {e}");
        }
        // the same bytes big-endian: a strip count past the end is found in that order too
        let mut mm = b"MM\0\x2a\0\0\0\x08".to_vec();
        mm.extend_from_slice(&[0, 2]); // two entries
        mm.extend_from_slice(&[1, 17, 0, 4, 0, 0, 0, 1, 0, 0, 0, 30]); // strip at byte 30
        mm.extend_from_slice(&[1, 23, 0, 4, 0, 0, 0, 1, 0, 0, 0, 10]); // of 10 bytes
        mm.extend_from_slice(&[0, 0, 0, 0]);
        mm.resize(40, 0);
        assert_eq!(check(&mm), Ok(()));
        assert!(
            check(&mm[..39])
                .unwrap_err()
                .to_string()
                .contains("strip 0")
        );
        // not TIFF: not checked
        assert_eq!(check(b"FUJIFILMCCD-RAW"), Ok(()));
        assert_eq!(check(b""), Ok(()));
    }
}
