//! How a frame's dispatches are queued: the parameter block each binds
//! ([`ParamBlocks`]), their compute passes ([`begin_pass`]) and the
//! timestamps around them ([`Clock`], [`Stamps`], read back as a
//! [`Profile`] by [`GpuFrame::profile`]).

use crate::layout::GpuParams;
use crate::Gpu;
#[cfg(doc)]
use crate::GpuFrame;
use wgpu::util::DeviceExt;

/// How a frame's passes are timed on the GPU.
pub(super) enum Clock<'a> {
    /// Not at all.
    Off,
    /// The frame: a timestamp at the start of its first pass and one at
    /// the end of its last (`Gpu::timestamps`, [`GpuFrame::run_timed`]).
    Frame,
    /// Each dispatch in a pass of its own, with timestamps at its start
    /// and end ([`GpuFrame::profile`]).
    Each(&'a mut Stamps),
}

impl Clock<'_> {
    /// The timestamps of the pass of `kernel` (at wavefront `step`, if
    /// any), the `first` or the `last` of the frame's passes.
    pub(super) fn writes<'s>(
        &'s mut self,
        gpu: &'s Gpu,
        kernel: &'static str,
        step: Option<u32>,
        first: bool,
        last: bool,
    ) -> Option<wgpu::ComputePassTimestampWrites<'s>> {
        match self {
            Clock::Off => None,
            Clock::Frame => gpu.timestamps.as_ref().filter(|_| first || last).map(|ts| {
                wgpu::ComputePassTimestampWrites {
                    query_set: &ts.set,
                    beginning_of_pass_write_index: first.then_some(0),
                    end_of_pass_write_index: last.then_some(1),
                }
            }),
            Clock::Each(stamps) => stamps.next(kernel, step),
        }
    }

    /// Whether each dispatch takes a pass of its own.
    pub(super) fn each(&self) -> bool {
        matches!(self, Clock::Each(_))
    }

    /// Queues the copy of the frame's timestamps to where they are read.
    pub(super) fn resolve(&self, gpu: &Gpu, enc: &mut wgpu::CommandEncoder) {
        match self {
            Clock::Off => {}
            Clock::Frame => {
                if let Some(ts) = gpu.timestamps.as_ref() {
                    enc.resolve_query_set(&ts.set, 0..2, &ts.resolve, 0);
                }
            }
            Clock::Each(stamps) => {
                let n = 2 * stamps.kernels.len() as u32;
                if n > 0 {
                    enc.resolve_query_set(&stamps.set, 0..n, &stamps.resolve, 0);
                }
            }
        }
    }
}

/// Parameter blocks a frame's parameter buffer holds, one per dispatch of
/// a submission (256 bytes each on most devices: 256 KiB). A submission
/// of more dispatches copies the next blocks in after every
/// `PARAM_BLOCKS` dispatches.
pub const PARAM_BLOCKS: usize = 1024;

/// The [`GpuParams`] of each dispatch of one submission, staged at once
/// and copied into the frame's parameter buffer ahead of the dispatches
/// that read them, each of which binds its own block by a dynamic offset
/// ([`crate::PARAMS_BINDING`]). Until 2026-12-05 each dispatch's
/// parameters were copied into one block just before it: a copy, and the
/// barriers around it, between every two dispatches of a frame (every
/// wavefront step); now there is one copy per [`PARAM_BLOCKS`]
/// dispatches.
pub(super) struct ParamBlocks {
    staging: wgpu::Buffer,
    count: usize,
    stride: u64,
}

impl ParamBlocks {
    /// `blocks`, each padded to the device's storage offset alignment.
    pub(super) fn new(gpu: &Gpu, blocks: &[GpuParams]) -> Self {
        let stride = gpu.params_stride();
        let mut bytes = vec![0u8; blocks.len().max(1) * stride as usize];
        for (chunk, block) in bytes.chunks_exact_mut(stride as usize).zip(blocks) {
            chunk[..std::mem::size_of::<GpuParams>()].copy_from_slice(bytemuck::bytes_of(block));
        }
        let staging = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("dispatch parameters"),
                contents: &bytes,
                usage: wgpu::BufferUsages::COPY_SRC,
            });
        ParamBlocks {
            staging,
            count: blocks.len(),
            stride,
        }
    }

    /// The dynamic offset of block `i` in `buffer` (of [`PARAM_BLOCKS`]
    /// blocks), for a dispatch queued next in `enc`. Where `i` opens a run
    /// of [`PARAM_BLOCKS`] blocks, first queues the copy of that run into
    /// `buffer` (after the dispatches that read the previous run: wgpu
    /// orders a copy after the earlier reads of its destination).
    pub(super) fn offset(
        &self,
        enc: &mut wgpu::CommandEncoder,
        buffer: &wgpu::Buffer,
        i: usize,
    ) -> u32 {
        let at = i % PARAM_BLOCKS;
        if at == 0 {
            let n = (self.count - i).min(PARAM_BLOCKS) as u64;
            let from = i as u64 * self.stride;
            enc.copy_buffer_to_buffer(&self.staging, from, buffer, 0, n * self.stride);
        }
        (at as u64 * self.stride) as u32
    }
}

/// A compute pass of a frame, with the timestamps `writes`.
pub(super) fn begin_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    writes: Option<wgpu::ComputePassTimestampWrites<'e>>,
) -> wgpu::ComputePass<'e> {
    enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: writes,
    })
}

/// Timestamps around each dispatch of one submission
/// ([`GpuFrame::profile`]): two per dispatch, in the order queued, and
/// which kernel each pair timed.
pub(super) struct Stamps {
    set: wgpu::QuerySet,
    pub(super) resolve: wgpu::Buffer,
    /// Per dispatch, its kernel and wavefront step.
    pub(super) kernels: Vec<(&'static str, Option<u32>)>,
    /// Dispatches were queued past [`Stamps::MAX`] (those went untimed).
    pub(super) full: bool,
}

impl Stamps {
    /// Dispatches one submission can time: a query set holds at most
    /// `wgpu::QUERY_SET_MAX_QUERIES` (4096) timestamps.
    pub(super) const MAX: u32 = wgpu::QUERY_SET_MAX_QUERIES / 2;

    pub(super) fn new(gpu: &Gpu) -> Self {
        let n = 2 * Self::MAX;
        Self {
            set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("dispatch timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: n,
            }),
            resolve: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("dispatch timestamps"),
                size: n as u64 * wgpu::QUERY_SIZE as u64,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            kernels: Vec::new(),
            full: false,
        }
    }

    /// The timestamps of the next dispatch's pass, of `kernel` at `step`.
    fn next(
        &mut self,
        kernel: &'static str,
        step: Option<u32>,
    ) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let i = self.kernels.len() as u32;
        if i >= Self::MAX {
            self.full = true;
            return None;
        }
        self.kernels.push((kernel, step));
        Some(wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * i),
            end_of_pass_write_index: Some(2 * i + 1),
        })
    }
}

/// One dispatch's GPU time in a [`Profile`].
#[derive(Clone, Debug, PartialEq)]
pub struct DispatchTime {
    /// The kernel's entry point in the render kernels (`main`, `resolve`,
    /// `realtime`, `aov_main`, `trace`, `trace_last`, `trace_extend`,
    /// `trace_scatter`, `trace_shadow`, `trace_shade`).
    pub kernel: &'static str,
    /// The wavefront's step (0: the camera rays; `None` outside the
    /// wavefronts).
    pub step: Option<u32>,
    /// GPU seconds from the start of the dispatch's pass to its end.
    pub seconds: f64,
}

/// A frame's GPU time dispatch by dispatch ([`GpuFrame::profile`]).
#[derive(Clone, Debug, Default)]
pub struct Profile {
    /// Every dispatch, in the order queued.
    pub dispatches: Vec<DispatchTime>,
    /// GPU seconds from each submission's first dispatch's start to its
    /// last's end, summed over the submissions: the dispatches' time and
    /// what passes between them (barriers, the copies of each dispatch's
    /// parameters, the start of the next).
    pub span: f64,
}

impl Profile {
    /// The dispatches' time, summed.
    pub fn dispatch_seconds(&self) -> f64 {
        self.dispatches.iter().map(|d| d.seconds).sum()
    }
}
