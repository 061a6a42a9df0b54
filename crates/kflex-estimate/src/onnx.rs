//! ONNX Runtime: one environment per process, the runtime library found
//! without the user's help, and models checked against what an estimator
//! expects when they are loaded (cargo feature `onnx`).
//!
//! kflex links ONNX Runtime dynamically (`ort`'s `load-dynamic`): the library
//! comes from the `onnxruntime` Python wheel the project pins
//! (`requirements.txt`, installed into `.venv` by `make venv`). It is looked
//! for, in order, at
//! 1. `ORT_DYLIB_PATH` (a file path);
//! 2. the `onnxruntime` package the embedding program names with
//!    [`prefer_onnxruntime_package`] (the Python module names its own
//!    interpreter's, so `import kflex` finds the runtime of the environment
//!    it runs in, activated or not);
//! 3. the project's virtual environment: `.venv/lib/python3*/site-packages/
//!    onnxruntime/capi/libonnxruntime.so*` in the current directory or any
//!    directory above it, then above the running executable;
//! 4. the active Python: `$VIRTUAL_ENV`, then `python3`'s own `onnxruntime`.
//!
//! When none has it, the error says what to install or set.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use ort::environment::Environment;
use ort::session::Session;
use ort::session::builder::GraphOptimizationLevel;
use ort::value::{TensorElementType, TensorRef, ValueType};
use sha2::{Digest, Sha256};

use crate::error::{EstimateError, Result};

/// The ONNX Runtime version kflex is built and tested against (the pinned wheel).
pub const ONNXRUNTIME_VERSION: &str = "1.31.1";

/// The `onnxruntime` package directory named by [`prefer_onnxruntime_package`].
static PREFERRED_PACKAGE: OnceLock<PathBuf> = OnceLock::new();

/// Names the `onnxruntime` Python package directory (the one holding
/// `capi/`) to look in after `ORT_DYLIB_PATH` and before the virtual
/// environments. The first call wins; it matters only before the first
/// model is loaded. Returns whether this call set it.
pub fn prefer_onnxruntime_package(dir: &Path) -> bool {
    PREFERRED_PACKAGE.set(dir.to_path_buf()).is_ok()
}

/// Where the ONNX Runtime library is: see the module docs for the order.
///
/// # Errors
/// [`EstimateError::OnnxRuntimeMissing`] naming every place looked at, or
/// `ORT_DYLIB_PATH` when it names no file.
pub fn onnxruntime_library() -> Result<PathBuf> {
    let mut searched = Vec::new();
    if let Some(path) = std::env::var_os("ORT_DYLIB_PATH") {
        let path = PathBuf::from(path);
        if path.is_file() {
            return Ok(path);
        }
        return Err(EstimateError::OnnxRuntimeMissing {
            searched: format!("ORT_DYLIB_PATH={} (no such file)", path.display()),
        });
    }
    searched.push("ORT_DYLIB_PATH (unset)".to_string());
    if let Some(package) = PREFERRED_PACKAGE.get() {
        if let Some(lib) = in_capi(&package.join("capi")) {
            return Ok(lib);
        }
        searched.push(format!("the onnxruntime package {}", package.display()));
    }
    let mut starts: Vec<PathBuf> = Vec::new();
    if let Ok(dir) = std::env::current_dir() {
        starts.push(dir);
    }
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        starts.push(dir);
    }
    for start in &starts {
        for dir in start.ancestors() {
            let venv = dir.join(".venv");
            if let Some(lib) = in_virtualenv(&venv) {
                return Ok(lib);
            }
        }
        searched.push(format!(".venv in {} and above", start.display()));
    }
    if let Some(venv) = std::env::var_os("VIRTUAL_ENV") {
        if let Some(lib) = in_virtualenv(Path::new(&venv)) {
            return Ok(lib);
        }
        searched.push(format!("VIRTUAL_ENV={}", Path::new(&venv).display()));
    }
    let python = std::process::Command::new("python3")
        .args([
            "-c",
            "import os, onnxruntime; print(os.path.dirname(onnxruntime.__file__))",
        ])
        .output();
    if let Ok(out) = python
        && out.status.success()
    {
        let package = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
        if let Some(lib) = in_capi(&package.join("capi")) {
            return Ok(lib);
        }
    }
    searched.push("python3's onnxruntime package".to_string());
    Err(EstimateError::OnnxRuntimeMissing {
        searched: searched.join("; "),
    })
}

/// `libonnxruntime.so*` of the `onnxruntime` package in a virtual environment.
fn in_virtualenv(venv: &Path) -> Option<PathBuf> {
    let lib = venv.join("lib");
    let entries = std::fs::read_dir(&lib).ok()?;
    let mut pythons: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("python3"))
        })
        .collect();
    pythons.sort();
    pythons
        .iter()
        .find_map(|py| in_capi(&py.join("site-packages/onnxruntime/capi")))
}

/// The runtime library in an `onnxruntime/capi` folder: the pinned version
/// if it is there, else the newest-named `libonnxruntime.so*`.
fn in_capi(capi: &Path) -> Option<PathBuf> {
    let pinned = capi.join(format!("libonnxruntime.so.{ONNXRUNTIME_VERSION}"));
    if pinned.is_file() {
        return Some(pinned);
    }
    let mut libs: Vec<PathBuf> = std::fs::read_dir(capi)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("libonnxruntime.so"))
        })
        .collect();
    libs.sort();
    libs.pop()
}

/// The process's one ONNX Runtime environment, created on first use.
///
/// # Errors
/// [`EstimateError::OnnxRuntimeMissing`] when the library cannot be found,
/// [`EstimateError::Onnx`] when it cannot be loaded; the same error again on
/// every later call (the library is loaded once per process).
pub fn environment() -> Result<&'static Environment> {
    static ENV: OnceLock<std::result::Result<Environment, EstimateError>> = OnceLock::new();
    ENV.get_or_init(|| {
        let lib = onnxruntime_library()?;
        let onnx = |e: &dyn std::fmt::Display| EstimateError::Onnx {
            path: lib.display().to_string(),
            message: e.to_string(),
        };
        ort::init_from(&lib)
            .map_err(|e| onnx(&e))?
            .with_name("kflex")
            .build()
            .map_err(|e| onnx(&e))
    })
    .as_ref()
    .map_err(Clone::clone)
}

/// A tensor a model must take or give: its name and shape, `-1` for the
/// dynamic batch axis. Elements are `f32`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TensorSpec {
    /// The input's or output's name in the graph.
    pub name: &'static str,
    /// Its shape, `-1` for a dynamic axis (the batch, first).
    pub shape: &'static [i64],
}

impl TensorSpec {
    /// Elements per batch item: the product of the fixed axes.
    fn per_item(&self) -> usize {
        self.shape
            .iter()
            .filter(|d| **d > 0)
            .map(|d| *d as usize)
            .product()
    }
}

/// An ONNX model with one `f32` input and one `f32` output, checked at load.
pub struct OnnxModel {
    path: String,
    session: Session,
    input: TensorSpec,
    output: TensorSpec,
    sha256: String,
}

impl std::fmt::Debug for OnnxModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnnxModel")
            .field("path", &self.path)
            .field("input", &self.input)
            .field("output", &self.output)
            .field("sha256", &self.sha256)
            .finish_non_exhaustive()
    }
}

/// The lowercase hex SHA-256 of some bytes.
pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The SHA-256 a model card beside `model` records, if there is a card:
/// `NAME.card.json` for `NAME.onnx`, a JSON object with a `sha256` field.
fn card_sha256(model: &Path) -> Result<Option<String>> {
    let card = model.with_extension("card.json");
    let text = match std::fs::read_to_string(&card) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => {
            return Err(EstimateError::io(&card, &e));
        }
    };
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| EstimateError::ModelFile {
            path: card.display().to_string(),
            message: format!("not a model card: {e}"),
        })?;
    match value.get("sha256").and_then(serde_json::Value::as_str) {
        Some(s) => Ok(Some(s.to_ascii_lowercase())),
        None => Err(EstimateError::ModelFile {
            path: card.display().to_string(),
            message: "the model card has no \"sha256\" string".to_string(),
        }),
    }
}

impl OnnxModel {
    /// Loads the model at `path` for batch-1 latency (`threads` intra-op
    /// threads, 1 by default in the estimators; no spinning) and checks it:
    /// the model card beside it, if any, must record the file's SHA-256, and
    /// its one input and one output must be `f32` tensors named and shaped
    /// as `input` and `output` say.
    ///
    /// # Errors
    /// [`EstimateError::Io`] (with the io error's kind) for a file or card
    /// that cannot be read; [`EstimateError::ModelFile`] for a card that is
    /// not a model card;
    /// [`EstimateError::ModelChecksum`] when the card records another file;
    /// [`EstimateError::Onnx`] when ONNX Runtime refuses the file (corrupt,
    /// truncated, not ONNX) or is missing ([`EstimateError::OnnxRuntimeMissing`]);
    /// [`EstimateError::ModelMismatch`] naming what the model has and what
    /// was expected.
    pub fn load(
        path: &Path,
        input: TensorSpec,
        output: TensorSpec,
        threads: usize,
    ) -> Result<Self> {
        let shown = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| EstimateError::io(path, &e))?;
        let sha256 = sha256_hex(&bytes);
        if let Some(card) = card_sha256(path)?
            && card != sha256
        {
            return Err(EstimateError::ModelChecksum {
                path: shown,
                card,
                file: sha256,
            });
        }
        let env = environment()?;
        let onnx = |e: &dyn std::fmt::Display| EstimateError::Onnx {
            path: shown.clone(),
            message: e.to_string(),
        };
        let session = Session::builder(env)
            .map_err(|e| onnx(&e))?
            .with_optimization_level(GraphOptimizationLevel::Level3)
            .map_err(|e| onnx(&e))?
            .with_intra_threads(threads.max(1))
            .map_err(|e| onnx(&e))?
            .with_inter_threads(1)
            .map_err(|e| onnx(&e))?
            .with_intra_op_spinning(false)
            .map_err(|e| onnx(&e))?
            .commit_from_memory(&bytes)
            .map_err(|e| onnx(&e))?;
        check_outlets(&shown, "input", session.inputs(), input)?;
        check_outlets(&shown, "output", session.outputs(), output)?;
        Ok(Self {
            path: shown,
            session,
            input,
            output,
            sha256,
        })
    }

    /// The model file's SHA-256 (lowercase hex).
    #[must_use]
    pub fn sha256(&self) -> &str {
        &self.sha256
    }

    /// Runs the model on `batch` items laid out one after the other in
    /// `input`, writing theirs into `output`.
    ///
    /// # Errors
    /// [`EstimateError::Length`] when a buffer does not hold `batch`
    /// items; [`EstimateError::Onnx`] when ONNX Runtime fails.
    pub fn run(&mut self, input: &[f32], batch: usize, output: &mut [f32]) -> Result<()> {
        let (per_in, per_out) = (self.input.per_item(), self.output.per_item());
        for (what, got, want) in [
            ("model input", input.len(), batch * per_in),
            ("model output", output.len(), batch * per_out),
        ] {
            if got != want {
                return Err(EstimateError::Length {
                    what,
                    expected: want,
                    got,
                });
            }
        }
        let shape: Vec<i64> = self
            .input
            .shape
            .iter()
            .map(|d| if *d < 0 { batch as i64 } else { *d })
            .collect();
        let path = &self.path;
        let onnx = |e: ort::Error| EstimateError::Onnx {
            path: path.clone(),
            message: e.to_string(),
        };
        let tensor = TensorRef::from_array_view((shape, input)).map_err(onnx)?;
        let outputs = self
            .session
            .run(ort::inputs![self.input.name => tensor])
            .map_err(onnx)?;
        let value = outputs
            .get(self.output.name)
            .ok_or_else(|| EstimateError::Onnx {
                path: path.clone(),
                message: format!("no output {:?}", self.output.name),
            })?;
        let (_, data) = value.try_extract_tensor::<f32>().map_err(onnx)?;
        if data.len() != output.len() {
            return Err(EstimateError::Length {
                what: "model result",
                expected: output.len(),
                got: data.len(),
            });
        }
        output.copy_from_slice(data);
        Ok(())
    }
}

fn check_outlets(
    path: &str,
    which: &'static str,
    outlets: &[ort::value::Outlet],
    want: TensorSpec,
) -> Result<()> {
    let describe = |o: &ort::value::Outlet| match o.dtype() {
        ValueType::Tensor { ty, shape, .. } => format!("{} {ty:?} {:?}", o.name(), &shape[..]),
        other => format!("{} {other:?}", o.name()),
    };
    let expected = format!("{} Float32 {:?}", want.name, want.shape);
    let mismatch = |found: String| EstimateError::ModelMismatch {
        path: path.to_string(),
        which,
        expected: expected.clone(),
        found,
    };
    let [outlet] = outlets else {
        let all: Vec<String> = outlets.iter().map(describe).collect();
        return Err(mismatch(format!(
            "{} {which}s: {}",
            outlets.len(),
            all.join(", ")
        )));
    };
    let ok = match outlet.dtype() {
        ValueType::Tensor { ty, shape, .. } => {
            outlet.name() == want.name
                && *ty == TensorElementType::Float32
                && shape.len() == want.shape.len()
                && shape
                    .iter()
                    .zip(want.shape)
                    .all(|(got, w)| if *w < 0 { *got < 0 } else { got == w })
        }
        _ => false,
    };
    if ok {
        Ok(())
    } else {
        Err(mismatch(describe(outlet)))
    }
}
