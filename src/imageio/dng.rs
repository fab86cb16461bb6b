//! A minimal uncompressed Bayer DNG writer (RGGB, 16 bit): enough for rawloader, and for tests
//! and benchmarks that need a real RAW file without a camera. Not a general DNG writer: no
//! colour matrices, no compression, no previews.
//!
//! Encoding of a linear image ([`dng_from_image`]): radiance `v` in channel `c` becomes the code
//! `black + clamp(v / full_scale * as_shot_neutral[c], 0, 1) * (white - black)` at the RGGB
//! photosites of that colour, so that `imageio::raw` (white balance = 1 / AsShotNeutral,
//! normalised to green) reads back `v / full_scale` when `as_shot_neutral[1] == 1`, to within
//! the demosaic's interpolation and a code's rounding. Pure: returns bytes.

use crate::render::image::LinearImage;

/// How [`dng_from_image`] turns radiance into sensor codes (see the module header).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BayerEncoding {
    pub black: u16,
    pub white: u16,
    /// The camera's response to grey, per channel (DNG AsShotNeutral); green = 1.
    pub as_shot_neutral: [f64; 3],
    /// Radiance that reaches the white level in green.
    pub full_scale: f32,
}

/// The RGGB colour (0 red, 1 green, 2 blue) of photosite (x, y).
pub fn rggb_colour(x: usize, y: usize) -> usize {
    match (y % 2, x % 2) {
        (0, 0) => 0,
        (1, 1) => 2,
        _ => 1,
    }
}

/// Mosaics `img` through the encoding and writes it as a minimal DNG.
pub fn dng_from_image(img: &LinearImage, enc: &BayerEncoding) -> Vec<u8> {
    let (w, h) = (img.width(), img.height());
    let range = f64::from(enc.white.saturating_sub(enc.black));
    let samples: Vec<u16> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let c = rggb_colour(x, y);
            let v = f64::from(img.get(x, y)[c]) / f64::from(enc.full_scale);
            let sensor = (v * enc.as_shot_neutral[c]).clamp(0.0, 1.0);
            (f64::from(enc.black) + sensor * range).round() as u16
        })
        .collect();
    write_minimal_dng(w, h, &samples, enc.black, enc.white, enc.as_shot_neutral)
}

/// Writes a minimal uncompressed Bayer DNG (RGGB, 16 bit) of `width x height` codes, row by
/// row, with one black and one white level and the as-shot neutral.
pub fn write_minimal_dng(
    width: usize,
    height: usize,
    samples: &[u16],
    black: u16,
    white: u16,
    as_shot_neutral: [f64; 3],
) -> Vec<u8> {
    // TIFF types: 1 BYTE, 2 ASCII, 3 SHORT, 4 LONG, 5 RATIONAL.
    struct Entry {
        tag: u16,
        typ: u16,
        count: u32,
        data: Vec<u8>,
    }
    let short = |tag, v: &[u16]| Entry {
        tag,
        typ: 3,
        count: v.len() as u32,
        data: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
    };
    let long = |tag, v: &[u32]| Entry {
        tag,
        typ: 4,
        count: v.len() as u32,
        data: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
    };
    let bytes = |tag, v: &[u8]| Entry {
        tag,
        typ: 1,
        count: v.len() as u32,
        data: v.to_vec(),
    };
    let ascii = |tag, s: &str| {
        let mut d = s.as_bytes().to_vec();
        d.push(0);
        Entry {
            tag,
            typ: 2,
            count: d.len() as u32,
            data: d,
        }
    };
    let rational = |tag, v: &[f64]| Entry {
        tag,
        typ: 5,
        count: v.len() as u32,
        data: v
            .iter()
            .flat_map(|x| {
                let den = 1_000_000u32;
                let num = (x * den as f64).round() as u32;
                num.to_le_bytes().into_iter().chain(den.to_le_bytes())
            })
            .collect(),
    };
    let pixel_bytes: Vec<u8> = samples.iter().flat_map(|x| x.to_le_bytes()).collect();
    let mut entries = vec![
        long(254, &[0]),
        long(256, &[width as u32]),
        long(257, &[height as u32]),
        short(258, &[16]),
        short(259, &[1]),
        short(262, &[32803]),
        ascii(271, "brdf-rig"),
        ascii(272, "test sensor"),
        long(273, &[0]), // strip offset, patched below
        short(277, &[1]),
        long(278, &[height as u32]),
        long(279, &[pixel_bytes.len() as u32]),
        short(33421, &[2, 2]),
        bytes(33422, &[0, 1, 1, 2]),
        bytes(50706, &[1, 4, 0, 0]),
        short(50714, &[black]),
        short(50717, &[white]),
        rational(50728, &as_shot_neutral),
    ];
    entries.sort_by_key(|e| e.tag);
    let ifd_offset = 8u32;
    let ifd_len = 2 + entries.len() as u32 * 12 + 4;
    let mut extra_offset = ifd_offset + ifd_len;
    let mut extra = Vec::new();
    let mut ifd = Vec::new();
    ifd.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    // Out-of-line values first, then the pixels; compute the pixel offset up front.
    let out_of_line: u32 = entries
        .iter()
        .filter(|e| e.data.len() > 4)
        .map(|e| e.data.len().next_multiple_of(2) as u32)
        .sum();
    let strip_offset = extra_offset + out_of_line;
    for e in &mut entries {
        if e.tag == 273 {
            e.data = strip_offset.to_le_bytes().to_vec();
        }
        ifd.extend_from_slice(&e.tag.to_le_bytes());
        ifd.extend_from_slice(&e.typ.to_le_bytes());
        ifd.extend_from_slice(&e.count.to_le_bytes());
        if e.data.len() <= 4 {
            let mut v = e.data.clone();
            v.resize(4, 0);
            ifd.extend_from_slice(&v);
        } else {
            ifd.extend_from_slice(&extra_offset.to_le_bytes());
            extra.extend_from_slice(&e.data);
            if e.data.len() % 2 == 1 {
                extra.push(0);
            }
            extra_offset += e.data.len().next_multiple_of(2) as u32;
        }
    }
    ifd.extend_from_slice(&0u32.to_le_bytes());
    let mut out = Vec::new();
    out.extend_from_slice(b"II");
    out.extend_from_slice(&42u16.to_le_bytes());
    out.extend_from_slice(&ifd_offset.to_le_bytes());
    out.extend_from_slice(&ifd);
    out.extend_from_slice(&extra);
    out.extend_from_slice(&pixel_bytes);
    out
}
