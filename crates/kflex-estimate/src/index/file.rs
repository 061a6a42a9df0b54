//! The database file: a versioned, checksummed little-endian binary of the
//! features, their poses, the projection and free-form metadata (layout:
//! [`FeatureIndex::save`]).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use super::{FeatureIndex, IndexParams, Pose, ProjectionDims, Search};
use crate::error::{EstimateError, Result};

/// Magic bytes at the start of every feature-index file.
const MAGIC: [u8; 8] = *b"KFLEXIDX";

/// The database file format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;

/// Bytes of the fixed header (magic to metadata length).
const HEADER_BYTES: usize = 40;

/// Bytes of the trailing checksum.
const CHECKSUM_BYTES: usize = 8;

/// The integrity hash of `bytes` (see the module docs).
fn checksum(bytes: &[u8]) -> u64 {
    const MUL: u64 = 0x9E37_79B9_7F4A_7C15;
    let step = |h: u64, w: u64| (h ^ w).wrapping_mul(MUL).rotate_left(29);
    let mut h = 0x6b66_6c65_7869_6478_u64 ^ bytes.len() as u64;
    let words = bytes.chunks_exact(8);
    let tail = words.remainder();
    for w in words {
        h = step(h, u64::from_le_bytes(w.try_into().expect("8 bytes")));
    }
    if !tail.is_empty() {
        let mut last = [0_u8; 8];
        last[..tail.len()].copy_from_slice(tail);
        h = step(h, u64::from_le_bytes(last));
    }
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^ (h >> 33)
}

/// The metadata block.
fn encode_metadata(metadata: &BTreeMap<String, String>) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend((metadata.len() as u32).to_le_bytes());
    for (k, v) in metadata {
        for s in [k, v] {
            out.extend((s.len() as u32).to_le_bytes());
            out.extend(s.as_bytes());
        }
    }
    out
}

impl FeatureIndex {
    /// The database file's bytes, as [`FeatureIndex::save`] writes them
    /// (layout there).
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        let meta = encode_metadata(&self.metadata);
        let n = self.len();
        let dim = self.dim;
        let dims = self.projection.get();
        let floats = dim + dims * dim + n * dim;
        let mut out =
            Vec::with_capacity(HEADER_BYTES + meta.len() + 4 * floats + 16 * n + CHECKSUM_BYTES);
        out.extend(MAGIC);
        out.extend(FORMAT_VERSION.to_le_bytes());
        out.extend((dim as u32).to_le_bytes());
        out.extend((dims as u32).to_le_bytes());
        out.extend(0_u32.to_le_bytes());
        out.extend((n as u64).to_le_bytes());
        out.extend((meta.len() as u64).to_le_bytes());
        out.extend(&meta);
        for v in self.mean.iter().chain(&self.axes).chain(&self.features) {
            out.extend(v.to_le_bytes());
        }
        for p in &self.poses {
            out.extend(p.theta_deg.to_le_bytes());
            out.extend(p.translation_mm.to_le_bytes());
        }
        out.extend(checksum(&out).to_le_bytes());
        out
    }

    /// Writes the index to `path` atomically: into a temporary file beside
    /// it, flushed to disk, then renamed over `path`, so a reader sees the old
    /// file or the new one, never half of one.
    ///
    /// # Format
    ///
    /// Layout, version 1 (all integers and floats little-endian):
    ///
    /// | bytes | what |
    /// |---|---|
    /// | 8 | magic `KFLEXIDX` |
    /// | 4 | format version, `u32` (1) |
    /// | 4 | `D`, feature dimension, `u32` |
    /// | 4 | `K`, projection width, `u32` (8, 12 or 16) |
    /// | 4 | flags, `u32`, 0 |
    /// | 8 | `N`, points, `u64` |
    /// | 8 | metadata block length in bytes, `u64` |
    /// | … | metadata: count `u32`, then per entry key length `u32`, key (UTF-8), value length `u32`, value (UTF-8) |
    /// | 4·D | mean, f32 |
    /// | 4·K·D | principal axes, row-major f32 |
    /// | 4·N·D | features, row-major f32 |
    /// | 16·N | poses: `theta_deg`, `translation_mm`, f64 each |
    /// | 8 | checksum of every byte before it, `u64` |
    ///
    /// The checksum mixes the file eight bytes at a time through a chain of
    /// bijections (xor, multiply by an odd constant, rotate), so any change
    /// confined to one 8-byte word — every single-bit flip — always changes it;
    /// other damage escapes with probability about 2⁻⁶⁴. It guards against
    /// damage, not against forgery. The sizes the header declares are checked
    /// against the file's length before anything is allocated, so a corrupt
    /// header cannot ask for memory the file does not hold.
    ///
    /// # Errors
    /// [`EstimateError::Io`] when the file cannot be written (no such
    /// directory, no permission, disk full); the temporary file is removed.
    /// [`EstimateError::Length`] for a dimension or a metadata string beyond
    /// the format's `u32` fields.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let too_long = self
            .metadata
            .iter()
            .flat_map(|(k, v)| [k.len(), v.len()])
            .chain([self.dim, self.metadata.len()])
            .find(|len| u32::try_from(*len).is_err());
        if let Some(got) = too_long {
            return Err(EstimateError::Length {
                what: "dimension, metadata entries or metadata string (a u32 in the file)",
                expected: u32::MAX as usize,
                got,
            });
        }
        let bytes = self.to_bytes();
        let tmp = temp_path(path);
        let written = (|| {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(&bytes)?;
            f.sync_all()?;
            std::fs::rename(&tmp, path)
        })();
        written.map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            EstimateError::io(path, &e)
        })
    }

    /// Reads an index written by [`FeatureIndex::save`] and rebuilds its
    /// k-d tree (the stored projection is reused, not recomputed): tens of
    /// milliseconds for 20,000 points of 256 dimensions. The search stays
    /// exact whatever projection the file holds (the bound is recomputed from
    /// the stored axes).
    ///
    /// # Errors
    /// * [`EstimateError::Io`] when the file cannot be read (`kind`
    ///   [`std::io::ErrorKind::NotFound`] when it does not exist);
    /// * [`EstimateError::IndexVersion`] for a format version other than
    ///   [`FORMAT_VERSION`];
    /// * [`EstimateError::IndexCorrupt`] for anything else wrong: not a
    ///   feature-index file, truncated or with trailing bytes, a checksum
    ///   mismatch, an unsupported projection width, metadata that is not
    ///   UTF-8, or values an index cannot hold (NaN, no points).
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| EstimateError::io(path, &e))?;
        Self::parse(&bytes, path)
    }

    /// [`FeatureIndex::load`] from bytes already in memory (an embedded
    /// asset, a buffer from elsewhere); errors name the path `<memory>`.
    ///
    /// # Errors
    /// As [`FeatureIndex::load`], but never [`EstimateError::Io`].
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        Self::parse(bytes, Path::new("<memory>"))
    }

    /// Parses the bytes of a feature-index file; `path` names it in errors.
    fn parse(bytes: &[u8], path: &Path) -> Result<Self> {
        let corrupt = |reason: String| EstimateError::IndexCorrupt {
            path: path.to_path_buf(),
            reason,
        };
        if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
            return Err(corrupt(format!(
                "the file does not start with the magic bytes {:?} ({} bytes long)",
                String::from_utf8_lossy(&MAGIC),
                bytes.len()
            )));
        }
        if bytes.len() < HEADER_BYTES + CHECKSUM_BYTES {
            return Err(corrupt(format!(
                "truncated: {} bytes, shorter than the {}-byte header and checksum",
                bytes.len(),
                HEADER_BYTES + CHECKSUM_BYTES
            )));
        }
        let mut r = Reader { bytes, at: 8 };
        let version = r.u32();
        if version != FORMAT_VERSION {
            return Err(EstimateError::IndexVersion {
                path: path.to_path_buf(),
                found: version,
                supported: FORMAT_VERSION,
            });
        }
        let (dim, dims, flags, n, meta_len) = (r.u32(), r.u32(), r.u32(), r.u64(), r.u64());
        let expected = expected_len(dim, dims, n, meta_len);
        if expected != Some(bytes.len() as u128) {
            return Err(corrupt(match expected {
                Some(e) => format!(
                    "{} bytes, but its header (N = {n}, D = {dim}, K = {dims}, {meta_len} bytes of metadata) needs {e}{}",
                    bytes.len(),
                    if (bytes.len() as u128) < e {
                        " (truncated)"
                    } else {
                        " (trailing bytes)"
                    }
                ),
                None => format!("its header declares an impossible size (N = {n}, D = {dim})"),
            }));
        }
        let body = bytes.len() - CHECKSUM_BYTES;
        let stored = u64::from_le_bytes(bytes[body..].try_into().expect("8 bytes"));
        if checksum(&bytes[..body]) != stored {
            return Err(corrupt(
                "checksum mismatch: the file is damaged".to_string(),
            ));
        }
        if flags != 0 {
            return Err(corrupt(format!("unknown flags {flags:#x}")));
        }
        let projection = ProjectionDims::from_count(dims as usize)
            .ok_or_else(|| corrupt(format!("projection width K = {dims}, expected 8, 12 or 16")))?;
        let (dim, n) = (dim as usize, n as usize);
        let meta_end = r.at + meta_len as usize;
        let metadata = decode_metadata(&bytes[r.at..meta_end]).map_err(corrupt)?;
        r.at = meta_end;
        let mean = r.f32s(dim);
        let axes = r.f32s(dims as usize * dim);
        let features = r.f32s(n * dim);
        let poses = (0..n)
            .map(|_| Pose {
                theta_deg: r.f64(),
                translation_mm: r.f64(),
            })
            .collect();
        for (what, values) in [("mean", &mean), ("principal axes", &axes)] {
            if let Some(v) = values.iter().find(|v| !v.is_finite()) {
                return Err(corrupt(format!("the {what} hold a non-finite value ({v})")));
            }
        }
        Self::from_parts(
            features,
            dim,
            poses,
            IndexParams {
                projection_dims: projection,
                search: Search::Auto,
            },
            Some((mean, axes)),
            metadata,
        )
        .map_err(|e| corrupt(e.to_string()))
    }
}

/// The file length a header declares, if it fits in `u128` arithmetic
/// (it always does for `u32`/`u64` fields).
fn expected_len(dim: u32, dims: u32, n: u64, meta_len: u64) -> Option<u128> {
    let (dim, dims, n, meta_len) = (
        u128::from(dim),
        u128::from(dims),
        u128::from(n),
        u128::from(meta_len),
    );
    let floats = dim
        .checked_mul(1 + dims)?
        .checked_add(n.checked_mul(dim)?)?;
    Some((HEADER_BYTES + CHECKSUM_BYTES) as u128 + meta_len + 4 * floats + 16 * n)
}

/// The metadata entries of a metadata block, or why it is malformed.
fn decode_metadata(block: &[u8]) -> std::result::Result<BTreeMap<String, String>, String> {
    let mut at = 0_usize;
    let mut take = |len: usize| -> std::result::Result<&[u8], String> {
        let end = at
            .checked_add(len)
            .filter(|end| *end <= block.len())
            .ok_or_else(|| "the metadata block ends inside an entry".to_string())?;
        let s = &block[at..end];
        at = end;
        Ok(s)
    };
    let word = |s: &[u8]| u32::from_le_bytes(s.try_into().expect("4 bytes")) as usize;
    let count = word(take(4)?);
    let mut out = BTreeMap::new();
    for _ in 0..count {
        let mut entry = [String::new(), String::new()];
        for s in &mut entry {
            let len = word(take(4)?);
            *s = String::from_utf8(take(len)?.to_vec())
                .map_err(|_| "a metadata string is not UTF-8".to_string())?;
        }
        let [k, v] = entry;
        if out.insert(k.clone(), v).is_some() {
            return Err(format!("metadata key {k:?} appears twice"));
        }
    }
    if at != block.len() {
        return Err("trailing bytes after the metadata entries".to_string());
    }
    Ok(out)
}

/// A cursor over bytes whose length was checked beforehand.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const W: usize>(&mut self) -> [u8; W] {
        let out = self.bytes[self.at..self.at + W]
            .try_into()
            .expect("length checked against the header");
        self.at += W;
        out
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
    fn f32s(&mut self, count: usize) -> Vec<f32> {
        let end = self.at + 4 * count;
        let out = self.bytes[self.at..end]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect();
        self.at = end;
        out
    }
}

/// The temporary file `save` writes before renaming: beside `path` (same
/// file system, so the rename is atomic), named after it and this process.
fn temp_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".tmp{}", std::process::id()));
    path.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checksum_sees_every_single_bit_flip() {
        let bytes: Vec<u8> = (0..37_u8).map(|b| b.wrapping_mul(91)).collect();
        let h = checksum(&bytes);
        for i in 0..bytes.len() * 8 {
            let mut b = bytes.clone();
            b[i / 8] ^= 1 << (i % 8);
            assert_ne!(checksum(&b), h, "bit {i}");
        }
        assert_ne!(checksum(&bytes[..36]), h);
    }

    #[test]
    fn metadata_round_trips() {
        let mut m = BTreeMap::new();
        m.insert("model_sha256".to_string(), "ab".repeat(32));
        m.insert("camera".to_string(), "v2, 640×480".to_string());
        m.insert(String::new(), String::new());
        assert_eq!(decode_metadata(&encode_metadata(&m)), Ok(m));
        assert!(decode_metadata(&[1, 0, 0, 0, 9, 0, 0, 0]).is_err());
        assert!(decode_metadata(&[]).is_err());
    }
}
