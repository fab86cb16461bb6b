//! The neural fits of the 100 MERL materials (Sztrajman et al. 2021), standing in for the MERL
//! tables, which cannot be downloaded here. They are smooth approximations fitted to the MERL
//! measurements, NOT measured data: every result that uses them must say so.
//!
//! Weights: 675 little-endian float32, row-major `[in][out]`:
//! `fc1[6][21], b1[21], fc2[21][21], b2[21], fc3[21][3], b3[3]`.
//! Network: `a1 = relu(x fc1 + b1); a2 = relu(a1 fc2 + b2); rgb = max(exp(a2 fc3 + b3) - 1, 0)`,
//! input `x = [sin th_h, 0, cos th_h, sin th_d cos ph_d, sin th_d sin ph_d, cos th_d]` (the half
//! vector at phi_h = 0 and the difference vector, angles as in [`crate::brdf::coords`]).
//! Output: f_r in 1/sr, RGB, MERL channel scales applied, no cosine factor.
//!
//! Two evaluators: `eval_angles` in f64 (the reference, what the test vectors were made with)
//! and an f32 path for tabulation (1.46 M bins). Pure except `load`, which names the file in every
//! error; must not depend on the basis or rendering.

use super::coords::{HalfDiff, MERL_BINS, MerlBin};
use super::merl::MerlTable;
use super::{BinValues, Brdf};
use nalgebra::Vector3;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

const IN: usize = 6;
const HID: usize = 21;
const OUT: usize = 3;
/// Number of float32 weights in one material file.
pub const NBRDF_WEIGHTS: usize = IN * HID + HID + HID * HID + HID + HID * OUT + OUT;

#[derive(Debug, thiserror::Error)]
pub enum NbrdfError {
    #[error("reading neural BRDF weights {path}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: neural BRDF file has {got} bytes, expected {expected} (675 float32 weights)")]
    WrongSize {
        path: PathBuf,
        got: usize,
        expected: usize,
    },
    #[error("{path}: weight {index} is not finite (corrupt file)")]
    NonFinite { path: PathBuf, index: usize },
}

/// One material's network.
#[derive(Clone, Debug, PartialEq)]
pub struct Nbrdf {
    fc1: Vec<f32>,
    b1: Vec<f32>,
    fc2: Vec<f32>,
    b2: Vec<f32>,
    fc3: Vec<f32>,
    b3: Vec<f32>,
}

impl Nbrdf {
    /// Parses 675 little-endian float32; `path` only names the source in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, NbrdfError> {
        if bytes.len() != NBRDF_WEIGHTS * 4 {
            return Err(NbrdfError::WrongSize {
                path: path.to_path_buf(),
                got: bytes.len(),
                expected: NBRDF_WEIGHTS * 4,
            });
        }
        let mut w = Vec::with_capacity(NBRDF_WEIGHTS);
        for (index, chunk) in bytes.chunks_exact(4).enumerate() {
            let mut b = [0u8; 4];
            b.copy_from_slice(chunk);
            let v = f32::from_le_bytes(b);
            if !v.is_finite() {
                return Err(NbrdfError::NonFinite {
                    path: path.to_path_buf(),
                    index,
                });
            }
            w.push(v);
        }
        let mut rest = w.as_slice();
        let mut take = |n: usize| {
            let (a, b) = rest.split_at(n);
            rest = b;
            a.to_vec()
        };
        Ok(Self {
            fc1: take(IN * HID),
            b1: take(HID),
            fc2: take(HID * HID),
            b2: take(HID),
            fc3: take(HID * OUT),
            b3: take(OUT),
        })
    }

    /// The 675 weights as little-endian float32, in file order (inverse of `from_bytes`).
    pub fn to_bytes(&self) -> Vec<u8> {
        [
            &self.fc1, &self.b1, &self.fc2, &self.b2, &self.fc3, &self.b3,
        ]
        .iter()
        .flat_map(|v| v.iter().flat_map(|w| w.to_le_bytes()))
        .collect()
    }

    /// Reads one `<material>.f32` file.
    pub fn load(path: &Path) -> Result<Self, NbrdfError> {
        let bytes = std::fs::read(path).map_err(|source| NbrdfError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// f_r at Rusinkiewicz angles (radians), in f64 throughout: the reference evaluator.
    pub fn eval_angles(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> [f64; 3] {
        let (sd, cd) = theta_d.sin_cos();
        let x = [
            theta_h.sin(),
            0.0,
            theta_h.cos(),
            sd * phi_d.cos(),
            sd * phi_d.sin(),
            cd,
        ];
        let mut a1 = [0.0f64; HID];
        for (j, a) in a1.iter_mut().enumerate() {
            let mut s = f64::from(self.b1[j]);
            for (i, xi) in x.iter().enumerate() {
                s += xi * f64::from(self.fc1[i * HID + j]);
            }
            *a = s.max(0.0);
        }
        let mut a2 = [0.0f64; HID];
        for (j, a) in a2.iter_mut().enumerate() {
            let mut s = f64::from(self.b2[j]);
            for (i, ai) in a1.iter().enumerate() {
                s += ai * f64::from(self.fc2[i * HID + j]);
            }
            *a = s.max(0.0);
        }
        let mut out = [0.0f64; OUT];
        for (j, o) in out.iter_mut().enumerate() {
            let mut s = f64::from(self.b3[j]);
            for (i, ai) in a2.iter().enumerate() {
                s += ai * f64::from(self.fc3[i * OUT + j]);
            }
            *o = (s.exp() - 1.0).max(0.0);
        }
        out
    }

    /// The same network in f32 (about twice as fast; relative error ~1e-5, see the tests).
    pub fn eval_angles_f32(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> [f32; 3] {
        let (sd, cd) = theta_d.sin_cos();
        let x = [
            theta_h.sin(),
            0.0,
            theta_h.cos(),
            sd * phi_d.cos(),
            sd * phi_d.sin(),
            cd,
        ];
        let mut a1 = [0.0f32; HID];
        a1.copy_from_slice(&self.b1);
        for (i, xi) in x.iter().enumerate() {
            let row = &self.fc1[i * HID..(i + 1) * HID];
            for (a, w) in a1.iter_mut().zip(row) {
                *a += xi * w;
            }
        }
        let mut a2 = [0.0f32; HID];
        a2.copy_from_slice(&self.b2);
        for (i, ai) in a1.iter().enumerate() {
            let ai = ai.max(0.0);
            let row = &self.fc2[i * HID..(i + 1) * HID];
            for (a, w) in a2.iter_mut().zip(row) {
                *a += ai * w;
            }
        }
        let mut out = [0.0f32; OUT];
        out.copy_from_slice(&self.b3);
        for (i, ai) in a2.iter().enumerate() {
            let ai = ai.max(0.0);
            for (j, o) in out.iter_mut().enumerate() {
                *o += ai * self.fc3[i * OUT + j];
            }
        }
        out.map(|s| (s.exp() - 1.0).max(0.0))
    }

    /// f32 values at bin centres, in parallel.
    pub fn values_at_f32(&self, bins: &[usize]) -> Vec<[f32; 3]> {
        bins.par_iter()
            .map(|&b| match MerlBin::from_index(b) {
                Some(bin) => {
                    let c = bin.centre();
                    self.eval_angles_f32(c.theta_h as f32, c.theta_d as f32, c.phi_d as f32)
                }
                None => [0.0; 3],
            })
            .collect()
    }

    /// The full MERL table at the bin centres (f32 network, parallel). The network is defined
    /// everywhere, so every bin gets a value, including those whose centre is below the
    /// horizon (the error metrics skip those).
    pub fn tabulate(&self) -> MerlTable {
        let bins: Vec<usize> = (0..MERL_BINS).collect();
        let values = self.values_at_f32(&bins);
        MerlTable::from_fn(|bin| {
            let v = values[bin.index()];
            Some([f64::from(v[0]), f64::from(v[1]), f64::from(v[2])])
        })
    }
}

/// The folder of `<material>.f32` files shipped with the crate (`crate::data::data_dir`).
pub fn default_dir() -> PathBuf {
    crate::data::data_dir().join("merl-nbrdf")
}

/// Loads every `<material>.f32` in `dir`, sorted by material name.
pub fn load_dir(dir: &Path) -> Result<Vec<(String, Nbrdf)>, NbrdfError> {
    let read_err = |source| NbrdfError::Read {
        path: dir.to_path_buf(),
        source,
    };
    let mut paths = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(read_err)? {
        let path = entry.map_err(read_err)?.path();
        if path.extension().is_some_and(|e| e == "f32") {
            paths.push(path);
        }
    }
    let mut all = paths
        .into_iter()
        .map(|path| {
            let name = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            Nbrdf::load(&path).map(|net| (name, net))
        })
        .collect::<Result<Vec<_>, _>>()?;
    // By name, not by file name: "chrome" before "chrome-steel".
    all.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(all)
}

impl Brdf for Nbrdf {
    /// The network at the exact angles of `(wi, wo)` (no binning); zero below the horizon.
    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let hd = HalfDiff::from_directions(wi, wo);
        self.eval_angles(hd.theta_h, hd.theta_d, hd.phi_d)
    }
}

impl BinValues for Nbrdf {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        self.values_at_f32(bins)
            .into_iter()
            .map(|v| v.map(f64::from))
            .collect()
    }
}

#[cfg(test)]
// Per-channel loops compare several arrays at the same index.
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    fn data_dir() -> PathBuf {
        default_dir()
    }

    #[test]
    fn loads_the_hundred_materials() {
        let all = load_dir(&data_dir()).expect("load all");
        assert_eq!(all.len(), 100);
        assert!(all.windows(2).all(|w| w[0].0 < w[1].0));
        assert!(all.iter().any(|(n, _)| n == "alum-bronze"));
    }

    #[derive(serde::Deserialize)]
    struct Case {
        material: String,
        theta_h: f64,
        theta_d: f64,
        phi_d: f64,
        rgb: [f64; 3],
    }

    #[derive(serde::Deserialize)]
    struct Vectors {
        cases: Vec<Case>,
    }

    fn vectors() -> Vec<Case> {
        let path = data_dir().join("testvectors.json");
        let text = std::fs::read_to_string(&path).expect("test vectors present");
        let v: Vectors = serde_json::from_str(&text).expect("test vectors parse");
        v.cases
    }

    #[test]
    fn f64_network_matches_the_test_vectors() {
        let cases = vectors();
        assert_eq!(cases.len(), 72);
        for case in &cases {
            let net = Nbrdf::load(&data_dir().join(format!("{}.f32", case.material)))
                .expect("weights load");
            let got = net.eval_angles(case.theta_h, case.theta_d, case.phi_d);
            for c in 0..3 {
                // The vectors were computed in float64 from the same float32 weights: only the
                // summation order can differ, ~1e-15 relative per term; 1e-10 leaves room for
                // exp() amplifying a pre-activation of magnitude ~10.
                let tol = 1e-10 * case.rgb[c].abs().max(1e-3);
                assert!(
                    (got[c] - case.rgb[c]).abs() <= tol,
                    "{} {c}: {} vs {}",
                    case.material,
                    got[c],
                    case.rgb[c]
                );
            }
        }
    }

    #[test]
    fn f32_network_matches_the_test_vectors() {
        for case in &vectors() {
            let net = Nbrdf::load(&data_dir().join(format!("{}.f32", case.material)))
                .expect("weights load");
            let got =
                net.eval_angles_f32(case.theta_h as f32, case.theta_d as f32, case.phi_d as f32);
            for c in 0..3 {
                // f32 has a 6e-8 unit roundoff; ~50 accumulated terms of magnitude up to ~10
                // give a pre-activation error up to ~1e-5, which exp() turns into the same
                // relative error of (rgb + 1). Hence 1e-4 (rgb + 1): 10x headroom.
                let tol = 1e-4 * (case.rgb[c].abs() + 1.0);
                assert!(
                    (f64::from(got[c]) - case.rgb[c]).abs() <= tol,
                    "{} {c}: {} vs {}",
                    case.material,
                    got[c],
                    case.rgb[c]
                );
            }
        }
    }

    #[test]
    fn tabulated_table_matches_the_network_at_bin_centres() {
        let net = Nbrdf::load(&data_dir().join("blue-acrylic.f32")).expect("load");
        let table = net.tabulate();
        for index in (0..MERL_BINS).step_by(7919) {
            let c = MerlBin::from_index(index).expect("bin").centre();
            let want = net.eval_angles(c.theta_h, c.theta_d, c.phi_d);
            let got = table.get(index).expect("every bin has data");
            for k in 0..3 {
                assert!((got[k] - want[k]).abs() <= 1e-4 * (want[k] + 1.0));
            }
        }
    }

    #[test]
    fn bad_weight_files_name_the_file() {
        let p = Path::new("broken.f32");
        let err = Nbrdf::from_bytes(&[0u8; 100], p).expect_err("short");
        assert!(matches!(err, NbrdfError::WrongSize { got: 100, .. }));
        assert!(err.to_string().contains("broken.f32"));
        let mut bytes = vec![0u8; NBRDF_WEIGHTS * 4];
        bytes[40..44].copy_from_slice(&f32::NAN.to_le_bytes());
        let err = Nbrdf::from_bytes(&bytes, p).expect_err("nan");
        assert!(matches!(err, NbrdfError::NonFinite { index: 10, .. }));
        assert!(err.to_string().contains("broken.f32"));
        let path = data_dir().join("teflon.f32");
        let bytes = std::fs::read(&path).expect("read");
        let net = Nbrdf::from_bytes(&bytes, &path).expect("parse");
        assert_eq!(net.to_bytes(), bytes);
        let err = Nbrdf::load(Path::new("/no/such/mat.f32")).expect_err("missing");
        assert!(err.to_string().contains("/no/such/mat.f32"));
    }
}
