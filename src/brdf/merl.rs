//! The MERL BRDF table: the currency of reconstruction (its output) and evaluation (its truth).
//!
//! File format (`.binary`, Matusik et al. 2003): three little-endian int32 `90 90 180`, then
//! `3 * 1_458_000` little-endian float64, planar R, G, B, each in the bin order of
//! [`crate::brdf::coords`]. A stored value times the channel scale (1/1500, 1.15/1500,
//! 1.66/1500) is f_r in 1/sr; writing divides by the same scale. A negative value means "no
//! data" in that bin.
//!
//! In memory the table keeps the stored (unscaled) values, so a file read and written again is
//! byte-identical; every accessor returns f_r in 1/sr (scale applied). Lookup is nearest-bin (no
//! interpolation), as the MERL reference code does. Pure except `read`/`write`, which name the
//! file in every error; must not depend on the basis, the network or rendering.

use super::Brdf;
use super::coords::{HalfDiff, MERL_BINS, MerlBin, PHI_D_BINS, THETA_D_BINS, THETA_H_BINS};
use nalgebra::Vector3;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Multiply a stored value by this to get f_r in 1/sr, per channel (R, G, B).
pub const MERL_SCALES: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];

const HEADER_BYTES: usize = 12;
const FILE_BYTES: usize = HEADER_BYTES + 3 * MERL_BINS * 8;

#[derive(Debug, thiserror::Error)]
pub enum MerlError {
    #[error("reading MERL table {path}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("writing MERL table {path}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "{path}: not a MERL table: header says {dims:?}, expected [90, 90, 180] (is it a MERL .binary file?)"
    )]
    BadHeader { path: PathBuf, dims: [i32; 3] },
    #[error(
        "{path}: MERL table has {got} bytes, expected {expected} (truncated or not a MERL file)"
    )]
    WrongSize {
        path: PathBuf,
        got: usize,
        expected: usize,
    },
    #[error("{path}: value at channel {channel}, bin {bin} is not finite")]
    NonFinite {
        path: PathBuf,
        channel: usize,
        bin: usize,
    },
    #[error(
        "{path}: the MERL table has no data: every bin has a negative value in some colour channel (negative means \"no data\")"
    )]
    NoData { path: PathBuf },
}

/// A full MERL table; negative entries mean no data.
#[derive(Clone, Debug, PartialEq)]
pub struct MerlTable {
    /// `3 * MERL_BINS` stored values (f_r / channel scale): all red, then green, then blue.
    data: Vec<f64>,
}

impl MerlTable {
    /// A table with no data anywhere (every entry -1).
    pub fn empty() -> Self {
        Self {
            data: vec![-1.0; 3 * MERL_BINS],
        }
    }

    /// Tabulates `f(bin)` at every bin (in parallel); `None` stores "no data".
    pub fn from_fn(f: impl Fn(MerlBin) -> Option<[f64; 3]> + Sync) -> Self {
        let mut table = Self::zeros();
        table.update(|i, _| MerlBin::from_index(i).and_then(&f));
        table
    }

    /// A table of zeros (f_r = 0 in every bin): the cheapest start for [`Self::update`], which
    /// writes every bin (zeroed memory is handed out by the system as it is first written,
    /// where [`Self::empty`] writes 35 MB first).
    pub fn zeros() -> Self {
        Self {
            data: vec![0.0; 3 * MERL_BINS],
        }
    }

    /// Replaces every bin's value by `f(index, its value)`, in parallel and in place: what
    /// [`Self::get`] then [`Self::set`] would do bin by bin (`None`, in and out, is "no data"),
    /// without a second table or a serial copy (a table is 35 MB; a reconstruction makes
    /// several per material).
    pub fn update(&mut self, f: impl Fn(usize, Option<[f64; 3]>) -> Option<[f64; 3]> + Sync) {
        self.update_counting(|i, v| (f(i, v), [0; 0]));
    }

    /// [`Self::update`] where `f` also returns counts, summed over the bins (integers: the
    /// same sums whatever order the threads take; no counter shared between them).
    pub fn update_counting<const N: usize>(
        &mut self,
        f: impl Fn(usize, Option<[f64; 3]>) -> (Option<[f64; 3]>, [usize; N]) + Sync,
    ) -> [usize; N] {
        self.par_bins_mut()
            .map(|(index, [r, g, b])| {
                let (new, counts) = f(index, stored_value([*r, *g, *b]));
                match new {
                    Some(v) => store([r, g, b], v),
                    None => (*r, *g, *b) = (-1.0, -1.0, -1.0),
                }
                counts
            })
            .reduce(|| [0; N], |a, b| std::array::from_fn(|i| a[i] + b[i]))
    }

    /// Multiplies f_r by `factor(index)` at every bin with data whose factor is below 1, in
    /// place and in parallel (`get`, scale, `set`); every other bin keeps its stored value.
    /// Returns, per bin, whether it was scaled.
    pub fn scale_down(&mut self, factor: impl Fn(usize) -> f64 + Sync) -> Vec<bool> {
        self.par_bins_mut()
            .map(|(index, [r, g, b])| {
                let Some(v) = stored_value([*r, *g, *b]) else {
                    return false;
                };
                let f = factor(index);
                if f >= 1.0 {
                    return false;
                }
                store([r, g, b], v.map(|x| x * f));
                true
            })
            .collect()
    }

    /// Every bin's index and its three stored channels, mutable, in parallel.
    fn par_bins_mut(&mut self) -> impl IndexedParallelIterator<Item = (usize, [&mut f64; 3])> {
        let (r, gb) = self.data.split_at_mut(MERL_BINS);
        let (g, b) = gb.split_at_mut(MERL_BINS);
        r.par_iter_mut()
            .zip(g.par_iter_mut())
            .zip(b.par_iter_mut())
            .enumerate()
            .with_min_len(1024)
            .map(|(index, ((r, g), b))| (index, [r, g, b]))
    }

    /// Tabulates any BRDF at the bin centres (phi_h = 0). Bins with a centre direction below the
    /// horizon get no data.
    pub fn tabulate(brdf: &dyn Brdf) -> Self {
        Self::from_fn(|bin| {
            let (wi, wo) = bin.centre_directions();
            (wi.z > 0.0 && wo.z > 0.0).then(|| brdf.eval_local(&wi, &wo))
        })
    }

    /// f_r at a flat bin index, or `None` when any channel has no data.
    pub fn get(&self, index: usize) -> Option<[f64; 3]> {
        if index >= MERL_BINS {
            return None;
        }
        let v = [
            self.data[index] * MERL_SCALES[0],
            self.data[MERL_BINS + index] * MERL_SCALES[1],
            self.data[2 * MERL_BINS + index] * MERL_SCALES[2],
        ];
        v.iter().all(|x| *x >= 0.0).then_some(v)
    }

    /// Sets f_r at a flat bin index (negative values mark no data).
    pub fn set(&mut self, index: usize, rgb: [f64; 3]) {
        for (c, v) in rgb.iter().enumerate() {
            self.data[c * MERL_BINS + index] = *v / MERL_SCALES[c];
        }
    }

    /// Nearest-bin lookup by angles.
    pub fn lookup(&self, angles: &HalfDiff) -> Option<[f64; 3]> {
        self.get(angles.merl_bin().index())
    }

    /// Serialises to the MERL `.binary` layout.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(FILE_BYTES);
        for d in [THETA_H_BINS, THETA_D_BINS, PHI_D_BINS] {
            out.extend_from_slice(&(d as i32).to_le_bytes());
        }
        for v in &self.data {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Parses the MERL `.binary` layout; `path` only names the source in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, MerlError> {
        let path_buf = || path.to_path_buf();
        if bytes.len() < HEADER_BYTES {
            return Err(MerlError::WrongSize {
                path: path_buf(),
                got: bytes.len(),
                expected: FILE_BYTES,
            });
        }
        let mut dims = [0i32; 3];
        for (k, d) in dims.iter_mut().enumerate() {
            let mut b = [0u8; 4];
            b.copy_from_slice(&bytes[4 * k..4 * k + 4]);
            *d = i32::from_le_bytes(b);
        }
        if dims != [90, 90, 180] {
            return Err(MerlError::BadHeader {
                path: path_buf(),
                dims,
            });
        }
        if bytes.len() != FILE_BYTES {
            return Err(MerlError::WrongSize {
                path: path_buf(),
                got: bytes.len(),
                expected: FILE_BYTES,
            });
        }
        let mut data = Vec::with_capacity(3 * MERL_BINS);
        for (k, chunk) in bytes[HEADER_BYTES..].chunks_exact(8).enumerate() {
            let mut b = [0u8; 8];
            b.copy_from_slice(chunk);
            let raw = f64::from_le_bytes(b);
            if !raw.is_finite() {
                return Err(MerlError::NonFinite {
                    path: path_buf(),
                    channel: k / MERL_BINS,
                    bin: k % MERL_BINS,
                });
            }
            data.push(raw);
        }
        let table = Self { data };
        // A table that answers "no data" everywhere would evaluate to 0 at every angle.
        if !(0..MERL_BINS).any(|i| table.get(i).is_some()) {
            return Err(MerlError::NoData { path: path_buf() });
        }
        Ok(table)
    }

    /// Reads a MERL `.binary` file.
    pub fn read(path: &Path) -> Result<Self, MerlError> {
        let bytes = std::fs::read(path).map_err(|source| MerlError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// Writes a MERL `.binary` file, atomically (`atomic::write_atomic_unsynced`: a killed or
    /// crashed run leaves the old file or the new one, never a truncated table; not fsynced, a
    /// table is 35 MB and can be made again).
    pub fn write(&self, path: &Path) -> Result<(), MerlError> {
        crate::atomic::write_atomic_unsynced(path, &self.to_bytes()).map_err(|source| {
            MerlError::Write {
                path: path.to_path_buf(),
                source,
            }
        })
    }
}

impl Brdf for MerlTable {
    /// Nearest bin; zero below the horizon and in bins with no data.
    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        self.lookup(&HalfDiff::from_directions(wi, wo))
            .unwrap_or([0.0; 3])
    }
}

impl super::BinValues for MerlTable {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        bins.iter()
            .map(|&b| self.get(b).unwrap_or([0.0; 3]))
            .collect()
    }
}

/// f_r from a bin's stored channels ([`MerlTable::get`]'s rule: `None` when any is negative).
fn stored_value(stored: [f64; 3]) -> Option<[f64; 3]> {
    let v = std::array::from_fn(|c| stored[c] * MERL_SCALES[c]);
    v.iter().all(|x: &f64| *x >= 0.0).then_some(v)
}

/// Stores f_r into a bin's channels ([`MerlTable::set`]'s rule).
fn store(stored: [&mut f64; 3], v: [f64; 3]) {
    for (c, s) in stored.into_iter().enumerate() {
        *s = v[c] / MERL_SCALES[c];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// A smooth analytic BRDF whose value depends on all three angles: a stand-in with a
    /// closed form.
    struct Analytic;
    impl Brdf for Analytic {
        fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
            let hd = HalfDiff::from_directions(wi, wo);
            let s = (-hd.theta_h * hd.theta_h / 0.02).exp();
            let a = 0.2 + 0.1 * hd.theta_d.cos() + 0.05 * (2.0 * hd.phi_d).cos();
            [a / PI + s, 0.5 * a / PI + 2.0 * s, 0.1 / PI + 0.5 * s]
        }
    }

    #[test]
    fn updating_in_place_is_getting_then_setting_each_bin() {
        let mut table = MerlTable::tabulate(&Analytic);
        table.set(17, [-1.0, -1.0, -1.0]);
        // bin by bin with get and set, into a fresh table
        let f = |i: usize, v: Option<[f64; 3]>| match (i % 3, v) {
            (0, _) => None,
            (1, Some(v)) => Some(v.map(|x| x.sqrt() * 1.1)),
            (_, v) => v.or(Some([0.5, 0.25, 0.125])),
        };
        let mut expected = MerlTable::empty();
        for i in 0..MERL_BINS {
            if let Some(v) = f(i, table.get(i)) {
                expected.set(i, v);
            }
        }
        table.update(f);
        assert_eq!(table, expected);
        let made = MerlTable::from_fn(|b| (b.theta_d < 40).then_some([b.theta_h as f64; 3]));
        let mut by_hand = MerlTable::empty();
        for i in 0..MERL_BINS {
            if let Some(b) = MerlBin::from_index(i).filter(|b| b.theta_d < 40) {
                by_hand.set(i, [b.theta_h as f64; 3]);
            }
        }
        assert_eq!(made, by_hand);
    }

    #[test]
    fn scaling_down_touches_only_bins_with_data_and_a_factor_below_one() {
        let mut table = MerlTable::tabulate(&Analytic);
        table.set(17, [-1.0, -1.0, -1.0]);
        let before = table.clone();
        let factor = |i: usize| if i % 2 == 1 { 0.5 } else { 1.5 };
        let scaled = table.scale_down(factor);
        assert_eq!(scaled.len(), MERL_BINS);
        for i in (0..MERL_BINS).step_by(997).chain([17]) {
            match before.get(i) {
                Some(v) if i % 2 == 1 => {
                    assert!(scaled[i]);
                    let mut one = MerlTable::empty();
                    one.set(i, v.map(|x| x * 0.5));
                    assert_eq!(table.get(i), one.get(i));
                }
                _ => {
                    assert!(!scaled[i]);
                    // untouched: the stored value itself, not a trip through the scale
                    assert_eq!(table.data[i].to_bits(), before.data[i].to_bits());
                }
            }
        }
    }

    #[test]
    fn file_round_trip_is_exact() {
        let mut table = MerlTable::tabulate(&Analytic);
        table.set(17, [-1.0, -1.0, -1.0]);
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("t.binary");
        table.write(&path).expect("write");
        let bytes = std::fs::read(&path).expect("bytes");
        let back = MerlTable::read(&path).expect("read");
        assert_eq!(back, table);
        // Read then write is byte-identical.
        assert_eq!(back.to_bytes(), bytes);
        assert_eq!(back.get(17), None);
        assert_eq!(back.get(18), table.get(18));
    }

    #[test]
    fn raw_values_are_scaled_on_read() {
        // A hand-built file: every stored value 1500 means f_r = 1, 1.15, 1.66.
        let mut bytes = Vec::new();
        for d in [90i32, 90, 180] {
            bytes.extend_from_slice(&d.to_le_bytes());
        }
        for _ in 0..3 * MERL_BINS {
            bytes.extend_from_slice(&1500.0f64.to_le_bytes());
        }
        let t = MerlTable::from_bytes(&bytes, Path::new("x.binary")).expect("parse");
        let v = t.get(12345).expect("data");
        assert!((v[0] - 1.0).abs() < 1e-12 && (v[1] - 1.15).abs() < 1e-12);
        assert!((v[2] - 1.66).abs() < 1e-12);
    }

    #[test]
    fn lookup_of_tabulated_analytic_brdf() {
        let table = MerlTable::tabulate(&Analytic);
        // At a bin centre the table holds the analytic value exactly.
        let bin = MerlBin {
            theta_h: 10,
            theta_d: 30,
            phi_d: 50,
        };
        let (wi, wo) = bin.centre_directions();
        let (got, want) = (table.eval_local(&wi, &wo), Analytic.eval_local(&wi, &wo));
        assert!((0..3).all(|c| (got[c] - want[c]).abs() <= 1e-14 * want[c]));
        // Anywhere else (rotated frames too: isotropy means the table ignores phi_h), the
        // lookup returns exactly the analytic value at the centre of the bin holding the
        // angles, with phi_d folded by reciprocity.
        for k in 0..200 {
            let t = k as f64 / 200.0;
            let hd = HalfDiff {
                theta_h: 0.02 + 0.6 * t,
                phi_h: 6.0 * t,
                theta_d: 0.1 + 0.8 * (1.0 - t),
                phi_d: 0.3 + 5.0 * t,
            };
            let (wi, wo) = hd.to_directions();
            let (ci, co) = hd.merl_bin().centre_directions();
            let (got, want) = (table.eval_local(&wi, &wo), Analytic.eval_local(&ci, &co));
            for c in 0..3 {
                // Only the rounding of dividing by the channel scale and multiplying back.
                assert!((got[c] - want[c]).abs() <= 1e-14 * want[c], "{hd:?}");
            }
        }
        // Below the horizon: zero.
        let below = Vector3::new(0.0, 0.6, -0.8);
        assert_eq!(table.eval_local(&below, &Vector3::z()), [0.0; 3]);
    }

    #[test]
    fn bad_files_name_the_file() {
        let p = Path::new("bogus.binary");
        let err = MerlTable::from_bytes(&[1, 2, 3], p).expect_err("short");
        assert!(err.to_string().contains("bogus.binary"));
        let mut bytes = Vec::new();
        for d in [90i32, 90, 90] {
            bytes.extend_from_slice(&d.to_le_bytes());
        }
        let err = MerlTable::from_bytes(&bytes, p).expect_err("header");
        assert!(matches!(err, MerlError::BadHeader { .. }));
        assert!(err.to_string().contains("bogus.binary"));
        let mut bytes = MerlTable::empty().to_bytes();
        bytes.truncate(bytes.len() - 8);
        let err = MerlTable::from_bytes(&bytes, p).expect_err("size");
        assert!(matches!(err, MerlError::WrongSize { .. }));
        let mut bytes = MerlTable::empty().to_bytes();
        let n = bytes.len();
        bytes[n - 8..].copy_from_slice(&f64::NAN.to_le_bytes());
        let err = MerlTable::from_bytes(&bytes, p).expect_err("nan");
        assert!(matches!(err, MerlError::NonFinite { channel: 2, .. }));
        let err = MerlTable::read(Path::new("/nonexistent/x.binary")).expect_err("missing");
        assert!(err.to_string().contains("/nonexistent/x.binary"));
    }
}
