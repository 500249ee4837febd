//! Errors of work queued on the GPU come back as `GpuError`s from the next
//! wait or read-back, not as wgpu's default panic.

mod common;

use isolux_gpu::{wgpu, GpuError};

/// A buffer larger than the device allows is a validation error that wgpu
/// reports through its uncaptured-error handler: `Gpu::check`, and every
/// `Gpu::wait` after it, return it as `GpuError::Failed`, naming the call.
#[test]
fn errors_of_queued_work_are_returned_not_panicked() {
    let Some(gpu) = common::open("errors of queued work") else {
        return;
    };
    assert!(gpu.check().is_ok());
    gpu.wait().expect("nothing failed yet");
    let too_big = gpu.device().limits().max_buffer_size.saturating_add(256);
    let _buffer = gpu.device().create_buffer(&wgpu::BufferDescriptor {
        label: Some("larger than the device allows"),
        size: too_big,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let err = gpu.wait().expect_err("the validation error is returned");
    eprintln!("{err}");
    assert!(matches!(err, GpuError::Failed(_)), "{err:?}");
    let text = err.to_string();
    assert!(text.starts_with("the GPU reported an error: "), "{text}");
    assert!(
        text.contains("create_buffer") || text.contains("larger than the device allows"),
        "{text}"
    );
    // It stays reported: the device's later work is not to be trusted.
    assert!(gpu.check().is_err());
}
