//! Shared by the GPU integration tests.

use isolux_gpu::{Gpu, GpuError};

/// The adapter, or `None` (with a message naming `what` was skipped) when
/// there is none outside CI. Under CI (`CI` set) `.ci/run` installs
/// lavapipe, and a missing adapter is a failure.
pub fn open(what: &str) -> Option<Gpu> {
    match Gpu::new() {
        Ok(g) => {
            eprintln!("adapter: {}", g.adapter);
            Some(g)
        }
        Err(GpuError::NoAdapter) if std::env::var_os("CI").is_none() => {
            eprintln!("no GPU adapter: {what} skipped (CI installs lavapipe)");
            None
        }
        Err(e) => panic!("{e}"),
    }
}
