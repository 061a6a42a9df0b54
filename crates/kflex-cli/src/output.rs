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

/// The folders [`make_dirs`] made, outermost first: a command that
/// then fails removes those still empty ([`remove_made_if_empty`]), so a
/// refused argument leaves no empty output folder behind.
static MADE: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Makes sure the results can be written to `dir` before any work: creates
/// it, then a file in it, which it removes; and none of the files `names`
/// the command will write there is held by something that is not a file
/// (a folder called `results.json` would stop the writing at the end).
pub(crate) fn check_writable(dir: &Path, names: &[&str]) -> Result<()> {
    let fail = |e: std::io::Error| {
        anyhow::Error::new(e).context(format!(
            "the output directory {} cannot be written (checked before running)",
            dir.display()
        ))
    };
    make_dirs(dir).map_err(fail)?;
    let probe = dir.join(format!(".kflex-write-check-{}", std::process::id()));
    std::fs::File::create(&probe).map_err(fail)?;
    std::fs::remove_file(&probe).map_err(fail)?;
    for name in names {
        let path = dir.join(name);
        if let Ok(meta) = std::fs::symlink_metadata(&path)
            && !meta.is_file()
            && !meta.file_type().is_symlink()
        {
            return Err(fail(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "{} is there and is not a file: the results would replace it; move it away",
                    path.display()
                ),
            )));
        }
    }
    Ok(())
}

/// Makes `dir` and the folders above it that are missing, outermost first,
/// one at a time, and records those this call made (only where making one
/// succeeded: a folder that was there, or that another process made
/// meanwhile, is never recorded), for [`remove_made_if_empty`].
pub(crate) fn make_dirs(dir: &Path) -> std::io::Result<()> {
    let chain: Vec<&Path> = dir
        .ancestors()
        .filter(|p| !p.as_os_str().is_empty())
        .collect();
    for p in chain.into_iter().rev() {
        match std::fs::create_dir(p) {
            Ok(()) => {
                if let Ok(mut made) = MADE.lock() {
                    made.push(p.to_path_buf());
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && p.is_dir() => {}
            // a file where a folder must go, this one or one above: say so
            // ("File exists" and "Not a directory" do not say which)
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => return Err(not_a_folder(p)),
            Err(e) if e.kind() == std::io::ErrorKind::NotADirectory => {
                return Err(match p.ancestors().skip(1).find(|a| a.is_file()) {
                    Some(file) => not_a_folder(file),
                    None => e,
                });
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// The error for a file at `path` where a folder must go.
fn not_a_folder(path: &Path) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::NotADirectory,
        format!("{} is a file, not a folder", path.display()),
    )
}

/// Removes the folders [`make_dirs`] made that are still empty,
/// innermost first (a folder that holds anything stays): called when a
/// command fails.
pub(crate) fn remove_made_if_empty() {
    if let Ok(made) = MADE.lock() {
        for dir in made.iter().rev() {
            // fails, harmlessly, where the folder is not empty
            let _ = std::fs::remove_dir(dir);
        }
    }
}

/// Raw 8-bit pixels (`color` `Rgb8` or `L8`, rows of `width`) encoded as
/// PNG in memory, `name` saying which file in an error; pixels that do not
/// fill `width × height` are an error.
pub(crate) fn encode_png(
    name: &str,
    pixels: &[u8],
    width: u32,
    height: u32,
    color: image::ExtendedColorType,
) -> Result<Vec<u8>> {
    use image::ImageEncoder;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(pixels, width, height, color)
        .with_context(|| format!("encoding {name}"))?;
    Ok(png)
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
/// written in full beside its place, and every file it replaces is kept
/// under a name of its own (a hard link, else a copy); only then are all
/// moved in. A failed write, or an old file that cannot be kept, leaves
/// every old file as it was; a failed move (rare: the files are in one
/// folder) puts back the ones already replaced, so the set is never a
/// mixture of two runs'. An old file that cannot be put back stays under
/// the name the error gives.
pub(crate) fn write_atomic_set(dir: &Path, files: &[(&str, &[u8])]) -> Result<Vec<PathBuf>> {
    make_dirs(dir).with_context(|| format!("creating {}", dir.display()))?;
    let paths: Vec<PathBuf> = files.iter().map(|(name, _)| dir.join(name)).collect();
    let remove = |paths: &[PathBuf]| paths.iter().for_each(|p| drop(std::fs::remove_file(p)));
    let mut temps: Vec<PathBuf> = Vec::with_capacity(files.len());
    for ((name, contents), path) in files.iter().zip(&paths) {
        let tmp = own_name(dir, name, "tmp");
        let written = (|| -> std::io::Result<()> {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(contents)?;
            f.sync_all()
        })();
        temps.push(tmp);
        if let Err(e) = written {
            remove(&temps);
            return Err(e).with_context(|| format!("writing {}", path.display()));
        }
    }
    // every file to be replaced kept first (`None`: there is none)
    let mut kept: Vec<Option<PathBuf>> = Vec::with_capacity(files.len());
    for ((name, _), path) in files.iter().zip(&paths) {
        if std::fs::symlink_metadata(path).is_err() {
            kept.push(None);
            continue;
        }
        match keep_aside(dir, name, path) {
            Ok(old) => kept.push(Some(old)),
            Err(e) => {
                remove(&temps);
                remove(&kept.iter().flatten().cloned().collect::<Vec<_>>());
                return Err(e)
                    .with_context(|| format!("keeping {} before replacing it", path.display()));
            }
        }
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
    let Some((e, path)) = failure else {
        remove(&kept.into_iter().flatten().collect::<Vec<_>>());
        return Ok(paths);
    };
    // put back what was replaced; an old file that will not go back stays
    let mut stranded = Vec::new();
    for (old, path) in kept.iter().zip(&paths).take(moved) {
        match old {
            Some(old) => {
                if std::fs::rename(old, path).is_err() {
                    stranded.push(format!(
                        "the old {} is kept as {}",
                        path.display(),
                        old.display()
                    ));
                }
            }
            None => drop(std::fs::remove_file(path)),
        }
    }
    remove(&temps[moved..]);
    remove(&kept[moved..].iter().flatten().cloned().collect::<Vec<_>>());
    let note = if stranded.is_empty() {
        String::new()
    } else {
        format!(" ({})", stranded.join("; "))
    };
    Err(e).with_context(|| format!("writing {}{note}", path.display()))
}

/// Keeps the file `path` under a name of its own in `dir` (from `name`): a
/// hard link, else (no links on this file system) a copy.
fn keep_aside(dir: &Path, name: &str, path: &Path) -> std::io::Result<PathBuf> {
    let mut last = None;
    // a name a crashed run left behind is passed over
    for _ in 0..64 {
        let old = own_name(dir, name, "old");
        if std::fs::symlink_metadata(&old).is_ok() {
            continue;
        }
        match std::fs::hard_link(path, &old) {
            Ok(()) => return Ok(old),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(_) => return std::fs::copy(path, &old).map(|_| old),
        }
    }
    Err(last.unwrap_or_else(|| std::io::Error::other("no free name to keep the old file under")))
}

/// The files in `dir` whose extension is one of `exts` and that are not in
/// `written`, sorted by name (none when `dir` cannot be read).
pub fn files_besides(dir: &Path, exts: &[&str], written: &[PathBuf]) -> Vec<PathBuf> {
    let ours: std::collections::HashSet<&std::ffi::OsStr> =
        written.iter().filter_map(|p| p.file_name()).collect();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut others: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.extension()
                    .is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x)))
                && p.file_name().is_some_and(|n| !ours.contains(n))
        })
        .collect();
    others.sort();
    others
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
        // the second's old file cannot be kept (a folder holds its place):
        // nothing is moved in, and a file new to the folder is not made
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
        let message = format!("{:#}", e.unwrap_err());
        assert!(
            message.contains("keeping") && message.contains("b.csv"),
            "{message}"
        );
        assert_eq!(read(&dir, "a.json"), "new a");
        assert_eq!(read(&dir, "b.csv/inside"), "x");
        assert_eq!(
            names(&dir),
            ["a.json", "b.csv"],
            "no c.txt, temporary file or link"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
