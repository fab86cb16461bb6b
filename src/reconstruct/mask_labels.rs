//! Material labels given by the job's label masks (`light_image[i].labels`, issue #17): one
//! light image's label mask decoded and checked, the votes its pixels cast for the mesh's
//! vertices, and the per-vertex labels those votes fix for the segmentation
//! (`segment::segment_with_labels`), which labels only the vertices left free.
//!
//! Conventions: a label mask has the size of its light image and holds one whole number per
//! pixel: 0 gives no label (the automatic segmentation decides there), `v` in 1..=255 says
//! "material `v`". Every labelled pixel where the mesh is seen (the face the view's z-buffer
//! names) and that the job's `mask` keeps votes for the three corners of that face, whether or
//! not the pixel is observed: a label is a statement about the surface, so a shadowed,
//! saturated or thinned-out pixel's label counts too, and all three corners, so that a mesh
//! finer than the pixels is still covered where the labels are drawn. A vertex takes the
//! label most of its votes give; a tie between two labels fixes nothing (the masks disagree
//! there, so the segmentation decides). The labels that fix at least one vertex become the
//! given materials, numbered densely in the order of their mask values (mask values 2 and 5
//! are materials 0 and 1 of the segmentation).
//!
//! Pure: decodes an image already in memory, reads the view's faces through a function;
//! reading the files and rasterising are `prepare`'s.

use crate::geometry::mesh::Mesh;
use image::DynamicImage;
use std::collections::{BTreeMap, HashMap};

/// The largest label a mask may hold (`material_map.ply` stores a label in one byte, and 255
/// materials are already far more than a core per material can fit in reasonable time).
pub const MAX_MASK_LABEL: u32 = 255;

/// What is wrong with a label mask (`prepare` names the job, the field and the file).
#[derive(Debug, thiserror::Error)]
pub enum LabelMaskError {
    #[error(transparent)]
    Read(Box<image::ImageError>),
    #[error("is {got_w}x{got_h} but its image is {want_w}x{want_h}")]
    Size {
        got_w: usize,
        got_h: usize,
        want_w: usize,
        want_h: usize,
    },
    #[error(
        "is a JPEG: lossy compression changes the values near every edge; save label masks as \
         PNG (8- or 16-bit grey, 0 = no label, v = material v)"
    )]
    Lossy,
    #[error(
        "holds samples that are not 8- or 16-bit whole numbers ({colour}): save label masks as \
         PNG (8- or 16-bit grey, 0 = no label, v = material v)"
    )]
    NotInteger { colour: String },
    #[error(
        "pixel ({x}, {y}) is ({r}, {g}, {b}), not grey: a label mask holds one value per pixel \
         (0 = no label, v = material v)"
    )]
    Colour {
        x: usize,
        y: usize,
        r: u16,
        g: u16,
        b: u16,
    },
    #[error("pixel ({x}, {y}) has label {value}: labels are 1 to {MAX_MASK_LABEL} (0 = no label)")]
    TooLarge { x: usize, y: usize, value: u16 },
}

/// One light image's label mask: per pixel, row-major, 0 (no label) or a material's label.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LabelImage {
    width: usize,
    height: usize,
    values: Vec<u8>,
}

impl LabelImage {
    /// Decodes and checks a label mask for a light image of `width` x `height`: grey (or
    /// colour with equal channels; alpha ignored), 8- or 16-bit, every value at most
    /// [`MAX_MASK_LABEL`]. A 16-bit value is the stored code itself, not scaled.
    pub fn decode(img: &DynamicImage, width: usize, height: usize) -> Result<Self, LabelMaskError> {
        let (w, h) = (img.width() as usize, img.height() as usize);
        if (w, h) != (width, height) {
            return Err(LabelMaskError::Size {
                got_w: w,
                got_h: h,
                want_w: width,
                want_h: height,
            });
        }
        let grey: Vec<u16> = match img {
            DynamicImage::ImageLuma8(b) => b.as_raw().iter().map(|&v| u16::from(v)).collect(),
            DynamicImage::ImageLuma16(b) => b.as_raw().clone(),
            _ => {
                let rgb: Vec<[u16; 3]> = match img.color() {
                    image::ColorType::La8 | image::ColorType::Rgb8 | image::ColorType::Rgba8 => {
                        img.to_rgb8().pixels().map(|p| p.0.map(u16::from)).collect()
                    }
                    image::ColorType::La16 | image::ColorType::Rgb16 | image::ColorType::Rgba16 => {
                        img.to_rgb16().pixels().map(|p| p.0).collect()
                    }
                    other => {
                        return Err(LabelMaskError::NotInteger {
                            colour: format!("{other:?}"),
                        });
                    }
                };
                let mut grey = Vec::with_capacity(rgb.len());
                for (i, [r, g, b]) in rgb.into_iter().enumerate() {
                    if r != g || g != b {
                        let (x, y) = (i % w, i / w);
                        return Err(LabelMaskError::Colour { x, y, r, g, b });
                    }
                    grey.push(r);
                }
                grey
            }
        };
        let mut values = Vec::with_capacity(grey.len());
        for (i, v) in grey.into_iter().enumerate() {
            match u8::try_from(v) {
                Ok(l) => values.push(l),
                Err(_) => {
                    let (x, y) = (i % w, i / w);
                    return Err(LabelMaskError::TooLarge { x, y, value: v });
                }
            }
        }
        Ok(Self {
            width: w,
            height: h,
            values,
        })
    }

    /// The label at pixel (x, y): `None` for 0 (no label) and outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<u32> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let v = *self.values.get(y * self.width + x)?;
        (v > 0).then_some(u32::from(v))
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }
}

/// The votes of the labelled observed pixels of every view, per (vertex, label).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LabelVotes {
    counts: BTreeMap<(u32, u32), u32>,
}

/// The vertex labels the masks fix.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FixedLabels {
    /// Per mesh vertex: its given material (an index into `mask_labels`), when the masks fix it.
    pub vertex: Vec<Option<u32>>,
    /// Per given material, the value drawn in the masks, ascending.
    pub mask_labels: Vec<u32>,
    /// Vertices whose votes tied between labels: left to the segmentation.
    pub ties: usize,
}

impl FixedLabels {
    /// Vertices fixed to given material `m`.
    pub fn vertices_of(&self, m: u32) -> usize {
        self.vertex.iter().filter(|&&l| l == Some(m)).count()
    }
}

impl LabelVotes {
    /// No labelled pixel was observed.
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// The votes of one view: every pixel with a label in `labels`, where `face_at(x, y)`
    /// names the mesh face the pixel sees and `mask` (row-major, the job's pixel mask) keeps
    /// it, votes for the three corners of that face.
    pub fn add_view(
        &mut self,
        mesh: &Mesh,
        labels: &LabelImage,
        mask: Option<&[bool]>,
        face_at: impl Fn(usize, usize) -> Option<u32>,
    ) {
        let mut per_face: HashMap<(u32, u32), u32> = HashMap::new();
        for y in 0..labels.height {
            for x in 0..labels.width {
                let Some(label) = labels.get(x, y) else {
                    continue;
                };
                let kept =
                    mask.is_none_or(|m| m.get(y * labels.width + x).copied().unwrap_or(false));
                if let (true, Some(face)) = (kept, face_at(x, y)) {
                    *per_face.entry((face, label)).or_insert(0) += 1;
                }
            }
        }
        for ((face, label), n) in per_face {
            let Some(corners) = mesh.faces().get(face as usize) else {
                continue;
            };
            for &v in corners {
                *self.counts.entry((v, label)).or_insert(0) += n;
            }
        }
    }

    /// Each vertex's majority label, for a mesh of `vertices` vertices; `None` when no vertex
    /// is fixed (no vote, or only ties).
    pub fn fixed(&self, vertices: usize) -> Option<FixedLabels> {
        if self.counts.is_empty() {
            return None;
        }
        let mut winner: Vec<Option<u32>> = vec![None; vertices];
        let mut ties = 0;
        let mut entries = self.counts.iter().peekable();
        while let Some((&(v, label), &n)) = entries.next() {
            // the entries of one vertex are consecutive (the map is ordered by vertex, then label)
            let (mut best, mut best_n, mut tied) = (label, n, false);
            while let Some((&(_, l), &m)) = entries.next_if(|((u, _), _)| *u == v) {
                if m > best_n {
                    (best, best_n, tied) = (l, m, false);
                } else if m == best_n {
                    tied = true;
                }
            }
            if tied {
                ties += 1;
            } else if let Some(w) = winner.get_mut(v as usize) {
                *w = Some(best);
            }
        }
        let mut mask_labels: Vec<u32> = winner.iter().flatten().copied().collect();
        mask_labels.sort_unstable();
        mask_labels.dedup();
        if mask_labels.is_empty() {
            return None;
        }
        let vertex = winner
            .iter()
            .map(|w| w.and_then(|l| mask_labels.binary_search(&l).ok().map(|i| i as u32)))
            .collect();
        Some(FixedLabels {
            vertex,
            mask_labels,
            ties,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{GrayImage, ImageBuffer, Luma, Rgb, RgbImage};
    use nalgebra::Point3;

    #[test]
    fn decodes_grey_8_and_16_bit_and_refuses_what_is_not_a_label() {
        let g8 = GrayImage::from_fn(3, 2, |x, y| Luma([(x + 3 * y) as u8]));
        let l = LabelImage::decode(&DynamicImage::ImageLuma8(g8), 3, 2).unwrap();
        assert_eq!(l.get(0, 0), None, "0 = no label");
        assert_eq!(l.get(2, 1), Some(5));
        assert_eq!(l.get(3, 0), None, "outside");
        // 16-bit: the code itself, not scaled to 8 bits
        let g16: ImageBuffer<Luma<u16>, Vec<u16>> =
            ImageBuffer::from_fn(2, 1, |x, _| Luma([x as u16 * 2]));
        let l = LabelImage::decode(&DynamicImage::ImageLuma16(g16.clone()), 2, 1).unwrap();
        assert_eq!(l.get(1, 0), Some(2));
        // grey drawn as RGB is accepted, colour is not
        let rgb = RgbImage::from_fn(2, 1, |x, _| Rgb([x as u8; 3]));
        let l = LabelImage::decode(&DynamicImage::ImageRgb8(rgb), 2, 1).unwrap();
        assert_eq!(l.get(1, 0), Some(1));
        let colour = RgbImage::from_fn(2, 2, |x, y| Rgb([1, 1 + (x * y) as u8, 1]));
        let e = LabelImage::decode(&DynamicImage::ImageRgb8(colour), 2, 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("(1, 1)") && e.contains("not grey"), "{e}");
        let e = LabelImage::decode(&DynamicImage::ImageLuma16(g16), 3, 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("2x1") && e.contains("3x1"), "{e}");
        let big: ImageBuffer<Luma<u16>, Vec<u16>> =
            ImageBuffer::from_fn(2, 1, |x, _| Luma([x as u16 * 256]));
        let e = LabelImage::decode(&DynamicImage::ImageLuma16(big), 2, 1)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("(1, 0)") && e.contains("256") && e.contains("1 to 255"),
            "{e}"
        );
        let float = DynamicImage::ImageRgb32F(ImageBuffer::new(2, 1));
        let e = LabelImage::decode(&float, 2, 1).unwrap_err().to_string();
        assert!(e.contains("whole numbers"), "{e}");
    }

    /// Two triangles sharing an edge: vertices 0..4 at the corners of the unit square.
    fn square() -> Mesh {
        let p = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        Mesh::new(p, vec![[0, 1, 2], [0, 2, 3]], "square")
            .unwrap()
            .0
    }

    #[test]
    fn a_vertex_takes_the_majority_of_the_pixels_on_its_faces_and_ties_fix_nothing() {
        let mesh = square();
        // 6x1 pixels with labels 0, 5, 5, 2, 2, 9; pixels 0..3 see face 0, 3..5 face 1, 5 none
        let img = GrayImage::from_raw(6, 1, vec![0, 5, 5, 2, 2, 9]).unwrap();
        let labels = LabelImage::decode(&DynamicImage::ImageLuma8(img), 6, 1).unwrap();
        let face_at = |x: usize, _y: usize| match x {
            0..=2 => Some(0),
            3 | 4 => Some(1),
            _ => None,
        };
        let mut votes = LabelVotes::default();
        assert!(votes.is_empty());
        votes.add_view(&mesh, &labels, None, face_at);
        // face 0 [0, 1, 2]: two votes for 5; face 1 [0, 2, 3]: two for 2; pixel 5 sees nothing
        // vertex 0 and 2: 5 twice, 2 twice (a tie); vertex 1: 5; vertex 3: 2
        let fixed = votes.fixed(4).unwrap();
        assert_eq!(fixed.mask_labels, vec![2, 5]);
        assert_eq!(fixed.vertex, vec![None, Some(1), None, Some(0)]);
        assert_eq!(fixed.ties, 2);
        assert_eq!(fixed.vertices_of(0), 1);
        // the pixel mask removes pixel 4: face 1 has one vote left, still for 2
        let mut masked = LabelVotes::default();
        let mask = [true, true, true, true, false, true];
        masked.add_view(&mesh, &labels, Some(&mask), face_at);
        let fixed = masked.fixed(4).unwrap();
        assert_eq!(fixed.vertex, vec![Some(1), Some(1), Some(1), Some(0)]);
        // a second view adds its votes: vertex 3 now 2 twice
        masked.add_view(&mesh, &labels, Some(&mask), |x, _| (x == 3).then_some(1));
        assert_eq!(masked.fixed(4).unwrap().vertex[3], Some(0));
        // no labelled pixel: nothing fixed
        assert_eq!(LabelVotes::default().fixed(4), None);
    }
}
