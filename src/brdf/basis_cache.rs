//! The on-disk cache of PCA bases: an I/O edge, kept apart from the pure `basis.rs`.
//!
//! A basis takes seconds to minutes to build; it is cached under a name derived from a key: the
//! SHA-256 of the format version, the settings (strides, components, excluded materials) and the
//! name and weights of every material used. Changing any of them makes a new file.
//!
//! File layout (little-endian): magic `BRDFRIG-BASIS\0\0\0`, u32 version, 32-byte key, u64 rows,
//! u64 k, u64 materials, then each material name (u32 length + UTF-8), the three u32 strides,
//! rows x u32 bin, rows x f64 cosine map, rows x f64 median, rows x f64 mean, (3 materials) x f64
//! singular values, rows x k f32 Q, and last the SHA-256 of everything before it. Anything that
//! does not check out (magic, version, key, checksum, sizes, a grid that differs from the one the
//! settings give) is treated as corrupt: rebuilt with a warning on stderr, never trusted.
//! Files are written to a temporary name and renamed, so a crash never leaves half a file.
//!
//! Default directory: `$BRDF_RIG_CACHE`, else `~/.cache/brdf-rig`. The pure modules (sampling,
//! ridge, metrics) must not depend on this file: they take a `Basis`, wherever it came from.

use super::BinValues;
use super::basis::{Basis, BasisError, BasisGrid, BasisSettings, GridStride};
use super::nbrdf::Nbrdf;
use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 16] = b"BRDFRIG-BASIS\0\0\0";
const VERSION: u32 = 1;

#[derive(Debug, thiserror::Error)]
pub enum BasisCacheError {
    #[error("creating basis cache directory {path}")]
    CreateDir {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("writing basis cache {path}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("building the basis")]
    Build(#[from] BasisError),
}

/// What `load_or_build` did.
#[derive(Clone, Debug, PartialEq)]
pub enum CacheStatus {
    /// Read from the cache.
    Hit(PathBuf),
    /// No cache file: built and saved.
    Built(PathBuf),
    /// A cache file existed but was corrupt: rebuilt and saved over it.
    Rebuilt { path: PathBuf, reason: String },
}

/// `$BRDF_RIG_CACHE`, else `~/.cache/brdf-rig`, else `./.brdf-rig-cache`.
pub fn default_cache_dir() -> PathBuf {
    if let Some(p) = std::env::var_os("BRDF_RIG_CACHE") {
        return PathBuf::from(p);
    }
    match std::env::var_os("HOME") {
        Some(home) => PathBuf::from(home).join(".cache/brdf-rig"),
        None => PathBuf::from(".brdf-rig-cache"),
    }
}

fn used_materials<'a>(
    settings: &BasisSettings,
    materials: &'a [(String, Nbrdf)],
) -> Vec<&'a (String, Nbrdf)> {
    let mut used: Vec<_> = materials
        .iter()
        .filter(|(n, _)| !settings.exclude.contains(n))
        .collect();
    used.sort_by(|a, b| a.0.cmp(&b.0));
    used
}

/// The cache key of a basis built from these settings and materials.
pub fn cache_key(settings: &BasisSettings, materials: &[(String, Nbrdf)]) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(MAGIC);
    h.update(VERSION.to_le_bytes());
    let s = settings.stride;
    for v in [s.theta_h, s.theta_d, s.phi_d, settings.basis_components] {
        h.update((v as u64).to_le_bytes());
    }
    let mut excluded = settings.exclude.clone();
    excluded.sort();
    for e in &excluded {
        h.update((e.len() as u64).to_le_bytes());
        h.update(e.as_bytes());
    }
    h.update(b"materials");
    for (name, net) in used_materials(settings, materials) {
        h.update((name.len() as u64).to_le_bytes());
        h.update(name.as_bytes());
        h.update(net.to_bytes());
    }
    h.finalize().into()
}

/// The basis for `settings` from the cache in `dir`, or built (and cached) when absent or
/// corrupt.
pub fn load_or_build(
    settings: &BasisSettings,
    materials: &[(String, Nbrdf)],
    dir: &Path,
) -> Result<(Basis, CacheStatus), BasisCacheError> {
    let key = cache_key(settings, materials);
    let path = dir.join(format!("basis-{}.bin", hex::encode(&key[..12])));
    let mut corrupt = None;
    match std::fs::read(&path) {
        Ok(bytes) => match decode(&bytes, &key, settings) {
            Ok(basis) => return Ok((basis, CacheStatus::Hit(path))),
            Err(reason) => {
                eprintln!(
                    "warning: basis cache {} is corrupt ({reason}); rebuilding it",
                    path.display()
                );
                corrupt = Some(reason.to_string());
            }
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => {
            eprintln!(
                "warning: cannot read basis cache {} ({e}); rebuilding it",
                path.display()
            );
            corrupt = Some(e.to_string());
        }
    }
    let refs: Vec<(&str, &dyn BinValues)> = materials
        .iter()
        .map(|(n, m)| (n.as_str(), m as &dyn BinValues))
        .collect();
    let basis = Basis::build(settings, &refs)?;
    std::fs::create_dir_all(dir).map_err(|source| BasisCacheError::CreateDir {
        path: dir.to_path_buf(),
        source,
    })?;
    let bytes = encode(&basis, &key);
    let write_err = |source| BasisCacheError::Write {
        path: path.clone(),
        source,
    };
    let mut tmp = tempfile::NamedTempFile::new_in(dir).map_err(write_err)?;
    tmp.write_all(&bytes).map_err(write_err)?;
    tmp.persist(&path).map_err(|e| write_err(e.error))?;
    let status = match corrupt {
        Some(reason) => CacheStatus::Rebuilt {
            path: path.clone(),
            reason,
        },
        None => CacheStatus::Built(path.clone()),
    };
    Ok((basis, status))
}

fn encode(b: &Basis, key: &[u8; 32]) -> Vec<u8> {
    let rows = b.grid.n_rows();
    let mut out = Vec::with_capacity(128 + rows * (4 + 24 + 4 * b.k));
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(key);
    for v in [rows, b.k, b.materials.len()] {
        out.extend_from_slice(&(v as u64).to_le_bytes());
    }
    for name in &b.materials {
        out.extend_from_slice(&(name.len() as u32).to_le_bytes());
        out.extend_from_slice(name.as_bytes());
    }
    let s = b.grid.stride();
    for v in [s.theta_h, s.theta_d, s.phi_d] {
        out.extend_from_slice(&(v as u32).to_le_bytes());
    }
    for &bin in b.grid.bins() {
        out.extend_from_slice(&(bin as u32).to_le_bytes());
    }
    for v in b
        .cos_map
        .iter()
        .chain(&b.median)
        .chain(&b.mean)
        .chain(&b.singular_values)
    {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in &b.q {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let sum: [u8; 32] = Sha256::digest(&out).into();
    out.extend_from_slice(&sum);
    out
}

/// Why a cache file cannot be used (it is rebuilt; the reason is reported).
#[derive(Debug, thiserror::Error)]
enum DecodeError {
    #[error("size overflow")]
    Overflow,
    #[error("file too short")]
    TooShort,
    #[error("checksum mismatch")]
    Checksum,
    #[error("not a basis cache file")]
    Magic,
    #[error("format version {0}, expected {VERSION}")]
    Version(u32),
    #[error("key does not match the settings and materials")]
    Key,
    #[error("material name not UTF-8")]
    Name,
    #[error("stride differs from the settings")]
    Stride,
    #[error("row count differs from the grid")]
    Rows,
    #[error("bins differ from the grid")]
    Bins,
    #[error("trailing bytes")]
    Trailing,
    #[error("{0}")]
    Invalid(BasisError),
}

/// A cursor that fails with a reason instead of panicking on short input.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeError> {
        let end = self.pos.checked_add(n).ok_or(DecodeError::Overflow)?;
        let s = self.bytes.get(self.pos..end).ok_or(DecodeError::TooShort)?;
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, DecodeError> {
        let mut b = [0u8; 4];
        b.copy_from_slice(self.take(4)?);
        Ok(u32::from_le_bytes(b))
    }
    fn u64(&mut self) -> Result<usize, DecodeError> {
        let mut b = [0u8; 8];
        b.copy_from_slice(self.take(8)?);
        usize::try_from(u64::from_le_bytes(b)).map_err(|_| DecodeError::Overflow)
    }
    fn f64s(&mut self, n: usize) -> Result<Vec<f64>, DecodeError> {
        let raw = self.take(n.checked_mul(8).ok_or(DecodeError::Overflow)?)?;
        Ok(raw
            .chunks_exact(8)
            .map(|c| {
                let mut b = [0u8; 8];
                b.copy_from_slice(c);
                f64::from_le_bytes(b)
            })
            .collect())
    }
}

fn decode(bytes: &[u8], key: &[u8; 32], settings: &BasisSettings) -> Result<Basis, DecodeError> {
    if bytes.len() < MAGIC.len() + 4 + 32 + 32 {
        return Err(DecodeError::TooShort);
    }
    let (body, sum) = bytes.split_at(bytes.len() - 32);
    let want: [u8; 32] = Sha256::digest(body).into();
    if sum != want {
        return Err(DecodeError::Checksum);
    }
    let mut r = Reader {
        bytes: body,
        pos: 0,
    };
    if r.take(MAGIC.len())? != MAGIC {
        return Err(DecodeError::Magic);
    }
    let version = r.u32()?;
    if version != VERSION {
        return Err(DecodeError::Version(version));
    }
    if r.take(32)? != key {
        return Err(DecodeError::Key);
    }
    let rows = r.u64()?;
    let k = r.u64()?;
    let n_mat = r.u64()?;
    let mut materials = Vec::new();
    for _ in 0..n_mat {
        let len = r.u32()? as usize;
        let name = std::str::from_utf8(r.take(len)?).map_err(|_| DecodeError::Name)?;
        materials.push(name.to_string());
    }
    let stride = GridStride {
        theta_h: r.u32()? as usize,
        theta_d: r.u32()? as usize,
        phi_d: r.u32()? as usize,
    };
    if stride != settings.stride {
        return Err(DecodeError::Stride);
    }
    let grid = BasisGrid::new(stride).map_err(DecodeError::Invalid)?;
    if grid.n_rows() != rows {
        return Err(DecodeError::Rows);
    }
    for &bin in grid.bins() {
        if r.u32()? as usize != bin {
            return Err(DecodeError::Bins);
        }
    }
    let cos_map = r.f64s(rows)?;
    let median = r.f64s(rows)?;
    let mean = r.f64s(rows)?;
    let singular_values = r.f64s(n_mat.checked_mul(3).ok_or(DecodeError::Overflow)?)?;
    let nq = rows.checked_mul(k).ok_or(DecodeError::Overflow)?;
    let q: Vec<f32> = r
        .take(nq.checked_mul(4).ok_or(DecodeError::Overflow)?)?
        .chunks_exact(4)
        .map(|c| {
            let mut b = [0u8; 4];
            b.copy_from_slice(c);
            f32::from_le_bytes(b)
        })
        .collect();
    if r.pos != body.len() {
        return Err(DecodeError::Trailing);
    }
    let basis = Basis {
        settings: settings.clone(),
        materials,
        grid,
        cos_map,
        median,
        mean,
        singular_values,
        q,
        k,
    };
    basis.validate().map_err(DecodeError::Invalid)?;
    Ok(basis)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::nbrdf;

    fn few() -> Vec<(String, Nbrdf)> {
        let dir = nbrdf::default_dir();
        ["blue-acrylic", "gold-paint", "pink-fabric", "teflon"]
            .iter()
            .map(|n| {
                let net = Nbrdf::load(&dir.join(format!("{n}.f32"))).expect("load");
                (n.to_string(), net)
            })
            .collect()
    }

    fn settings() -> BasisSettings {
        BasisSettings {
            stride: GridStride {
                theta_h: 6,
                theta_d: 10,
                phi_d: 20,
            },
            basis_components: 8,
            exclude: vec!["teflon".into()],
        }
    }

    #[test]
    fn builds_then_hits_then_rebuilds_a_corrupt_file() {
        let dir = tempfile::tempdir().expect("tmp");
        let mats = few();
        let s = settings();
        let (built, status) = load_or_build(&s, &mats, dir.path()).expect("build");
        let CacheStatus::Built(path) = status else {
            panic!("expected a fresh build, got {status:?}");
        };
        let (hit, status) = load_or_build(&s, &mats, dir.path()).expect("hit");
        assert_eq!(status, CacheStatus::Hit(path.clone()));
        assert_eq!(hit, built);
        assert_eq!(hit.materials().len(), 3);

        // Flip one byte in the middle: detected, rebuilt, identical result.
        let mut bytes = std::fs::read(&path).expect("read");
        let mid = bytes.len() / 2;
        bytes[mid] ^= 0x40;
        std::fs::write(&path, &bytes).expect("write");
        let (again, status) = load_or_build(&s, &mats, dir.path()).expect("rebuild");
        assert!(matches!(status, CacheStatus::Rebuilt { .. }), "{status:?}");
        assert_eq!(again, built);
        // Truncated: same.
        std::fs::write(&path, &bytes[..100]).expect("write");
        let (_, status) = load_or_build(&s, &mats, dir.path()).expect("rebuild");
        assert!(matches!(status, CacheStatus::Rebuilt { .. }));
    }

    #[test]
    fn key_depends_on_settings_and_materials() {
        let mats = few();
        let s = settings();
        let k0 = cache_key(&s, &mats);
        let mut s2 = s.clone();
        s2.exclude = vec!["pink-fabric".into()];
        assert_ne!(cache_key(&s2, &mats), k0);
        let mut s3 = s.clone();
        s3.basis_components = 9;
        assert_ne!(cache_key(&s3, &mats), k0);
        let mut s4 = s.clone();
        s4.stride.phi_d = 10;
        assert_ne!(cache_key(&s4, &mats), k0);
        let mut mats2 = few();
        // Dropping the excluded material changes nothing; dropping a used one does.
        mats2.truncate(3);
        assert_eq!(cache_key(&s, &mats2), k0);
        mats2.remove(1);
        assert_ne!(cache_key(&s, &mats2), k0);
        // A different file under the right name decodes as corrupt, never as a basis.
        let other = encode(
            &load_or_build(&s, &mats, tempfile::tempdir().expect("tmp").path())
                .expect("b")
                .0,
            &k0,
        );
        assert!(decode(&other, &cache_key(&s3, &mats), &s3).is_err());
    }
}
