//! What both kinds of `kflex-cli run` print and write: the definitions of
//! the maximum hysteresis's readings, figures as `mean ± std`, and result
//! files written whole or not at all.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// The maximum hysteresis as kflex measures it (the calibrated reading).
pub(crate) const WIDTH_DEFINITION: &str = "hysteresis loop width: largest gap between the falling- and rising-branch mean of the measured angle at equal command, 1-deg bins of theta_d";
/// The error's peak-to-peak, the paper's literal wording.
pub(crate) const PEAK_TO_PEAK_DEFINITION: &str =
    "max e - min e, e = measured angle - theta_d (the paper's literal wording)";
/// The peak loss.
pub(crate) const PEAK_LOSS_DEFINITION: &str = "max theta_d - max measured angle";

/// `mean ± std` in a fixed width.
pub(crate) fn pm(mean: f64, std: f64) -> String {
    format!("{mean:6.2} ± {std:4.2}")
}

/// A paper figure as [`pm`], or a dash where the paper has none.
pub(crate) fn paper_pm(mean: Option<f64>, std: Option<f64>) -> String {
    match (mean, std) {
        (Some(m), Some(s)) => pm(m, s),
        _ => format!("{:>13}", "—"),
    }
}

/// Makes sure the results can be written to `dir` before any work: creates
/// it, then a file in it, which it removes.
pub(crate) fn check_writable(dir: &Path) -> Result<()> {
    let fail = |e: std::io::Error| {
        anyhow::Error::new(e).context(format!(
            "the output directory {} cannot be written (checked before running)",
            dir.display()
        ))
    };
    std::fs::create_dir_all(dir).map_err(fail)?;
    let probe = dir.join(format!(".kflex-write-check-{}", std::process::id()));
    std::fs::File::create(&probe).map_err(fail)?;
    std::fs::remove_file(&probe).map_err(fail)
}

/// Writes `dir/name` atomically: a temporary file in the same folder, then a
/// rename, so a reader never sees half a file and an old file survives a
/// failed write. A newline ends the file.
pub(crate) fn write_atomic(dir: &Path, name: &str, contents: &str) -> Result<PathBuf> {
    if contents.ends_with('\n') {
        write_atomic_bytes(dir, name, contents.as_bytes())
    } else {
        write_atomic_bytes(dir, name, format!("{contents}\n").as_bytes())
    }
}

/// Writes the bytes `contents` to `dir/name` atomically, as [`write_atomic`].
pub(crate) fn write_atomic_bytes(dir: &Path, name: &str, contents: &[u8]) -> Result<PathBuf> {
    let paths = write_atomic_set(dir, &[(name, contents)])?;
    Ok(paths.into_iter().next().unwrap_or_else(|| dir.join(name)))
}

/// A file name in `dir` of this process's and this call's own, from `name`
/// and `tag`: two runs writing into one directory never touch each other's.
fn own_name(dir: &Path, name: &str, tag: &str) -> PathBuf {
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    dir.join(format!(".{name}.{}-{call}.{tag}", std::process::id()))
}

/// Writes several files of `dir` (name, bytes) as one: every file is first
/// written in full beside its place, then all are moved in. A failed write
/// leaves every old file as it was; a failed move (rare: the files are in
/// one folder) puts back the ones already moved, from links to the old
/// files made before, so the set is never a mixture of two runs'.
pub(crate) fn write_atomic_set(dir: &Path, files: &[(&str, &[u8])]) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let paths: Vec<PathBuf> = files.iter().map(|(name, _)| dir.join(name)).collect();
    let mut temps: Vec<PathBuf> = Vec::with_capacity(files.len());
    let cleanup = |temps: &[PathBuf]| temps.iter().for_each(|t| drop(std::fs::remove_file(t)));
    for ((name, contents), path) in files.iter().zip(&paths) {
        let tmp = own_name(dir, name, "tmp");
        let written = (|| -> std::io::Result<()> {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(contents)?;
            f.sync_all()
        })();
        temps.push(tmp);
        if let Err(e) = written {
            cleanup(&temps);
            return Err(e).with_context(|| format!("writing {}", path.display()));
        }
    }
    // the old files kept under links of their own until all are moved in
    // (with whether there was one: a file that cannot be linked stays)
    let mut kept: Vec<(Option<PathBuf>, bool)> = Vec::with_capacity(files.len());
    for ((name, _), path) in files.iter().zip(&paths) {
        let link = own_name(dir, name, "old");
        let linked = std::fs::hard_link(path, &link).is_ok();
        kept.push((linked.then_some(link), path.exists()));
    }
    let mut moved = 0;
    let mut failure = None;
    for (tmp, path) in temps.iter().zip(&paths) {
        if let Err(e) = std::fs::rename(tmp, path) {
            failure = Some((e, path.clone()));
            break;
        }
        moved += 1;
    }
    if let Some((e, path)) = failure {
        for ((old, existed), path) in kept.iter().zip(&paths).take(moved) {
            match old {
                Some(old) => drop(std::fs::rename(old, path)),
                None if !existed => drop(std::fs::remove_file(path)),
                None => {}
            }
        }
        cleanup(&temps[moved..]);
        let links: Vec<PathBuf> = kept.into_iter().filter_map(|k| k.0).collect();
        cleanup(&links);
        return Err(e).with_context(|| format!("writing {}", path.display()));
    }
    let links: Vec<PathBuf> = kept.into_iter().filter_map(|k| k.0).collect();
    cleanup(&links);
    Ok(paths)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("kflex-output-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    fn read(dir: &Path, name: &str) -> String {
        std::fs::read_to_string(dir.join(name)).unwrap()
    }

    #[test]
    fn a_set_of_files_is_written_whole_or_not_at_all() {
        let dir = scratch("set");
        write_atomic_set(&dir, &[("a.json", b"old a"), ("b.csv", b"old b")]).unwrap();
        write_atomic_set(&dir, &[("a.json", b"new a"), ("b.csv", b"new b")]).unwrap();
        assert_eq!(
            (read(&dir, "a.json"), read(&dir, "b.csv")),
            ("new a".into(), "new b".into())
        );
        assert_eq!(
            names(&dir),
            ["a.json", "b.csv"],
            "no temporary file or link left"
        );
        // the second cannot be written (its folder is missing): the first is
        // not replaced either
        let e = write_atomic_set(&dir, &[("a.json", b"third a"), ("no/b.csv", b"third b")]);
        assert!(format!("{:#}", e.unwrap_err()).contains("no/b.csv"));
        assert_eq!(read(&dir, "a.json"), "new a");
        assert_eq!(names(&dir), ["a.json", "b.csv"]);
        // the second cannot be moved in (a folder holds its place): the first,
        // already moved, is put back, and a file new to the folder removed
        std::fs::remove_file(dir.join("b.csv")).unwrap();
        std::fs::create_dir(dir.join("b.csv")).unwrap();
        std::fs::write(dir.join("b.csv").join("inside"), "x").unwrap();
        let e = write_atomic_set(
            &dir,
            &[
                ("c.txt", b"fresh c"),
                ("a.json", b"fourth a"),
                ("b.csv", b"fourth b"),
            ],
        );
        assert!(format!("{:#}", e.unwrap_err()).contains("b.csv"));
        assert_eq!(read(&dir, "a.json"), "new a");
        assert_eq!(names(&dir), ["a.json", "b.csv"], "c.txt taken out again");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
