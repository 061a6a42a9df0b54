//! The Rust side of `tools/index_bench.py`: writes the synthetic embedding
//! manifold as `.npy` files, and times the feature index against a linear
//! scan on `.npy` data, printing JSON.
//!
//! ```text
//! cargo run --release -p kflex-estimate --features index --example index_bench -- \
//!     generate --n 10000 --queries 1000 --out /tmp/idx            # db.npy, poses.npy, queries.npy
//! cargo run --release -p kflex-estimate --features index --example index_bench -- \
//!     time --dir /tmp/idx [--k 8] [--rounds 3] [--search auto|tree|scan]   # JSON on stdout
//! ```
//!
//! `time` builds the index from `db.npy` (N×D f32) and `poses.npy` (N×2 f64),
//! then runs every row of `queries.npy` (Q×D f32) one at a time (batch 1) on
//! this thread, through the index and through the linear scan, checks they
//! agree, and writes the index's answers to `answers_rust.npy` (Q, i64). Per
//! query times are taken one query at a time; the figures are the median
//! and the mean of the best of `--rounds` passes.

#[path = "../tests/support/manifold.rs"]
mod manifold;

use std::path::{Path, PathBuf};
use std::time::Instant;

use kflex_estimate::{FeatureIndex, IndexParams, Pose, ProjectionDims, Search};
use manifold::{Manifold, rng};

/// Default noise of the synthetic manifold, per component (see `tests/support/manifold.rs`).
const NOISE_STD: f64 = manifold::DEFAULT_NOISE_STD;

fn main() {
    if let Err(e) = run() {
        eprintln!("index_bench: {e}");
        std::process::exit(1);
    }
}

fn arg<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> Result<T, String> {
    match args.iter().position(|a| a == name) {
        None => Ok(default),
        Some(i) => args
            .get(i + 1)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| format!("{name} needs a value")),
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(arg(
        &args,
        "--dir",
        arg(&args, "--out", String::from("."))?,
    )?);
    match args.first().map(String::as_str) {
        Some("generate") => generate(
            &dir,
            arg(&args, "--n", 10_000)?,
            arg(&args, "--queries", 1000)?,
            arg(&args, "--dim", 256)?,
            arg(&args, "--seed", 1)?,
        ),
        Some("time") => time(
            &dir,
            arg(&args, "--k", 8)?,
            arg(&args, "--rounds", 3)?,
            &arg(&args, "--search", "auto".to_string())?,
        ),
        _ => Err("usage: index_bench generate|time [options] (see the file's docs)".into()),
    }
}

fn generate(dir: &Path, n: usize, queries: usize, dim: usize, seed: u64) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    let surface = Manifold::new(dim, NOISE_STD, 7);
    let mut r = rng(seed);
    let (features, poses) = surface.sample(n, &mut r);
    let (q, _) = surface.sample(queries, &mut r);
    let flat: Vec<f64> = poses
        .iter()
        .flat_map(|p| [p.theta_deg, p.translation_mm])
        .collect();
    write_npy(&dir.join("db.npy"), "<f4", &[n, dim], &f32_bytes(&features))?;
    write_npy(&dir.join("poses.npy"), "<f8", &[n, 2], &f64_bytes(&flat))?;
    write_npy(
        &dir.join("queries.npy"),
        "<f4",
        &[queries, dim],
        &f32_bytes(&q),
    )?;
    Ok(())
}

fn time(dir: &Path, k: usize, rounds: usize, search: &str) -> Result<(), String> {
    let search_method = match search {
        "auto" => Search::Auto,
        "tree" => Search::Tree,
        "scan" => Search::Scan,
        _ => return Err("--search must be auto, tree or scan".into()),
    };
    let (shape, features) = read_npy_f32(&dir.join("db.npy"))?;
    let (qshape, queries) = read_npy_f32(&dir.join("queries.npy"))?;
    let (n, dim) = (shape[0], shape[1]);
    if qshape[1] != dim {
        return Err(format!("queries are {}-d, the database {dim}-d", qshape[1]));
    }
    let poses = read_poses(&dir.join("poses.npy"), n)?;
    let projection_dims = ProjectionDims::from_count(k).ok_or("--k must be 8, 12 or 16")?;
    let t = Instant::now();
    let index = FeatureIndex::build(
        &features,
        dim,
        &poses,
        IndexParams {
            projection_dims,
            search: search_method,
        },
    )
    .map_err(|e| e.to_string())?;
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    let file = dir.join("index.kfi");
    let t = Instant::now();
    index.save(&file).map_err(|e| e.to_string())?;
    let save_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let loaded = FeatureIndex::load(&file).map_err(|e| e.to_string())?;
    let load_ms = t.elapsed().as_secs_f64() * 1e3;
    drop(loaded);

    let rows: Vec<&[f32]> = queries.chunks_exact(dim).collect();
    let mut answers = Vec::with_capacity(rows.len());
    let mut full = 0_usize;
    for q in &rows {
        let (a, stats) = index.nearest_with_stats(q).map_err(|e| e.to_string())?;
        let b = index.nearest_linear(q).map_err(|e| e.to_string())?;
        if a != b {
            return Err(format!("index and linear scan disagree: {a:?} vs {b:?}"));
        }
        answers.push(a.index as i64);
        full += stats.full_distances;
    }
    let index_us = per_query_us(&rows, rounds, |q| index.nearest(q).map(|n| n.index));
    let linear_us = per_query_us(&rows, rounds, |q| index.nearest_linear(q).map(|n| n.index));
    let answer_bytes: Vec<u8> = answers.iter().flat_map(|a| a.to_le_bytes()).collect();
    write_npy(
        &dir.join("answers_rust.npy"),
        "<i8",
        &[answers.len()],
        &answer_bytes,
    )?;
    println!(
        "{{\"n\": {n}, \"dim\": {dim}, \"k\": {k}, \"search\": \"{}\", \"queries\": {}, \"build_ms\": {build_ms:.3}, \
         \"save_ms\": {save_ms:.3}, \"load_ms\": {load_ms:.3}, \
         \"index_us_median\": {:.4}, \"index_us_mean\": {:.4}, \
         \"linear_us_median\": {:.4}, \"linear_us_mean\": {:.4}, \
         \"full_distances_mean\": {:.3}}}",
        if index.search_method() == Search::Scan {
            "scan"
        } else {
            "tree"
        },
        rows.len(),
        index_us.0,
        index_us.1,
        linear_us.0,
        linear_us.1,
        full as f64 / rows.len() as f64
    );
    Ok(())
}

/// (median, mean) µs per query, one query at a time, best of `rounds`
/// passes (by mean) after one warm-up pass.
fn per_query_us<F: FnMut(&[f32]) -> kflex_estimate::Result<usize>>(
    rows: &[&[f32]],
    rounds: usize,
    mut f: F,
) -> (f64, f64) {
    let mut sink = 0_usize;
    for q in rows {
        sink ^= f(q).unwrap_or(0);
    }
    let mut best = (f64::INFINITY, f64::INFINITY);
    let mut times = Vec::with_capacity(rows.len());
    for _ in 0..rounds.max(1) {
        times.clear();
        for q in rows {
            let t = Instant::now();
            sink ^= f(std::hint::black_box(q)).unwrap_or(0);
            times.push(t.elapsed().as_secs_f64() * 1e6);
        }
        let mean = times.iter().sum::<f64>() / times.len() as f64;
        times.sort_by(f64::total_cmp);
        if mean < best.1 {
            best = (times[times.len() / 2], mean);
        }
    }
    std::hint::black_box(sink);
    best
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn f64_bytes(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Writes a version-1.0 `.npy` file of a C-ordered array.
fn write_npy(path: &Path, descr: &str, shape: &[usize], data: &[u8]) -> Result<(), String> {
    let shape = match shape {
        [n] => format!("({n},)"),
        s => format!(
            "({})",
            s.iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header.as_bytes());
    out.extend(data);
    std::fs::write(path, out).map_err(|e| format!("{}: {e}", path.display()))
}

/// Reads a `.npy` file: (descr, shape, data bytes). Version 1.0 or 2.0,
/// C order only.
fn read_npy(path: &Path) -> Result<(String, Vec<usize>, Vec<u8>), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let bad = || format!("{}: not a C-ordered .npy file", path.display());
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad());
    }
    let (len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        _ => (
            u32::from_le_bytes(
                bytes
                    .get(8..12)
                    .ok_or_else(bad)?
                    .try_into()
                    .map_err(|_| bad())?,
            ) as usize,
            12,
        ),
    };
    let header =
        std::str::from_utf8(bytes.get(start..start + len).ok_or_else(bad)?).map_err(|_| bad())?;
    if header.contains("'fortran_order': True") {
        return Err(bad());
    }
    let field = |key: &str| -> Option<&str> {
        let at = header.find(key)? + key.len();
        Some(header[at..].trim_start_matches([':', ' ']))
    };
    let descr = field("'descr'")
        .and_then(|s| s.strip_prefix('\''))
        .and_then(|s| s.split('\'').next())
        .ok_or_else(bad)?
        .to_string();
    let shape = field("'shape'")
        .and_then(|s| s.strip_prefix('('))
        .and_then(|s| s.split(')').next())
        .ok_or_else(bad)?
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse::<usize>().map_err(|_| bad()))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((descr, shape, bytes[start + len..].to_vec()))
}

fn read_npy_f32(path: &Path) -> Result<(Vec<usize>, Vec<f32>), String> {
    let (descr, shape, data) = read_npy(path)?;
    if descr != "<f4" || shape.len() != 2 || data.len() != 4 * shape[0] * shape[1] {
        return Err(format!("{}: expected a 2-d <f4 array", path.display()));
    }
    let values = data
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok((shape, values))
}

fn read_poses(path: &Path, n: usize) -> Result<Vec<Pose>, String> {
    let (descr, shape, data) = read_npy(path)?;
    if descr != "<f8" || shape != [n, 2] || data.len() != 16 * n {
        return Err(format!("{}: expected an {n}×2 <f8 array", path.display()));
    }
    let v: Vec<f64> = data
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect();
    Ok(v.chunks_exact(2)
        .map(|p| Pose {
            theta_deg: p[0],
            translation_mm: p[1],
        })
        .collect())
}
