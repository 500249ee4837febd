//! The wavefront path tracer's host side (`trace` and the sorted
//! wavefront's kernels in wavefront.wgsl; docs/gpu.md, "The wavefront
//! path tracer"): a frame's path state, queues and step counters
//! ([`Wavefront`], made on a frame's first wavefront run), their tiles and
//! samples a run ([`wavefront_shape`]), the dispatches of a run's steps
//! ([`GpuFrame::dispatch_wavefront`]), and the diagnostics read back from
//! them ([`GpuFrame::wavefront_steps`], [`GpuFrame::sorted_steps`]).

use super::passes::{begin_pass, Clock, ParamBlocks};
use super::{GpuFrame, LAYERS_MAX, LAYER_BYTES_MAX, TILE};
use crate::{Gpu, GpuError, WF_BINS};
use wgpu::util::DeviceExt;

/// Bytes of one path's state between the wavefront's steps (`WfPath` in
/// wavefront.wgsl).
pub(super) const WF_PATH_BYTES: u64 = 112;

/// The wavefront's steps of one bounce each, before the last step takes
/// every bounce left, in a scene without a medium (when `max_depth + 1`
/// is smaller, that many: a path outside a medium takes at most
/// `max_depth + 1` bounces, so then the last step's queue is empty).
const WF_SINGLE_STEPS: u32 = 16;

/// The same in a scene with a random-walk medium, whose paths take
/// hundreds of events (each a bounce, none raising the depth): in the
/// random-walk scene the queue shrinks by 3-4% a step at first, by 1%
/// after a hundred, and 128 steps leave the last one 2.6% of the tile's
/// pixels (66 of 2,560 at 61 x 35). Lavapipe, the random-walk scene at
/// 160 x 90, 16 spp, interleaved: 9 steps 12.6 / 13.4 s, 32 steps 12.2 / 10.7 s,
/// 128 steps 10.5 / 9.1 s (the megakernel 16.4-18.0 s).
const WF_MEDIUM_STEPS: u32 = 128;

/// Paths per wavefront tile at most (a 2048 x 2048 film in one tile where
/// the device dispatches 65,536 workgroups in x, in two where it
/// dispatches 65,535: `wavefront_shape` in render/wavefront.rs).
pub const WF_TILE_MAX: u64 = 1 << 22;

/// Paths per wavefront tile at most where a caller asks for more than
/// [`WF_TILE_MAX`] ([`GpuFrame::set_wavefront_tile`]): a 1920 x 1080
/// film's 16 samples in one run (3.7 GB of path state; the device's
/// binding and dispatch limits still cap it).
pub(super) const WF_TILE_LIMIT: u64 = 1 << 25;

/// What the sorted wavefront's sort did in a tile
/// ([`GpuFrame::sorted_steps`]): per step, the paths `trace_extend` listed
/// and their count in each bin (material records, the last bin shared by
/// the records from `WF_BINS - 1` on; the last step, unsorted, lists
/// none); and the bins of the last non-empty list in the order
/// `trace_shade` took it, which never decrease.
#[derive(Clone, Debug)]
pub struct SortedSteps {
    /// Paths listed per step.
    pub lengths: Vec<u32>,
    /// Per step, paths listed per bin.
    pub counts: Vec<Vec<u32>>,
    /// The bins of the last non-empty list, in shading order.
    pub last: Vec<u32>,
    /// Per slot of the tile (on step 0 its padded pixels, 8 x 8 blocks row
    /// by row of blocks, one padded film after another where the tile
    /// holds several samples), 1 + the last step whose list held the path
    /// in the last run, 0 where none did (the camera ray missed, or the
    /// tile has no such pixel). A path listed at step `k` was listed at every
    /// step before: its steps are `0 .. listed[slot]`. What
    /// `examples/wavefront_lanes.rs` models the SIMT lanes' use with.
    pub listed: Vec<u32>,
    /// Per slot, the bin of the path's hit at that last step (where
    /// `listed` is not 0).
    pub bins: Vec<u32>,
}

/// The wavefront path tracer's buffers for one frame (`trace` in
/// wavefront.wgsl, docs/gpu.md "The wavefront path tracer").
pub(super) struct Wavefront {
    bind: wgpu::BindGroup,
    /// The queues (and the sorted wavefront's lists), for diagnostics.
    queue: wgpu::Buffer,
    /// The sorted wavefront's hits, for diagnostics.
    hits: wgpu::Buffer,
    /// Per step `[workgroups, 1, 1, queued paths]`: filled by the steps.
    pub(super) ctl: wgpu::Buffer,
    /// `ctl` as it is before a tile's first step.
    pub(super) ctl_init: wgpu::Buffer,
    /// The next indirect dispatch's arguments, copied from `ctl`.
    indirect: wgpu::Buffer,
    /// Paths per tile (a multiple of 64), and tiles per film.
    tile: u32,
    tiles: u32,
    /// Steps per tile, the last included.
    steps: u32,
    /// Padded pixels of the film (8 x 8 blocks).
    padded: u32,
    /// Samples per run at most: a film that fits a tile several times runs
    /// that many samples' paths in one (`tile` = `samples * padded`, one
    /// tile per film), each sample's into a sample layer that `resolve`
    /// adds after the run; 1 where the film takes one tile or more.
    pub(super) samples: u32,
    /// Made for the sorted wavefront (its hits, its lists and their
    /// counters; [`GpuFrame::set_sorted`]).
    sorted: bool,
}

impl Wavefront {
    /// The camera rays' slots of a run of `n` samples in the tile that
    /// starts at padded pixel `start`: the tile's pixels, or the run's
    /// samples' where the tile holds several (`n * padded`, `start` 0).
    fn camera_slots(&self, n: u32, start: u32) -> u32 {
        self.tile.min(n * self.padded - start)
    }
}

/// The pixels of a `width x height` film in whole 8 x 8 tiles (`TILE`):
/// the wavefront's paths of one sample (its slots), what a tile of `n`
/// samples' paths holds `n` times.
pub fn padded_pixels(width: u32, height: u32) -> u32 {
    width.div_ceil(TILE) * height.div_ceil(TILE) * TILE * TILE
}

/// The wavefront's samples a run and paths a tile for a film of `padded`
/// pixels (whole 8 x 8 tiles): up to `samples_max` samples' paths in one
/// tile where the film fits the tile that many times, else one sample's
/// in tiles of up to `fit` paths (what the path buffer binds). Every
/// step is a dispatch of a workgroup of 64 threads per path of the tile,
/// in x alone (`wf_begin` reads `gid.x`), so a tile holds at most 64
/// times `groups_max`, the device's workgroups per dimension: 65,535 on
/// lavapipe and under DX12 (the least Vulkan and WebGPU promise), where a
/// tile of 2^22 paths (a film of 2048 x 2048 pixels or more in tiles of
/// `WF_TILE_MAX`, on a device binding 470 MB or more; NVIDIA allows
/// 2^31 - 1) asked for 65,536 and wgpu refused the dispatch.
fn wavefront_shape(padded: u32, fit: u64, groups_max: u64, samples_max: u64) -> (u32, u32) {
    let fit = (fit.min(64 * groups_max) / 64 * 64).max(64);
    let samples = (fit / padded as u64).min(samples_max).max(1) as u32;
    let tile = if samples > 1 {
        samples * padded
    } else {
        (padded as u64).min(fit) as u32
    };
    (samples, tile)
}

impl GpuFrame {
    /// Paths per tile of the wavefront at most (rounded down to a
    /// multiple of 64, at least 64, at most 2^25; by default 2^22; fewer
    /// where the adapter binds or dispatches less): a film of more padded
    /// pixels runs in several tiles, one after another. The same image
    /// whatever the tile. For tests (a film in several tiles without a
    /// huge film) and comparisons (`isolux bench gpu --runs`: more
    /// samples a run at 1080p than the default tile holds).
    pub fn set_wavefront_tile(&mut self, paths: u64) {
        self.tile_max = paths.clamp(64, WF_TILE_LIMIT);
        self.wf = None;
    }

    /// The wavefront's samples a run and tiles a run, as the last run
    /// made them; `None` before the wavefront ran.
    pub fn wavefront_runs(&self) -> Option<(u32, u32)> {
        self.wf.as_ref().map(|wf| (wf.samples, wf.tiles))
    }

    /// Samples the wavefront runs together at most (1 to 16, the
    /// default): a film whose padded pixels fit a tile `n` times or more
    /// runs `n` samples' paths in one tile (at 1920 x 1080 two fit the
    /// default tile of 2^22 paths), so that each step is one dispatch
    /// for all of them: fewer dispatches and fuller late steps. Each
    /// sample ends in a sample layer, added to the pixels in sample order
    /// after the run (`resolve`), so the image is the same whatever `n`.
    /// For comparisons and tests.
    pub fn set_wavefront_samples(&mut self, n: u32) {
        self.wf_samples_max = n.clamp(1, LAYERS_MAX);
        self.wf = None;
    }

    /// How many paths each step of the wavefront ran, in the last tile of
    /// the last run queued (step 0: the tile's padded pixels, or the run's
    /// samples' where a tile holds several, [`GpuFrame::set_wavefront_samples`];
    /// waits for the queue); `None` before the wavefront ran. A
    /// diagnostic: the counts fall as paths end.
    pub fn wavefront_steps(&self, gpu: &Gpu) -> Result<Option<Vec<u32>>, GpuError> {
        let Some(wf) = self.wf.as_ref() else {
            return Ok(None);
        };
        let ctl: Vec<[u32; 4]> = gpu.read_back(&wf.ctl)?;
        let last = (wf.tiles - 1) * wf.tile;
        let mut out = vec![wf.camera_slots(self.wf_last_run.1, last)];
        out.extend(ctl[1..wf.steps as usize].iter().map(|c| c[3]));
        Ok(Some(out))
    }

    /// What the sorted wavefront's sort did in the last tile of the last
    /// run queued (its samples); `None` unless the sorted wavefront ran. A
    /// diagnostic ([`SortedSteps`]).
    pub fn sorted_steps(&self, gpu: &Gpu) -> Result<Option<SortedSteps>, GpuError> {
        let Some(wf) = self.wf.as_ref().filter(|wf| wf.sorted) else {
            return Ok(None);
        };
        let ctl: Vec<u32> = gpu.read_back(&wf.ctl)?;
        let steps = wf.steps as usize;
        let stride = 4 + 2 * WF_BINS as usize;
        let region = |k: usize| &ctl[4 * steps + k * stride..][..stride];
        let lengths: Vec<u32> = (0..steps).map(|k| region(k)[3]).collect();
        let counts = (0..steps)
            .map(|k| region(k)[4..4 + WF_BINS as usize].to_vec())
            .collect();
        // Later steps whose lists are empty leave the list region as the
        // last non-empty one wrote it.
        let len = lengths.iter().rfind(|&&n| n > 0).copied().unwrap_or(0) as usize;
        let queue: Vec<u32> = gpu.read_back(&wf.queue)?;
        let hits: Vec<[u32; 8]> = gpu.read_back(&wf.hits)?;
        let list = &queue[3 * wf.tile as usize..][..len];
        // trace_extend's stamp: 1 + step in bits 0-6, the tile's index in
        // bits 8-15, the run's first sample's in bits 16-31 (each modulo
        // its room).
        let (tile, sample) = (wf.tiles - 1, self.wf_last_run.0);
        let ours = |h: &[u32; 8]| h[6] >> 8 == (tile & 0xff) | (sample & 0xffff) << 8;
        let (listed, bins) = hits[..wf.tile as usize]
            .iter()
            .map(|h| if ours(h) { (h[6] & 0x7f, h[5]) } else { (0, 0) })
            .unzip();
        Ok(Some(SortedSteps {
            lengths,
            counts,
            last: list.iter().map(|&slot| hits[slot as usize][5]).collect(),
            listed,
            bins,
        }))
    }

    /// The wavefront's buffers for this film, made on first use: one tile
    /// of paths as large as the adapter binds, at most [`WF_TILE_MAX`].
    pub(super) fn make_wavefront(&mut self, gpu: &Gpu) {
        let params = self.params;
        let medium = self.random_walk;
        let sorted = self.sorted();
        let tile_max = self.tile_max;
        let samples_max = self.wf_samples_max as u64;
        let layers_fit = gpu.binding_limit().min(LAYER_BYTES_MAX) / self.layer_bytes().max(1);
        if self.wf.as_ref().is_some_and(|wf| wf.sorted != sorted) {
            self.wf = None;
        }
        let groups_max = gpu.device.limits().max_compute_workgroups_per_dimension as u64;
        self.wf.get_or_insert_with(|| {
            let (w, h) = (params.film[0], params.film[1]);
            let padded = padded_pixels(w, h);
            let fit = (gpu.binding_limit() / WF_PATH_BYTES).min(tile_max);
            let (samples, tile) =
                wavefront_shape(padded, fit, groups_max, samples_max.min(layers_fit));
            let tiles = padded.div_ceil(tile);
            let steps = if medium {
                WF_MEDIUM_STEPS
            } else {
                WF_SINGLE_STEPS.min(params.counts[2] + 1)
            } + 1;
            let paths = gpu.output("wavefront paths", tile as u64 * WF_PATH_BYTES);
            // The sorted wavefront's two lists after the two queues, its
            // hits (two `vec4`s a path), and per step its lists' counters
            // after the steps' (wavefront.wgsl `sort_base`).
            let lists = if sorted { 4 } else { 2 };
            let queue = gpu.output("wavefront queues", lists * tile as u64 * 4);
            let hits = gpu.output("wavefront hits", if sorted { tile as u64 * 32 } else { 16 });
            let mut init: Vec<[u32; 4]> = (0..steps).map(|_| [0, 1, 1, 0]).collect();
            if sorted {
                for _ in 0..steps {
                    init.push([0, 1, 1, 0]);
                    init.extend((0..WF_BINS / 2).map(|_| [0; 4]));
                }
            }
            let ctl_init = gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("wavefront counters (clear)"),
                    contents: bytemuck::cast_slice(&init),
                    usage: wgpu::BufferUsages::COPY_SRC,
                });
            // Then the frame's count of paths ended at the cap of their
            // medium events (wavefront.wgsl `wf_end`): not in `ctl_init`,
            // so a tile's first step keeps it; cleared by `reset`.
            let ctl = gpu.output("wavefront counters", (init.len() as u64 + 1) * 16);
            // A step's dispatch, then the sorted wavefront's lists'.
            let indirect = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("wavefront dispatch"),
                size: 32,
                usage: wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let bind = gpu.wavefront_bind_group(&[&paths, &queue, &ctl, &hits]);
            Wavefront {
                bind,
                queue,
                hits,
                ctl,
                ctl_init,
                indirect,
                tile,
                tiles,
                steps,
                padded,
                samples,
                sorted,
            }
        });
        let samples = self.wf.as_ref().map_or(1, |wf| wf.samples);
        self.grow_layers(gpu, samples);
    }

    /// Queues samples `self.samples ..` (`count` of them) of the wavefront
    /// path tracer in one submission: per run of up to `Wavefront::samples`
    /// samples, its layers cleared, then per tile the counters cleared,
    /// step 0 over the tile's pixels (the run's samples' where the tile
    /// holds several), then each step `k` over the
    /// paths step `k - 1` queued (an indirect dispatch whose workgroups
    /// step `k - 1` counted). The sorted wavefront runs each step but the
    /// last as `trace_extend` (as `trace`'s dispatch), then
    /// `trace_scatter`, `trace_shadow` (where
    /// [`Features::shadows_ahead`](crate::Features::shadows_ahead)) and `trace_shade` over the paths
    /// `trace_extend` listed (an indirect dispatch whose workgroups it
    /// counted). After the run's last tile, `resolve` adds its layers to
    /// the sums in sample order. Timestamps as in
    /// [`GpuFrame::dispatch_samples`].
    pub(super) fn dispatch_wavefront(&mut self, gpu: &Gpu, count: u32, clock: &mut Clock) {
        let first = self.samples;
        let params = self.params;
        let pipeline = gpu.trace_pipeline(self.features, false);
        let last_pipeline = gpu.trace_pipeline(self.features, true);
        let sorted = self.sorted().then(|| gpu.sorted_pipelines(self.features));
        self.make_wavefront(gpu);
        let Some(wf) = self.wf.as_ref() else {
            return;
        };
        let resolve = gpu.resolve_pipeline();
        // Runs of up to `wf.samples` samples, each of all its tiles.
        let per = wf.samples;
        let runs: Vec<(u32, u32)> = (0..count)
            .step_by(per as usize)
            .map(|s| (first + s, per.min(count - s)))
            .collect();
        let mut blocks = Vec::new();
        for &(s0, n) in &runs {
            for t in 0..wf.tiles {
                for k in 0..wf.steps {
                    let mut p = params;
                    p.pass_info[0] = s0;
                    p.pass_info[1] = 1;
                    p.wave = [k, wf.steps, t * wf.tile, wf.tile];
                    // The run's samples (sample `s0 + z` ends in layer z,
                    // which `resolve` adds to the sums after the run) and
                    // `trace_extend`'s sort key: material or none.
                    p.layers = [n, 0, self.by_material as u32, 0];
                    blocks.push(p);
                }
            }
        }
        let staged = ParamBlocks::new(gpu, &blocks);
        let mut enc = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("wavefront"),
            });
        let total = blocks.len();
        for (i, block) in blocks.iter().enumerate() {
            let [k, _, start, _] = block.wave;
            let n = block.layers[0];
            let last_tile = start / wf.tile + 1 == wf.tiles;
            if k == 0 && start == 0 {
                // The run's layers, which its paths add to as they end.
                enc.clear_buffer(&self.layers, 0, Some(n as u64 * self.layer_bytes()));
            }
            if k == 0 {
                enc.copy_buffer_to_buffer(&wf.ctl_init, 0, &wf.ctl, 0, wf.ctl_init.size());
            } else {
                enc.copy_buffer_to_buffer(&wf.ctl, k as u64 * 16, &wf.indirect, 0, 16);
            }
            let at = staged.offset(&mut enc, &self.params_buf, i);
            let last = k + 1 == wf.steps;
            let kernels = sorted.as_ref().filter(|_| !last && k < self.sorted_steps);
            let (name, step_pipeline) = match kernels {
                Some([extend, ..]) => ("trace_extend", extend),
                None if last => ("trace_last", &last_pipeline),
                None => ("trace", &pipeline),
            };
            let writes = clock.writes(gpu, name, Some(k), i == 0, false);
            let mut pass = begin_pass(&mut enc, "wavefront step", writes);
            pass.set_pipeline(step_pipeline);
            pass.set_bind_group(0, &self.bind, &[at]);
            pass.set_bind_group(1, &wf.bind, &[]);
            if k == 0 {
                let slots = wf.camera_slots(n, start);
                pass.dispatch_workgroups(slots.div_ceil(64), 1, 1);
            } else {
                pass.dispatch_workgroups_indirect(&wf.indirect, 0);
            }
            drop(pass);
            if let Some([_, scatter, shadow, shade]) = kernels {
                // The list's counters: after the steps', 4 + 2 WF_BINS
                // words a step (wavefront.wgsl `sort_base`).
                let list = (wf.steps as u64 * 4 + k as u64 * (4 + 2 * WF_BINS as u64)) * 4;
                enc.copy_buffer_to_buffer(&wf.ctl, list, &wf.indirect, 16, 16);
                // One pass (a pass each when profiled): wgpu orders a
                // pass's dispatches by their storage use (as `samples`
                // runs `main`, then `resolve`), each a thread per listed
                // path (the list's workgroups, counted by `trace_extend`).
                let mut kernels = vec![("trace_scatter", scatter)];
                if self.features.shadows_ahead() {
                    kernels.push(("trace_shadow", shadow));
                }
                kernels.push(("trace_shade", shade));
                let dispatch = |pass: &mut wgpu::ComputePass, pipeline| {
                    pass.set_bind_group(0, &self.bind, &[at]);
                    pass.set_bind_group(1, &wf.bind, &[]);
                    pass.set_pipeline(pipeline);
                    pass.dispatch_workgroups_indirect(&wf.indirect, 16);
                };
                if clock.each() {
                    for (name, pipeline) in kernels {
                        let writes = clock.writes(gpu, name, Some(k), false, false);
                        dispatch(&mut begin_pass(&mut enc, name, writes), pipeline);
                    }
                } else {
                    let mut pass = begin_pass(&mut enc, "wavefront sort", None);
                    for (_, pipeline) in kernels {
                        dispatch(&mut pass, pipeline);
                    }
                }
            }
            if last && last_tile {
                // The run's layers added to the sums in sample order (the
                // parameters' `layers`: n of them, not replacing).
                let writes = clock.writes(gpu, "resolve", None, false, i + 1 == total);
                let mut pass = begin_pass(&mut enc, "resolve", writes);
                pass.set_bind_group(0, &self.bind, &[at]);
                pass.set_pipeline(&resolve);
                let (gx, gy) = self.film_groups();
                pass.dispatch_workgroups(gx, gy, 1);
            }
        }
        clock.resolve(gpu, &mut enc);
        gpu.queue.submit(Some(enc.finish()));
        if let Some(&run) = runs.last() {
            self.wf_last_run = run;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each step of the wavefront dispatches a workgroup per 64 paths of
    /// its tile in x: never more than the device allows, on any film,
    /// binding and sample count; a tile holds whole samples where it holds
    /// more than one, and a film in tiles runs one sample a run.
    #[test]
    fn wavefront_tiles_fit_the_dispatch_limit() {
        let films = [
            (160, 90),
            (1920, 1080),
            (2048, 2048),
            (2560, 1640),
            (3840, 2160),
            (8192, 8192),
        ];
        for (w, h) in films {
            let padded = padded_pixels(w, h);
            for binding in [128u64 << 20, 1 << 30, (4u64 << 30) - 1, 1 << 40] {
                for groups_max in [65_535u64, (1 << 31) - 1] {
                    for (samples_max, tile_max) in [
                        (1, WF_TILE_MAX),
                        (2, WF_TILE_MAX),
                        (16, WF_TILE_MAX),
                        (16, WF_TILE_LIMIT),
                    ] {
                        let fit = (binding / WF_PATH_BYTES).min(tile_max);
                        let (samples, tile) = wavefront_shape(padded, fit, groups_max, samples_max);
                        let case = format!("{w}x{h}, binding {binding}, {groups_max} groups, {samples_max} samples: {samples} x {tile}");
                        assert!((tile as u64).div_ceil(64) <= groups_max, "{case}");
                        assert!(tile as u64 <= fit.max(64), "{case}");
                        assert!(samples >= 1 && samples as u64 <= samples_max, "{case}");
                        if samples > 1 {
                            assert_eq!(tile, samples * padded, "{case}");
                        } else {
                            assert!(tile <= padded && tile % 64 == 0, "{case}");
                        }
                    }
                }
            }
        }
        // 1080p, two samples a run in the default tile, on every device.
        let padded = 240 * 135 * 64;
        assert_eq!(
            wavefront_shape(padded, WF_TILE_MAX, 65_535, 16),
            (2, 2 * padded)
        );
        // All 16 in the largest tile where the device dispatches them.
        assert_eq!(
            wavefront_shape(padded, WF_TILE_LIMIT, (1 << 31) - 1, 16),
            (16, 16 * padded)
        );
    }
}
