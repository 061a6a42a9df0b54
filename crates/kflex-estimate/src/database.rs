//! IBJAE's feature databases on disk: one file per working band
//! (`band-000.kfdb`, `band-001.kfdb`, … in the bands' order, each a
//! [`FeatureIndex`] file with the band, grid, camera and SCNN in its
//! metadata), built over a camera's working regions by
//! [`build_databases`], written by [`save_databases`] (a whole directory or
//! nothing) and read by [`load_databases`], which refuses a database built
//! for another camera.

use std::path::{Path, PathBuf};

use kflex_model::{Camera, Instrument, WorkingRegions};

use crate::error::{EstimateError, Result};
use crate::ibjae::{BandDatabase, build_band_database, camera_key, check_camera};
use crate::index::FeatureIndex;
use crate::scnn::Scnn;

/// The extension of a band's database file.
pub const DATABASE_EXT: &str = "kfdb";

/// The file of a database directory that holds its count of bands (a
/// directory short of a band is an error, not fewer bands).
pub const MANIFEST: &str = "bands";

/// The file of band `i` in a database directory.
#[must_use]
pub fn database_file(dir: &Path, i: usize) -> PathBuf {
    dir.join(format!("band-{i:03}.{DATABASE_EXT}"))
}

/// The databases of every band of `regions`: the nominal `instrument`'s
/// silhouettes through `camera` on a grid of `theta_step_deg` ×
/// `translation_step_mm`, embedded by `scnn` ([`build_band_database`] per
/// band, in the bands' order).
///
/// # Errors
/// As [`build_band_database`].
pub fn build_databases(
    scnn: &mut Scnn,
    camera: &Camera,
    instrument: &Instrument,
    regions: &WorkingRegions,
    theta_step_deg: f64,
    translation_step_mm: f64,
) -> Result<Vec<BandDatabase>> {
    regions
        .bands()
        .iter()
        .map(|band| {
            build_band_database(
                scnn,
                camera,
                instrument,
                band,
                theta_step_deg,
                translation_step_mm,
            )
        })
        .collect()
}

/// Writes `bands` into the directory `dir` as `band-000.kfdb`, … and their
/// count ([`MANIFEST`]): first into a new directory beside it, which then
/// takes `dir`'s place, so `dir` holds either the old databases or all the
/// new ones, never a mixture (between the two renames `dir` is briefly
/// absent; a crash there leaves the old databases in `.NAME.old-PID` beside
/// it); files of `dir` that are not databases are kept.
///
/// # Errors
/// [`EstimateError::Io`] naming the file or directory that could not be
/// written or moved (the new directory is removed again), or kind
/// `InvalidInput` for a `dir` that is a file, has no name of its own (`.`,
/// `..`, `/`) or holds a directory; [`EstimateError::NoBandDatabase`] for no bands.
pub fn save_databases(dir: &Path, bands: &[BandDatabase]) -> Result<()> {
    if bands.is_empty() {
        return Err(EstimateError::NoBandDatabase);
    }
    write_databases(dir, bands)
}

/// Whether [`save_databases`] could write into `dir`, asked before the work
/// that makes the databases: `dir` passes its checks, and the directory
/// beside it that the new databases are first written into can be made
/// (it is removed again).
///
/// # Errors
/// As [`save_databases`] for `dir` and for making that directory.
pub fn check_database_dir(dir: &Path) -> Result<()> {
    let (fresh, _) = swap_names(dir)?;
    refuse_subdirectories(dir)?;
    if let Some(p) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(p).map_err(|e| EstimateError::io(p, &e))?;
    }
    let _ = std::fs::remove_dir_all(&fresh);
    std::fs::create_dir(&fresh).map_err(|e| EstimateError::io(&fresh, &e))?;
    let _ = std::fs::remove_dir_all(&fresh);
    Ok(())
}

/// The directories beside `dir` that [`save_databases`] writes the new
/// databases into and moves the old ones to, after checking `dir` can be
/// swapped whole.
fn swap_names(dir: &Path) -> Result<(PathBuf, PathBuf)> {
    let refuse = |message: &str| EstimateError::Io {
        path: dir.to_path_buf(),
        kind: std::io::ErrorKind::InvalidInput,
        message: message.to_string(),
    };
    // the directory is swapped whole, so it must have a name of its own
    let Some(name) = dir.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return Err(refuse(
            "not a directory by name (`.`, `..` or `/`): give the databases' own directory",
        ));
    };
    if dir.exists() && !dir.is_dir() {
        return Err(refuse("exists and is not a directory"));
    }
    let parent = dir.parent().filter(|p| !p.as_os_str().is_empty());
    let sibling = |tag: &str| {
        let n = format!(".{name}.{tag}-{}", std::process::id());
        parent.map_or_else(|| PathBuf::from(&n), |p| p.join(&n))
    };
    Ok((sibling("new"), sibling("old")))
}

/// An error about a file of the hidden new directory `fresh`, named as the
/// file it was to become in `dir` (a user knows `db/band-002.kfdb`, not
/// `.db.new-888/band-002.kfdb`).
fn as_final(e: EstimateError, fresh: &Path, dir: &Path) -> EstimateError {
    match e {
        EstimateError::Io {
            path,
            kind,
            message,
        } => {
            let named = path.strip_prefix(fresh).ok().map(|rest| dir.join(rest));
            EstimateError::Io {
                path: named.unwrap_or(path),
                kind,
                message,
            }
        }
        e => e,
    }
}

/// The error for a directory found inside the databases' directory, which
/// is replaced whole.
fn subdirectory(path: PathBuf) -> EstimateError {
    EstimateError::Io {
        path,
        kind: std::io::ErrorKind::InvalidInput,
        message: "a directory inside the databases' directory: move it out first (the \
                  databases' directory is replaced whole)"
            .into(),
    }
}

/// Refuses a `dir` that holds a directory (none yet is fine).
fn refuse_subdirectories(dir: &Path) -> Result<()> {
    if !dir.is_dir() {
        return Ok(());
    }
    for entry in std::fs::read_dir(dir).map_err(|e| EstimateError::io(dir, &e))? {
        let path = entry.map_err(|e| EstimateError::io(dir, &e))?.path();
        if path.is_dir() {
            return Err(subdirectory(path));
        }
    }
    Ok(())
}

fn write_databases(dir: &Path, bands: &[BandDatabase]) -> Result<()> {
    let (fresh, old) = swap_names(dir)?;
    let parent = dir.parent().filter(|p| !p.as_os_str().is_empty());
    fn io(path: &Path) -> impl Fn(std::io::Error) -> EstimateError + '_ {
        move |e| EstimateError::io(path, &e)
    }
    let _ = std::fs::remove_dir_all(&fresh);
    if let Some(p) = parent {
        std::fs::create_dir_all(p).map_err(io(p))?;
    }
    std::fs::create_dir(&fresh).map_err(io(&fresh))?;
    let written = (|| -> Result<()> {
        for (i, b) in bands.iter().enumerate() {
            b.index.save(database_file(&fresh, i))?;
        }
        let manifest = fresh.join(MANIFEST);
        std::fs::write(&manifest, format!("{}\n", bands.len())).map_err(io(&manifest))?;
        // what else the old directory holds (a README, a card) stays
        if dir.is_dir() {
            for entry in std::fs::read_dir(dir).map_err(io(dir))? {
                let entry = entry.map_err(io(dir))?;
                let path = entry.path();
                // a directory first, whatever its name (`archive.kfdb/` is
                // not a database and would go with the old directory)
                if path.is_dir() {
                    return Err(subdirectory(path));
                }
                let ours = path.extension().and_then(|e| e.to_str()) == Some(DATABASE_EXT)
                    || entry.file_name() == MANIFEST;
                if ours {
                    continue;
                }
                let to = fresh.join(entry.file_name());
                std::fs::copy(&path, &to).map_err(io(&path))?;
            }
        }
        Ok(())
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_dir_all(&fresh);
        return Err(as_final(e, &fresh, dir));
    }
    // the swap: the old directory aside, the new one in its place
    let had_old = dir.exists();
    if had_old {
        std::fs::rename(dir, &old).map_err(|e| {
            let _ = std::fs::remove_dir_all(&fresh);
            EstimateError::io(dir, &e)
        })?;
    }
    if let Err(e) = std::fs::rename(&fresh, dir) {
        if had_old {
            let _ = std::fs::rename(&old, dir);
        }
        let _ = std::fs::remove_dir_all(&fresh);
        return Err(EstimateError::io(dir, &e));
    }
    if had_old {
        let _ = std::fs::remove_dir_all(&old);
    }
    Ok(())
}

/// The most band databases a directory may hold ([`load_databases`]; the
/// full range has 28).
pub const MAX_BANDS: usize = 10_000;

/// Reads the databases of `dir` (as many as its [`MANIFEST`] counts,
/// `band-000.kfdb`, …), each checked against `camera`: a database rendered
/// through another camera (intrinsics, lens or mounting) would answer for
/// silhouettes that camera sees, not this one's.
///
/// # Errors
/// [`EstimateError::Io`] when the manifest or a band's file is missing (kind
/// `NotFound`) or cannot be read; [`EstimateError::ModelFile`] for a
/// manifest that is not a count of 1 to 10,000; as [`FeatureIndex::load`] and
/// [`BandDatabase::from_index`] for a damaged file;
/// [`EstimateError::ModelMismatch`] naming both cameras for a database
/// built for another camera.
pub fn load_databases(dir: &Path, camera: &Camera) -> Result<Vec<BandDatabase>> {
    let expected = camera_key(camera);
    let manifest = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&manifest).map_err(|e| EstimateError::io(&manifest, &e))?;
    let count: usize = text
        .trim()
        .parse()
        .ok()
        .filter(|&n| (1..=MAX_BANDS).contains(&n))
        .ok_or_else(|| EstimateError::ModelFile {
            path: manifest.display().to_string(),
            message: format!("not a count of bands (1 to {MAX_BANDS}): {:?}", text.trim()),
        })?;
    let mut bands = Vec::with_capacity(count);
    for i in 0..count {
        let path = database_file(dir, i);
        let index = FeatureIndex::load(&path)?;
        check_camera(&index, &expected, &path.display().to_string())?;
        bands.push(BandDatabase::from_index(index)?);
    }
    Ok(bands)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_of_the_new_copy_is_named_as_the_file_it_becomes() {
        let (dir, fresh) = (Path::new("/data/db"), Path::new("/data/.db.new-888"));
        let io = |path: &str| EstimateError::Io {
            path: PathBuf::from(path),
            kind: std::io::ErrorKind::StorageFull,
            message: "No space left on device (os error 28)".into(),
        };
        let named = |e: EstimateError| match e {
            EstimateError::Io { path, .. } => path,
            e => panic!("{e}"),
        };
        assert_eq!(
            named(as_final(io("/data/.db.new-888/band-002.kfdb"), fresh, dir)),
            Path::new("/data/db/band-002.kfdb")
        );
        assert_eq!(named(as_final(io("/data/.db.new-888"), fresh, dir)), dir);
        // a file elsewhere keeps its name, and other errors pass as they are
        assert_eq!(
            named(as_final(io("/data/db/README"), fresh, dir)),
            Path::new("/data/db/README")
        );
        assert!(matches!(
            as_final(EstimateError::NoBandDatabase, fresh, dir),
            EstimateError::NoBandDatabase
        ));
    }
}
