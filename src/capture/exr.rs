//! Linear images to and from OpenEXR bytes in memory. The session encodes in memory so that it can
//! checksum exactly the bytes it writes, then writes them atomically (see `session`).
//! 32-bit float RGB, RLE compression (lossless and fast).

use exr::prelude::*;
use std::io::Cursor;

use crate::render::image::LinearImage;

/// Encodes an image as OpenEXR.
pub fn encode_exr(img: &LinearImage) -> std::result::Result<Vec<u8>, String> {
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let [r, g, b] = img.get(x, y);
        (r, g, b)
    });
    let image = Image::from_channels((img.width(), img.height()), channels);
    let mut buf = Cursor::new(Vec::new());
    image
        .write()
        .non_parallel()
        .to_buffered(&mut buf)
        .map_err(|e| e.to_string())?;
    Ok(buf.into_inner())
}

/// Decodes OpenEXR bytes with R, G, B channels.
pub fn decode_exr(bytes: &[u8]) -> std::result::Result<LinearImage, String> {
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgb_channels(
            |size, _| LinearImage::new(size.width(), size.height()),
            |img: &mut LinearImage, Vec2(x, y), (r, g, b): (f32, f32, f32)| {
                img.set(x, y, [r, g, b])
            },
        )
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| e.to_string())?;
    Ok(image.layer_data.channel_data.pixels)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip_is_exact() {
        let mut img = LinearImage::new(7, 5);
        for y in 0..5 {
            for x in 0..7 {
                img.set(
                    x,
                    y,
                    [x as f32 * 0.1, y as f32 * 3.5, 1e-6 + (x * y) as f32],
                );
            }
        }
        let bytes = encode_exr(&img).unwrap();
        let back = decode_exr(&bytes).unwrap();
        assert_eq!(back, img);
        assert!(decode_exr(b"not an exr").is_err());
    }
}
