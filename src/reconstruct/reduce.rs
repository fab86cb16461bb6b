//! Fewer observations where pixels repeat each other: per light image, at most `cap` pixels
//! per (MERL bin, image region), drawn uniformly at random (a fixed hash of image and pixel, so
//! a run is reproducible) from the pixels that pass every other test.
//!
//! Why: a 24-megapixel photograph shows each MERL bin of a smooth object on hundreds of
//! neighbouring pixels with the same directions and nearly the same value; the core's cost grows
//! with the number of pixels, its information does not. Stratifying by bin keeps every bin
//! that any pixel saw (the angular coverage the basis fit and eq. 3 see is unchanged), and by
//! image region (a grid of `regions` x `regions` cells over the image) keeps pixels from every
//! part of the surface that shows the bin (positions, curvatures and normal errors differ there),
//! so the held-out validation still sees every image and every part of it. At the sizes the
//! tests and the study use (up to ~640x480) few cells hold more than `cap` pixels, and the set
//! is nearly the full one.
//!
//! The selection keeps the `cap` smallest priorities of each cell: a pixel enters while the
//! cell is not full or when its priority is below the cell's largest, which it evicts. A
//! caller can ask [`Reservoir::admits`] before paying for a test that only matters for kept
//! pixels (the shadow ray). Pure.

use super::observe::Observation;
use serde::Serialize;
use std::collections::HashMap;

/// How far to thin the observations of one light image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Reduction {
    /// The image is cut into `regions` x `regions` cells.
    pub regions: u32,
    /// Pixels kept per (MERL bin, cell).
    pub cap: usize,
}

impl Default for Reduction {
    fn default() -> Self {
        Self {
            regions: 16,
            cap: 8,
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

    /// The region row of image row `y` (bands of rows that share no cell).
    pub fn region_row(&self, y: usize, height: usize) -> usize {
        let r = self.regions.max(1) as usize;
        (y * r / height.max(1)).min(r - 1)
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

/// The kept pixels of some cells, as the scan goes.
pub struct Reservoir {
    cap: usize,
    cells: HashMap<(usize, u32), Vec<(u64, Observation)>>,
    /// Pixels let in and later pushed out by a smaller priority.
    evicted: usize,
}

impl Reservoir {
    pub fn new(cap: usize) -> Self {
        Self {
            cap: cap.max(1),
            cells: HashMap::new(),
            evicted: 0,
        }
    }

    /// Whether a pixel of cell `key` (bin, region) with `prio` would be kept now.
    pub fn admits(&self, key: (usize, u32), prio: u64) -> bool {
        match self.cells.get(&key) {
            None => true,
            Some(v) if v.len() < self.cap => true,
            Some(v) => v.iter().any(|(p, _)| *p > prio),
        }
    }

    /// Keeps `o` (call after [`Self::admits`] said yes), evicting the cell's largest priority
    /// when it is full.
    pub fn insert(&mut self, key: (usize, u32), prio: u64, o: Observation) {
        let cap = self.cap;
        let cell = self.cells.entry(key).or_default();
        if cell.len() < cap {
            cell.push((prio, o));
            return;
        }
        if let Some((i, _)) = cell
            .iter()
            .enumerate()
            .max_by_key(|(_, (p, _))| *p)
            .filter(|(_, (p, _))| *p > prio)
        {
            cell[i] = (prio, o);
            self.evicted += 1;
        }
    }

    /// Pixels let in and later evicted.
    pub fn evicted(&self) -> usize {
        self.evicted
    }

    /// The kept observations in image order (row, then column).
    pub fn into_observations(self) -> Vec<Observation> {
        let mut out: Vec<Observation> = self
            .cells
            .into_values()
            .flat_map(|c| c.into_iter().map(|(_, o)| o))
            .collect();
        out.sort_by_key(|o| (o.image, o.y, o.x));
        out
    }
}

/// Thins the observations of one `width` x `height` light image; returns the kept ones (image
/// order) and how many were dropped.
pub fn reduce(
    obs: Vec<Observation>,
    width: usize,
    height: usize,
    r: &Reduction,
) -> (Vec<Observation>, usize) {
    let n = obs.len();
    let mut res = Reservoir::new(r.cap);
    for o in obs {
        let key = (o.bin, r.region(o.x, o.y, width, height));
        let prio = priority(o.image, o.x, o.y);
        if res.admits(key, prio) {
            res.insert(key, prio, o);
        }
    }
    let kept = res.into_observations();
    let dropped = n - kept.len();
    (kept, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};

    fn obs(x: u32, y: u32, light: Vector3<f64>) -> Observation {
        Observation::new(
            0,
            x,
            y,
            Point3::origin(),
            Vector3::z(),
            light,
            Vector3::z(),
            0.0,
            [1.0; 3],
            [1.0; 3],
        )
        .unwrap()
    }

    #[test]
    fn each_cell_keeps_its_cap_of_smallest_priorities_and_every_bin_survives() {
        let r = Reduction { regions: 2, cap: 3 };
        let a = Vector3::new(0.3, 0.0, 1.0).normalize();
        let b = Vector3::new(0.0, 0.7, 1.0).normalize();
        // 20 x 20 image: bin of `a` everywhere, plus one pixel of bin `b`
        let mut all: Vec<Observation> = (0..20)
            .flat_map(|y| (0..20).map(move |x| (x, y)))
            .map(|(x, y)| obs(x, y, a))
            .collect();
        all.push(obs(3, 3, b));
        let (kept, dropped) = reduce(all.clone(), 20, 20, &r);
        // 4 cells x 3 of bin a, plus the lone b
        assert_eq!(kept.len(), 13);
        assert_eq!(dropped, all.len() - 13);
        assert!(kept.iter().any(|o| o.bin == obs(3, 3, b).bin));
        // within a cell: the 3 smallest priorities
        let mut cell0: Vec<u64> = all
            .iter()
            .filter(|o| o.bin == kept[0].bin && r.region(o.x, o.y, 20, 20) == 0)
            .map(|o| priority(0, o.x, o.y))
            .collect();
        cell0.sort_unstable();
        let mut got: Vec<u64> = kept
            .iter()
            .filter(|o| o.bin == kept[0].bin && r.region(o.x, o.y, 20, 20) == 0)
            .map(|o| priority(0, o.x, o.y))
            .collect();
        got.sort_unstable();
        assert_eq!(got, cell0[..3]);
        // image order, and a large cap keeps everything
        assert!(
            kept.windows(2)
                .all(|w| (w[0].y, w[0].x) <= (w[1].y, w[1].x))
        );
        let (kept, dropped) = reduce(
            all.clone(),
            20,
            20,
            &Reduction {
                regions: 2,
                cap: 1000,
            },
        );
        assert_eq!((kept.len(), dropped), (all.len(), 0));
    }
}
