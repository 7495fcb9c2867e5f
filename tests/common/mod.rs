//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use trilab::gpu::{Context, ContextOptions, Validation};
use trilab::scene::{load_obj, Mesh};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn bunny() -> Mesh {
    load_obj(&root().join("scenes/bunny.obj")).expect("bundled bunny loads")
}

/// Runs `f` on a Vulkan context with the validation layer required, on its own thread with a
/// wall-clock limit (lavapipe has no watchdog: a hung kernel must fail the test, not CI).
/// Fails (never skips) when there is no device or no validation layer, and when the layer
/// reported anything, teardown included.
pub fn with_gpu<T: Send + 'static>(timeout_s: u64, f: impl FnOnce(&Context) -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let ctx = Context::new(&ContextOptions { validation: Validation::Required, ..Default::default() })
            .unwrap_or_else(|e| {
                panic!("GPU tests need a Vulkan device and the validation layer (they fail, never skip): {e}")
            });
        assert!(ctx.validation_enabled(), "validation layer and debug messenger must be active in tests");
        let log = ctx.validation_log();
        let out = f(&ctx);
        drop(ctx);
        let _ = tx.send((out, log.messages()));
    });
    match rx.recv_timeout(Duration::from_secs(timeout_s)) {
        Ok((out, messages)) => {
            assert!(messages.is_empty(), "{} validation message(s):\n{}", messages.len(), messages.join("\n"));
            out
        }
        Err(RecvTimeoutError::Timeout) => panic!("GPU test did not finish within {timeout_s} s"),
        Err(RecvTimeoutError::Disconnected) => panic!("GPU test failed (see the panic above)"),
    }
}
