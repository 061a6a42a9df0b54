//! Without the runtime library, loading a model says what to do (its own
//! test binary: it sets ORT_DYLIB_PATH for the whole process).
#![cfg(feature = "onnx")]

use kflex_estimate::{EstimateError, Kbjae};

#[test]
fn a_missing_runtime_library_is_an_error_that_says_what_to_do() {
    let nowhere = std::env::temp_dir().join("kflex-no-such-dir/libonnxruntime.so.1.31.1");
    // SAFETY: the only test of this binary; nothing else reads the environment meanwhile.
    unsafe { std::env::set_var("ORT_DYLIB_PATH", &nowhere) };
    let model = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/kbjae_test.onnx");
    let e = Kbjae::load(&model).unwrap_err();
    assert!(matches!(e, EstimateError::OnnxRuntimeMissing { .. }), "{e}");
    let message = e.to_string();
    for hint in [
        "ORT_DYLIB_PATH",
        "make venv",
        "onnxruntime==1.31.1",
        "kflex-no-such-dir",
    ] {
        assert!(message.contains(hint), "{message}");
    }
    // loaded once per process: the same answer again
    assert_eq!(Kbjae::load(&model).unwrap_err(), e);
}
