//! Where a sphere might be: circles in the image found from its edges, whatever lies around
//! them. A circular Hough transform: every strong-gradient pixel votes for centres along its
//! gradient line (both ways: the sphere may be darker or brighter than its surround), and each
//! well-supported centre gets the radius at which the most directions around it have an edge
//! pointing at it. A holder hiding part of the outline, a textured backdrop or a post only take
//! votes away; they do not move the peak, as they would move a thresholded region's border.
//! The luminance is clamped at its 99th percentile first, so that a highlight (hundreds of times
//! brighter in an HDR image) does not make the sphere's own edge look weak.
//!
//! Conventions: pixel centres at half-integers; radii in pixels. Pure: no I/O.

use crate::calib::regions::{self, Plane};

/// A circle that may be the sphere's outline: centre, radius and how much of its
/// circumference has an edge pointing at its centre (0..1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Seed {
    pub cx: f64,
    pub cy: f64,
    pub r: f64,
    pub coverage: f64,
}

/// Angular sectors in which a radius's support is counted.
const SECTORS: usize = 72;

/// Circles in `lum` with radius in `[r_min, r_max]`, best supported first: up to three radii
/// around each of at most `max` centres.
pub(super) fn circles(lum: &Plane, r_min: f64, r_max: f64, max: usize) -> Vec<Seed> {
    let (w, h) = (lum.width, lum.height);
    if w < 5 || h < 5 || r_max < r_min {
        return Vec::new();
    }
    // Highlights and lamps are far brighter than any outline in an HDR image, and small: clamped
    // at the 99th percentile, they no longer set the scale of what counts as an edge.
    let ceiling = regions::quantile(&lum.data, 0.99).unwrap_or(f32::INFINITY);
    let s = Plane {
        width: w,
        height: h,
        data: lum.data.iter().map(|&v| v.min(ceiling)).collect(),
    }
    .box3();
    // gradients by central differences of the smoothed luminance
    let mut edges: Vec<(f64, f64, f64, f64, f64)> = Vec::new(); // x, y, ux, uy, magnitude
    let mut mags = Vec::with_capacity(w * h);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let gx = 0.5 * f64::from(s.at(x + 1, y) - s.at(x - 1, y));
            let gy = 0.5 * f64::from(s.at(x, y + 1) - s.at(x, y - 1));
            mags.push(gx.hypot(gy) as f32);
        }
    }
    let strong = regions::quantile(&mags, 0.998).unwrap_or(0.0);
    let typical = regions::quantile(&mags, 0.5).unwrap_or(0.0);
    let thr = f64::from((0.15 * strong).max(3.0 * typical));
    if thr.is_nan() || thr <= 0.0 {
        return Vec::new();
    }
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let m = f64::from(mags[(y - 1) * (w - 2) + (x - 1)]);
            if m >= thr {
                let gx = 0.5 * f64::from(s.at(x + 1, y) - s.at(x - 1, y));
                let gy = 0.5 * f64::from(s.at(x, y + 1) - s.at(x, y - 1));
                edges.push((x as f64 + 0.5, y as f64 + 0.5, gx / m, gy / m, m));
            }
        }
    }
    // centre votes
    let mut acc = vec![0f32; w * h];
    let (r0, r1) = (r_min.floor() as usize, r_max.ceil() as usize);
    for &(x, y, ux, uy, m) in &edges {
        for sign in [-1.0, 1.0] {
            for r in r0..=r1 {
                let cx = x + sign * r as f64 * ux;
                let cy = y + sign * r as f64 * uy;
                if cx >= 0.0 && cy >= 0.0 && cx < w as f64 && cy < h as f64 {
                    acc[cy as usize * w + cx as usize] += m as f32;
                }
            }
        }
    }
    let acc = Plane {
        width: w,
        height: h,
        data: acc,
    }
    .box3();
    // local maxima, strongest first, at least r_min apart
    let mut peaks: Vec<(usize, usize, f32)> = Vec::new();
    for y in 2..h - 2 {
        for x in 2..w - 2 {
            let v = acc.at(x, y);
            if v <= 0.0 {
                continue;
            }
            let is_max = (-2i64..=2).all(|dy| {
                (-2i64..=2).all(|dx| {
                    (dx == 0 && dy == 0)
                        || acc.at((x as i64 + dx) as usize, (y as i64 + dy) as usize) <= v
                })
            });
            if is_max {
                peaks.push((x, y, v));
            }
        }
    }
    peaks.sort_by(|a, b| b.2.total_cmp(&a.2));
    let mut chosen: Vec<(f64, f64)> = Vec::new();
    let mut seeds = Vec::new();
    for &(px, py, _) in &peaks {
        if chosen.len() >= 3 * max {
            break;
        }
        let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
        if chosen
            .iter()
            .any(|&(ox, oy)| (ox - cx).hypot(oy - cy) < r_min)
        {
            continue;
        }
        chosen.push((cx, cy));
        seeds.extend(
            radii(&edges, cx, cy, r_min, r_max)
                .into_iter()
                .map(|s| refined(&edges, s)),
        );
    }
    // the best covered centres, each with its radii
    let mut order: Vec<(f64, f64, f64)> = Vec::new(); // centre, best coverage
    for s in &seeds {
        match order.iter_mut().find(|o| o.0 == s.cx && o.1 == s.cy) {
            Some(o) => o.2 = o.2.max(s.coverage),
            None => order.push((s.cx, s.cy, s.coverage)),
        }
    }
    order.sort_by(|a, b| b.2.total_cmp(&a.2));
    order.truncate(max);
    seeds.retain(|s| order.iter().any(|o| o.0 == s.cx && o.1 == s.cy));
    seeds.sort_by(|a, b| b.coverage.total_cmp(&a.coverage));
    seeds
}

/// The radii around `(cx, cy)` with the strongest edges facing the centre, all of one sign (a
/// sphere darker than its surround all round, or brighter), among the radii whose such edges
/// cover at least half as many directions as the best covered one: the strongest, and up to two
/// more at least 3 px from it and each other (a sphere can show concentric rings, where it
/// mirrors the edge of its backdrop, inside its outline).
fn radii(
    edges: &[(f64, f64, f64, f64, f64)],
    cx: f64,
    cy: f64,
    r_min: f64,
    r_max: f64,
) -> Vec<Seed> {
    let bins = r_max.ceil() as usize + 2;
    // per sign (outward, inward gradient), radius bin: sectors hit and summed magnitude
    let mut sectors = vec![vec![[false; SECTORS]; bins]; 2];
    let mut weight = vec![vec![0.0f64; bins]; 2];
    for &(x, y, ux, uy, m) in edges {
        let (dx, dy) = (x - cx, y - cy);
        let d = dx.hypot(dy);
        if d < r_min - 1.0 || d > r_max + 1.0 || d == 0.0 {
            continue;
        }
        let facing = (ux * dx + uy * dy) / d;
        if facing.abs() < 0.85 {
            continue; // the edge does not face the centre
        }
        let a = dy.atan2(dx).rem_euclid(std::f64::consts::TAU);
        let sector = ((a / std::f64::consts::TAU * SECTORS as f64) as usize).min(SECTORS - 1);
        let sign = usize::from(facing < 0.0);
        let bin = (d.round() as usize).min(bins - 1);
        sectors[sign][bin][sector] = true;
        weight[sign][bin] += m;
    }
    // an edge blurred over a few pixels: count three adjacent bins together
    let mut rows = Vec::new();
    for sign in 0..2 {
        for r in (r_min.ceil() as usize).max(1)..bins - 1 {
            let covered = (0..SECTORS)
                .filter(|&k| (r - 1..=r + 1).any(|b| sectors[sign][b][k]))
                .count();
            let w: f64 = (r - 1..=r + 1).map(|b| weight[sign][b]).sum();
            rows.push((r, covered, w / r as f64));
        }
    }
    let Some(most) = rows.iter().map(|r| r.1).max() else {
        return Vec::new();
    };
    rows.retain(|r| 2 * r.1 >= most);
    rows.sort_by(|a, b| b.2.total_cmp(&a.2));
    let mut out: Vec<Seed> = Vec::new();
    for (r, covered, _) in rows {
        if out.len() == 3 {
            break;
        }
        if out.iter().all(|s| (s.r - r as f64).abs() >= 3.0) {
            out.push(Seed {
                cx,
                cy,
                r: r as f64,
                coverage: covered as f64 / SECTORS as f64,
            });
        }
    }
    out
}

/// A seed snapped to the round edge near it: the circle fitted to the edge pixels within a band
/// around it that face its centre, with the band narrowed from 3 to 1.5 px. The Hough centre is
/// only as good as its accumulator's pixel, and a ring inside the outline pulls it.
fn refined(edges: &[(f64, f64, f64, f64, f64)], seed: Seed) -> Seed {
    let mut s = seed;
    for band in [3.0, 2.0, 1.5] {
        let pts: Vec<(f64, f64)> = edges
            .iter()
            .filter(|&&(x, y, ux, uy, _)| {
                let (dx, dy) = (x - s.cx, y - s.cy);
                let d = dx.hypot(dy);
                d > 0.0 && (d - s.r).abs() <= band && ((ux * dx + uy * dy) / d).abs() >= 0.85
            })
            .map(|&(x, y, ..)| (x, y))
            .collect();
        if pts.len() < 12 {
            break;
        }
        match regions::fit_circle(&pts) {
            Some((cx, cy, r)) if (r - s.r).abs() < band && (cx - s.cx).hypot(cy - s.cy) < band => {
                s = Seed { cx, cy, r, ..s };
            }
            _ => break,
        }
    }
    s
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    /// A dark disc, partly hidden by a bright bar, on a checkerboard: the strongest circle is
    /// the disc, to within a pixel.
    #[test]
    fn a_partly_hidden_disc_on_a_checkerboard_is_found() {
        let (w, h) = (200, 150);
        let mut data = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let checker = if (x / 16 + y / 16) % 2 == 0 { 0.4 } else { 0.7 };
                let (dx, dy) = (x as f64 + 0.5 - 90.3, y as f64 + 0.5 - 70.8);
                let disc = dx.hypot(dy) < 31.0;
                let bar = y > 90 && (80..110).contains(&x);
                data[y * w + x] = if bar {
                    0.55
                } else if disc {
                    0.05
                } else {
                    checker
                };
            }
        }
        let lum = Plane {
            width: w,
            height: h,
            data,
        };
        let seeds = circles(&lum, 8.0, 75.0, 3);
        let s = seeds[0];
        assert!(
            (s.cx - 90.3).abs() < 1.5 && (s.cy - 70.8).abs() < 1.5,
            "{s:?}"
        );
        assert!((s.r - 31.0).abs() <= 1.5 && s.coverage > 0.6, "{s:?}");
    }
}
