//! Fewer observations where pixels repeat each other, per light image, in two steps:
//!
//! 1. A lattice: above `reference_pixels` (about what the method needs: 1920x1440 by default)
//!    only every `stride`-th pixel along each axis is looked at, `stride = floor(sqrt(pixels /
//!    reference_pixels))` (24 MP: 2). A photogrammetry mesh has no detail at that scale (a
//!    face of the 70k-face Bunny spans ~8x8 pixels of a 24 MP view), so the skipped pixels
//!    repeat their neighbours' directions and curvature.
//! 2. Cells: the pixels that pass every other test are grouped by (MERL bin, image region: a
//!    grid of `regions` x `regions` cells over the image); when there are more than `budget`,
//!    each cell keeps at most `c` of them, `c` the largest count (up to `cap`) that keeps the
//!    total within `budget` (water filling: the most repeated cells are thinned first, a bin
//!    seen once keeps its pixel). When even one per cell is over budget, a uniform random
//!    `budget` of the cells keep one each (neighbouring bins then stand for each other).
//!
//! Which pixels of a cell are kept is uniform at random but reproducible: the smallest values
//! of a fixed hash of (image, pixel) ([`priority`]). Why: a 24-megapixel photograph shows each
//! MERL bin of a smooth object on hundreds of neighbouring pixels with the same directions and
//! nearly the same value; the core's cost grows with the number of pixels, its information does
//! not. Below the budget (the 640x480 benchmark's busiest view has 38k pixels) only cells over
//! `cap` are thinned, and the set is nearly the full one. Every image keeps pixels, so the
//! held-out validation and the eq. 3 choice still see every image. Pure.

use super::observation::Observation;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// How far to thin the observations of one light image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Reduction {
    /// Above this many pixels an image is looked at on a lattice (step 1 of the header).
    pub reference_pixels: usize,
    /// The image is cut into `regions` x `regions` cells.
    pub regions: u32,
    /// Pixels kept at most per (MERL bin, region).
    pub cap: usize,
    /// Pixels kept at most per image.
    pub budget: usize,
}

impl Default for Reduction {
    fn default() -> Self {
        Self {
            reference_pixels: 1920 * 1440,
            regions: 4,
            cap: 16,
            budget: 40_000,
        }
    }
}

impl Reduction {
    /// The cell of pixel `(x, y)` of a `width` x `height` image.
    pub fn region(&self, x: u32, y: u32, width: usize, height: usize) -> u32 {
        let r = u64::from(self.regions.max(1));
        let cx = (u64::from(x) * r / width.max(1) as u64).min(r - 1);
        let cy = (u64::from(y) * r / height.max(1) as u64).min(r - 1);
        (cy * r + cx) as u32
    }

    /// The lattice step of a `width` x `height` image (1: every pixel).
    pub fn stride(&self, width: usize, height: usize) -> usize {
        let ratio = (width * height) as f64 / self.reference_pixels.max(1) as f64;
        (ratio.sqrt().floor() as usize).max(1)
    }

    /// Whether pixel `(x, y)` lies on the lattice of step `stride` (the middle of each block).
    pub fn on_lattice(stride: usize, x: usize, y: usize) -> bool {
        stride <= 1 || (x % stride == stride / 2 && y % stride == stride / 2)
    }
}

/// The random but reproducible rank of pixel `(x, y)` of image `image` (SplitMix64 finaliser).
pub fn priority(image: usize, x: u32, y: u32) -> u64 {
    let mut z = (image as u64)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((u64::from(y) << 32) | u64::from(x));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A pixel offered to the cells: its priority and position.
pub type Entry = (u64, u32, u32);

/// The candidates of one image, by cell, each keeping its `cap` smallest priorities.
#[derive(Debug, Default)]
pub struct Cells {
    cap: usize,
    cells: HashMap<(usize, u32), Vec<Entry>>,
    offered: usize,
}

impl Cells {
    pub fn new(cap: usize) -> Self {
        Self {
            cap: cap.max(1),
            cells: HashMap::new(),
            offered: 0,
        }
    }

    /// Offers a pixel of cell `key` (MERL bin, region).
    pub fn offer(&mut self, key: (usize, u32), e: Entry) {
        self.offered += 1;
        let cap = self.cap;
        let cell = self.cells.entry(key).or_default();
        if cell.len() < cap {
            cell.push(e);
        } else if let Some(worst) = cell.iter_mut().max_by_key(|w| w.0)
            && worst.0 > e.0
        {
            *worst = e;
        }
    }

    /// Merges the cells of another part of the same image.
    pub fn merge(&mut self, other: Cells) {
        self.offered += other.offered;
        for (key, mut es) in other.cells {
            let cell = self.cells.entry(key).or_default();
            cell.append(&mut es);
            if cell.len() > self.cap {
                cell.sort_unstable();
                cell.truncate(self.cap);
            }
        }
    }

    /// Pixels offered so far.
    pub fn offered(&self) -> usize {
        self.offered
    }

    /// The kept pixels `(x, y)` within `budget` (module header, step 2), in image order.
    pub fn select(mut self, budget: usize) -> Vec<(u32, u32)> {
        let total = |c: usize, cells: &HashMap<(usize, u32), Vec<Entry>>| -> usize {
            cells.values().map(|v| v.len().min(c)).sum()
        };
        let budget = budget.max(1);
        let mut out: Vec<Entry> = if total(1, &self.cells) > budget {
            let mut firsts: Vec<Entry> = self
                .cells
                .into_values()
                .filter_map(|v| v.into_iter().min())
                .collect();
            firsts.sort_unstable();
            firsts.truncate(budget);
            firsts
        } else {
            // the largest c in [1, cap] within budget (total is monotone in c)
            let (mut lo, mut hi) = (1, self.cap);
            while lo < hi {
                let mid = (lo + hi).div_ceil(2);
                if total(mid, &self.cells) <= budget {
                    lo = mid;
                } else {
                    hi = mid - 1;
                }
            }
            self.cells
                .values_mut()
                .flat_map(|v| {
                    v.sort_unstable();
                    v.truncate(lo);
                    v.drain(..)
                })
                .collect()
        };
        let mut px: Vec<(u32, u32)> = out.drain(..).map(|(_, x, y)| (x, y)).collect();
        px.sort_unstable_by_key(|&(x, y)| (y, x));
        px
    }
}

/// Thins the observations of one `width` x `height` light image (step 2 of the header only:
/// they are already made); returns the kept ones (image order) and how many were dropped.
pub fn reduce(
    obs: Vec<Observation>,
    width: usize,
    height: usize,
    r: &Reduction,
) -> (Vec<Observation>, usize) {
    let n = obs.len();
    let mut cells = Cells::new(r.cap);
    for o in &obs {
        let key = (o.bin, r.region(o.x, o.y, width, height));
        cells.offer(key, (priority(o.image, o.x, o.y), o.x, o.y));
    }
    let kept: std::collections::HashSet<(u32, u32)> = cells.select(r.budget).into_iter().collect();
    let mut out: Vec<Observation> = obs
        .into_iter()
        .filter(|o| kept.contains(&(o.x, o.y)))
        .collect();
    out.sort_by_key(|o| (o.y, o.x));
    let dropped = n - out.len();
    (out, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::observation::Seen;
    use nalgebra::Vector3;

    fn obs(x: u32, y: u32, light: Vector3<f64>) -> Observation {
        Observation::new(
            Seen::pixel(0, x, y, Vector3::z()),
            light,
            Vector3::z(),
            [1.0; 3],
            [1.0; 3],
        )
        .unwrap()
    }

    #[test]
    fn cells_are_thinned_most_repeated_first_within_the_budget() {
        let r = Reduction {
            reference_pixels: 1 << 20,
            regions: 2,
            cap: 3,
            budget: 1000,
        };
        let a = Vector3::new(0.3, 0.0, 1.0).normalize();
        let b = Vector3::new(0.0, 0.7, 1.0).normalize();
        // 20 x 20 image: bin of `a` everywhere but at (3, 3), which shows bin `b`
        let mut all: Vec<Observation> = (0..20)
            .flat_map(|y| (0..20).map(move |x| (x, y)))
            .filter(|&p| p != (3, 3))
            .map(|(x, y)| obs(x, y, a))
            .collect();
        all.push(obs(3, 3, b));
        let (kept, dropped) = reduce(all.clone(), 20, 20, &r);
        // 4 cells x cap 3 of bin a, plus the lone b
        assert_eq!(kept.len(), 13);
        assert_eq!(dropped, all.len() - 13);
        assert!(kept.iter().any(|o| o.bin == obs(3, 3, b).bin));
        // within a cell: the 3 smallest priorities
        let prios = |v: &[Observation]| {
            let mut p: Vec<u64> = v
                .iter()
                .filter(|o| o.bin == obs(0, 0, a).bin && r.region(o.x, o.y, 20, 20) == 0)
                .map(|o| priority(0, o.x, o.y))
                .collect();
            p.sort_unstable();
            p
        };
        assert_eq!(prios(&kept), prios(&all)[..3]);
        assert!(
            kept.windows(2)
                .all(|w| (w[0].y, w[0].x) <= (w[1].y, w[1].x))
        );
        // a budget of 9: water filling gives c = 2 (4 x 2 + 1), the lone b kept
        let (kept, _) = reduce(all.clone(), 20, 20, &Reduction { budget: 9, ..r });
        assert_eq!(kept.len(), 9);
        assert!(kept.iter().any(|o| o.bin == obs(3, 3, b).bin));
        // a budget below the number of cells: one pixel in each of `budget` cells
        let (kept, _) = reduce(all.clone(), 20, 20, &Reduction { budget: 3, ..r });
        assert_eq!(kept.len(), 3);
        // a large cap and budget keep everything
        let big = Reduction { cap: 1000, ..r };
        let (kept, dropped) = reduce(all.clone(), 20, 20, &big);
        assert_eq!((kept.len(), dropped), (all.len(), 0));
        // the lattice: 24 MP against a 1920x1440 reference steps by 2
        let d = Reduction::default();
        assert_eq!(d.stride(6000, 4000), 2);
        assert_eq!(d.stride(640, 480), 1);
        assert!(Reduction::on_lattice(2, 1, 3) && !Reduction::on_lattice(2, 0, 3));
    }
}
