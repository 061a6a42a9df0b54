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

use std::mem::ManuallyDrop;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock, PoisonError, Weak};

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

/// The most intra-op threads a model is loaded with ([`OnnxModel::load`]).
pub const MAX_THREADS: usize = 256;

/// An ONNX model with one `f32` input and one `f32` output, checked at load.
pub struct OnnxModel {
    path: String,
    session: Session,
    input: TensorSpec,
    output: TensorSpec,
    sha256: String,
    /// Intra-op threads of its session.
    threads: usize,
    /// Batch 1 without allocation (the estimators' per-tick call).
    one: BatchOne,
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

/// The file at `path`, read, with its SHA-256, checked against the model
/// card beside it (if any), for a model of `threads` intra-op threads.
fn read_checked(path: &Path, threads: usize) -> Result<(Vec<u8>, String)> {
    // ONNX Runtime takes the count as a C int; more than cores is waste
    kflex_model::Bounds::closed(0.0, MAX_THREADS as f64).check("threads", threads as f64)?;
    let bytes = std::fs::read(path).map_err(|e| EstimateError::io(path, &e))?;
    let sha256 = sha256_hex(&bytes);
    if let Some(card) = card_sha256(path)?
        && card != sha256
    {
        return Err(EstimateError::ModelChecksum {
            path: path.display().to_string(),
            card,
            file: sha256,
        });
    }
    Ok((bytes, sha256))
}

/// Loaded models kept for reuse. ONNX Runtime takes about 10 ms to build a
/// session (the SCNN's), and a session keeps nothing from one run to the
/// next; so estimators made through a pool ([`crate::Scnn::load_pooled`],
/// [`crate::Kbjae::load_pooled`]) take a kept model of the same file (the
/// same SHA-256, read and checked again at each load), tensors and threads
/// where there is one, and give it back when they are dropped. An
/// experiment grid, which makes fresh estimators for every run, then builds
/// each session about once per job. It keeps at most [`ModelPool::MAX_KEPT`].
#[derive(Debug, Default)]
pub struct ModelPool {
    kept: Mutex<Vec<OnnxModel>>,
}

impl ModelPool {
    /// The most models a pool keeps (those given back beyond are dropped).
    pub const MAX_KEPT: usize = 64;

    /// A new, empty pool, to share.
    #[must_use]
    pub fn new() -> Arc<Self> {
        Arc::default()
    }

    /// Models it keeps now.
    #[must_use]
    pub fn kept(&self) -> usize {
        self.lock().len()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<OnnxModel>> {
        self.kept.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// [`OnnxModel::load`] through the pool: a kept model of the same file,
    /// tensors and threads, else a new one; given back when the result is dropped.
    pub(crate) fn load(
        self: &Arc<Self>,
        path: &Path,
        input: TensorSpec,
        output: TensorSpec,
        threads: usize,
    ) -> Result<Pooled> {
        let (bytes, sha256) = read_checked(path, threads)?;
        let found = {
            let mut kept = self.lock();
            kept.iter()
                .position(|m| m.serves(path, &sha256, input, output, threads))
                .map(|i| kept.swap_remove(i))
        };
        let model = match found {
            Some(model) => model,
            None => OnnxModel::from_checked(path, &bytes, sha256, input, output, threads)?,
        };
        Ok(Pooled {
            model: ManuallyDrop::new(model),
            home: Arc::downgrade(self),
        })
    }
}

/// A model that goes back to its pool when dropped (or is dropped with it,
/// where it has none, or the pool is gone or full).
pub(crate) struct Pooled {
    model: ManuallyDrop<OnnxModel>,
    home: Weak<ModelPool>,
}

impl Pooled {
    /// A model of no pool.
    pub(crate) fn alone(model: OnnxModel) -> Self {
        Self {
            model: ManuallyDrop::new(model),
            home: Weak::new(),
        }
    }
}

impl std::fmt::Debug for Pooled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.model.fmt(f)
    }
}

impl std::ops::Deref for Pooled {
    type Target = OnnxModel;
    fn deref(&self) -> &OnnxModel {
        &self.model
    }
}

impl std::ops::DerefMut for Pooled {
    fn deref_mut(&mut self) -> &mut OnnxModel {
        &mut self.model
    }
}

impl Drop for Pooled {
    fn drop(&mut self) {
        // SAFETY: `model` is taken once, here, and not used after.
        let model = unsafe { ManuallyDrop::take(&mut self.model) };
        if let Some(pool) = self.home.upgrade() {
            let mut kept = pool.lock();
            if kept.len() < ModelPool::MAX_KEPT {
                kept.push(model);
            }
        }
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
    /// [`EstimateError::Model`] naming `threads` above [`MAX_THREADS`];
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
        let (bytes, sha256) = read_checked(path, threads)?;
        Self::from_checked(path, &bytes, sha256, input, output, threads)
    }

    /// [`OnnxModel::load`] of a file already read and checked
    /// ([`read_checked`]).
    fn from_checked(
        path: &Path,
        bytes: &[u8],
        sha256: String,
        input: TensorSpec,
        output: TensorSpec,
        threads: usize,
    ) -> Result<Self> {
        let shown = path.display().to_string();
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
            .commit_from_memory(bytes)
            .map_err(|e| onnx(&e))?;
        check_outlets(&shown, "input", session.inputs(), input)?;
        check_outlets(&shown, "output", session.outputs(), output)?;
        let one = BatchOne::new(input, output).map_err(|m| onnx(&m))?;
        Ok(Self {
            path: shown,
            session,
            input,
            output,
            sha256,
            threads: threads.max(1),
            one,
        })
    }

    /// Whether it is the model `path` holds now (its SHA-256 `sha256`) with
    /// `input`, `output` and `threads`: what a pooled model must be to serve
    /// a load ([`ModelPool`]).
    fn serves(
        &self,
        path: &Path,
        sha256: &str,
        input: TensorSpec,
        output: TensorSpec,
        threads: usize,
    ) -> bool {
        self.path == path.display().to_string()
            && self.sha256 == sha256
            && self.input == input
            && self.output == output
            && self.threads == threads.max(1)
    }

    /// The model file's SHA-256 (lowercase hex).
    #[must_use]
    pub fn sha256(&self) -> &str {
        &self.sha256
    }

    /// The intra-op threads its session runs on (ONNX Runtime does not
    /// promise the same bits for another count).
    #[must_use]
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Runs the model on `batch` items laid out one after the other in
    /// `input`, writing theirs into `output`.
    ///
    /// # Errors
    /// [`EstimateError::Length`] when a buffer does not hold `batch`
    /// items; [`EstimateError::Onnx`] when ONNX Runtime fails, or when the
    /// model answers with a value that is not finite (a damaged or
    /// tampered weight, whatever the input: no NaN leaves a model).
    pub fn run(&mut self, input: &[f32], batch: usize, output: &mut [f32]) -> Result<()> {
        self.run_unchecked(input, batch, output)?;
        if let Some(k) = output.iter().position(|v| !v.is_finite()) {
            let per_out = self.output.per_item().max(1);
            return Err(EstimateError::Onnx {
                path: self.path.clone(),
                message: format!(
                    "the model answered {} (value {} of item {} of {batch}); \
                     its weights may be damaged: restore or retrain the file",
                    output[k],
                    k % per_out,
                    k / per_out
                ),
            });
        }
        Ok(())
    }

    /// [`OnnxModel::run`] without the check of the answer.
    fn run_unchecked(&mut self, input: &[f32], batch: usize, output: &mut [f32]) -> Result<()> {
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
        if batch == 1 {
            return self
                .one
                .run(&self.session, input, output)
                .map_err(|message| EstimateError::Onnx {
                    path: self.path.clone(),
                    message,
                });
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

/// Batch 1 without allocation: an input and an output tensor created once
/// over buffers this struct owns, and ONNX Runtime's C `Run` called with
/// them, the output preallocated (`ort`'s `Session::run` builds an input
/// list and an output map on every call, which a control tick must not).
struct BatchOne {
    /// The input tensor's data (its address is fixed: a boxed slice).
    input: Box<[f32]>,
    /// The output tensor's data.
    output: Box<[f32]>,
    input_value: std::ptr::NonNull<ort::sys::OrtValue>,
    output_value: std::ptr::NonNull<ort::sys::OrtValue>,
    input_name: std::ffi::CString,
    output_name: std::ffi::CString,
}

// SAFETY: the two `OrtValue`s belong to this struct alone and are used only
// through `&mut self`, so by one thread at a time; ONNX Runtime's values
// are not tied to the thread that made them.
unsafe impl Send for BatchOne {}

// SAFETY: nothing reads or writes the values through `&self`: `run` takes
// `&mut self`, so a shared reference gives no access to them at all.
unsafe impl Sync for BatchOne {}

/// `Ok` for a null status, else its message (the status released).
fn status(s: ort::sys::OrtStatusPtr) -> std::result::Result<(), String> {
    if s.0.is_null() {
        return Ok(());
    }
    let api = ort::api();
    // SAFETY: `s` is a status ONNX Runtime returned; its message lives
    // until the status is released, which happens after the copy.
    let message = unsafe { std::ffi::CStr::from_ptr((api.GetErrorMessage)(s.0)) }
        .to_string_lossy()
        .into_owned();
    // SAFETY: released once, here.
    unsafe { (api.ReleaseStatus)(s.0) };
    Err(message)
}

impl BatchOne {
    fn new(input: TensorSpec, output: TensorSpec) -> std::result::Result<Self, String> {
        use ort::sys::{ONNXTensorElementDataType, OrtAllocatorType, OrtMemType, OrtValue};
        let api = ort::api();
        let batch_one = |spec: TensorSpec| -> Vec<i64> {
            spec.shape
                .iter()
                .map(|&d| if d < 0 { 1 } else { d })
                .collect()
        };
        let (in_shape, out_shape) = (batch_one(input), batch_one(output));
        let mut input_data = vec![0.0f32; input.per_item()].into_boxed_slice();
        let mut output_data = vec![0.0f32; output.per_item()].into_boxed_slice();
        let mut info = std::ptr::null_mut();
        // SAFETY: an out-pointer ONNX Runtime fills.
        status(unsafe {
            (api.CreateCpuMemoryInfo)(
                OrtAllocatorType::OrtArenaAllocator,
                OrtMemType::OrtMemTypeDefault,
                &mut info,
            )
        })?;
        let tensor = |data: &mut [f32], shape: &[i64]| -> std::result::Result<_, String> {
            let mut value: *mut OrtValue = std::ptr::null_mut();
            // SAFETY: `data` outlives the value (both are owned by the
            // `BatchOne` being built, and the value is released first, in
            // `drop`); the byte length and the shape agree with it.
            status(unsafe {
                (api.CreateTensorWithDataAsOrtValue)(
                    info,
                    data.as_mut_ptr().cast(),
                    std::mem::size_of_val(data),
                    shape.as_ptr(),
                    shape.len(),
                    ONNXTensorElementDataType::ONNX_TENSOR_ELEMENT_DATA_TYPE_FLOAT,
                    &mut value,
                )
            })?;
            std::ptr::NonNull::new(value).ok_or_else(|| "ONNX Runtime made no tensor".to_string())
        };
        let made = tensor(&mut input_data, &in_shape).and_then(|i| {
            tensor(&mut output_data, &out_shape)
                .map(|o| (i, o))
                .inspect_err(|_| {
                    // SAFETY: made above, released once.
                    unsafe { (api.ReleaseValue)(i.as_ptr()) }
                })
        });
        // SAFETY: the tensors keep their own copy of the memory description.
        unsafe { (api.ReleaseMemoryInfo)(info) };
        let (input_value, output_value) = made?;
        let name = |n: &str| std::ffi::CString::new(n).map_err(|e| e.to_string());
        Ok(Self {
            input: input_data,
            output: output_data,
            input_value,
            output_value,
            input_name: name(input.name)?,
            output_name: name(output.name)?,
        })
    }

    /// One item through `session`: `input` in, the result into `output`
    /// (both of the sizes the tensors were made with; checked by the caller).
    fn run(
        &mut self,
        session: &Session,
        input: &[f32],
        output: &mut [f32],
    ) -> std::result::Result<(), String> {
        use ort::AsPointer;
        self.input.copy_from_slice(input);
        let api = ort::api();
        let names_in = [self.input_name.as_ptr()];
        let names_out = [self.output_name.as_ptr()];
        let inputs = [self.input_value.as_ptr().cast_const()];
        let mut outputs = [self.output_value.as_ptr()];
        // SAFETY: the session is alive for the call; the names and values
        // are valid and match the model's one input and one output (checked
        // at load); the output is preallocated, so ONNX Runtime writes into
        // `self.output` and hands back the same value.
        status(unsafe {
            (api.Run)(
                session.ptr().cast_mut(),
                std::ptr::null(),
                names_in.as_ptr(),
                inputs.as_ptr(),
                1,
                names_out.as_ptr(),
                1,
                outputs.as_mut_ptr(),
            )
        })?;
        output.copy_from_slice(&self.output);
        Ok(())
    }
}

impl Drop for BatchOne {
    fn drop(&mut self) {
        let api = ort::api();
        // SAFETY: made in `new`, released once, before their buffers.
        unsafe {
            (api.ReleaseValue)(self.input_value.as_ptr());
            (api.ReleaseValue)(self.output_value.as_ptr());
        }
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
