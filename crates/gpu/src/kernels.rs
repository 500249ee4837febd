//! The device's kernels: shader modules compiled from this crate's
//! WGSL (probed for indices out of bounds where asked), the bind group
//! layouts of the render and wavefront kernels, and their pipelines,
//! each compiled on first use and cached on the [`Gpu`].

use crate::{
    binds_wavefront_group, params_size, probe_spirv, render_source_variant, Features, Gpu,
    OutOfBounds, PARAMS_BINDING, RENDER_BINDINGS, WAVEFRONT_BINDINGS,
};
use std::sync::OnceLock;

impl Gpu {
    /// A render module of this crate's WGSL: probed for indices out of
    /// bounds where [`Gpu::set_bounds_probe`] asks, otherwise as
    /// [`Gpu::module`] compiles it.
    fn render_module(&self, source: String) -> wgpu::ShaderModule {
        match self.bounds_probe {
            Some(policy) => self.probe_module("render", &source, policy),
            None => self.module("render", source),
        }
    }

    /// `source` written as SPIR-V by naga with every index checked by
    /// `policy` (and every loop bounded, as wgpu's checked modules are),
    /// passed through to the driver. An error (none is expected: the
    /// sources are validated by the unit tests) is kept for
    /// [`Gpu::check`], and the module is then compiled without the probe,
    /// so that the next wait reports it.
    fn probe_module(&self, label: &str, source: &str, policy: OutOfBounds) -> wgpu::ShaderModule {
        match probe_spirv(source, policy) {
            Ok(words) => {
                // SAFETY: the SPIR-V is naga's, written from this crate's
                // WGSL after naga validated it, for a Vulkan device
                // (`for_bounds_probes` opens no other).
                unsafe {
                    self.device.create_shader_module_passthrough(
                        wgpu::ShaderModuleDescriptorPassthrough {
                            label: Some(label),
                            spirv: Some(words.into()),
                            ..Default::default()
                        },
                    )
                }
            }
            Err(e) => {
                if let Ok(mut first) = self.failure.lock() {
                    first.get_or_insert(format!("the bounds probe's SPIR-V: {e}"));
                }
                self.module(label, source.to_string())
            }
        }
    }

    /// A module of this crate's WGSL, with or without wgpu's run-time
    /// checks ([`Gpu::set_runtime_checks`]).
    fn module(&self, label: &str, source: String) -> wgpu::ShaderModule {
        let desc = wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        };
        if self.runtime_checks {
            return self.device.create_shader_module(desc);
        }
        // SAFETY: `ShaderRuntimeChecks::unchecked` asks that no loop of
        // the module runs forever and no index leaves its array. The
        // modules are this crate's own shaders, whose loops all end and
        // whose indices stay in bounds (`set_runtime_checks`); buffer
        // accesses keep the driver's robust access where it offers it.
        unsafe {
            self.device
                .create_shader_module_trusted(desc, wgpu::ShaderRuntimeChecks::unchecked())
        }
    }

    pub(crate) fn pipeline<'a>(
        &self,
        cell: &'a OnceLock<wgpu::ComputePipeline>,
        label: &str,
        source: impl FnOnce() -> String,
    ) -> &'a wgpu::ComputePipeline {
        cell.get_or_init(|| {
            let module = self.module(label, source());
            self.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(label),
                    layout: None,
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: Default::default(),
                    cache: None,
                })
        })
    }

    /// A storage buffer holding `bytes` (padded: storage buffers may not
    /// be empty).
    /// The bind group layout shared by `render.wgsl`'s entry points (the
    /// path tracer and the real-time mode): explicit, so that both bind
    /// the same buffers whichever of them each entry point reads.
    fn render_layout(&self) -> &(wgpu::BindGroupLayout, wgpu::PipelineLayout) {
        self.render_layout.get_or_init(|| {
            use wgpu::BufferBindingType as B;
            // objects, perturbations, materials, lights, env texels,
            // env cdf, accum (rw), params (read-only storage, not
            // uniform: see `params_buffer`), material data, env levels,
            // BVH nodes, AOVs (rw), material albedos, tile lists (rw),
            // sample layers (rw).
            let kinds: [B; RENDER_BINDINGS] = [
                B::Storage { read_only: true },
                B::Storage { read_only: true },
                B::Storage { read_only: true },
                B::Storage { read_only: true },
                B::Storage { read_only: true },
                B::Storage { read_only: true },
                B::Storage { read_only: false },
                B::Storage { read_only: true },
                B::Storage { read_only: true },
                B::Storage { read_only: true },
                B::Storage { read_only: true },
                B::Storage { read_only: false },
                B::Storage { read_only: true },
                B::Storage { read_only: false },
                B::Storage { read_only: false },
            ];
            let bgl = self.buffer_layout("render bindings", &kinds, Some(PARAMS_BINDING));
            let pl = self
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("render"),
                    bind_group_layouts: &[&bgl],
                    push_constant_ranges: &[],
                });
            (bgl, pl)
        })
    }

    /// The path tracer (`realtime` false, entry `main`, camera.wgsl) or the real-time
    /// mode (entry `realtime`, realtime.wgsl) of the render kernels, with the code of
    /// `features`.
    pub(crate) fn render_pipeline(
        &self,
        realtime: bool,
        features: Features,
    ) -> wgpu::ComputePipeline {
        self.render_entry(if realtime { "realtime" } else { "main" }, features)
    }

    /// The sum of a dispatch's sample layers (`resolve` of `camera.wgsl`).
    pub(crate) fn resolve_pipeline(&self) -> wgpu::ComputePipeline {
        self.render_entry("resolve", Features::NONE)
    }

    /// The camera rays' tile lists (`cull_tiles` of `camera.wgsl`).
    pub(crate) fn cull_pipeline(&self) -> wgpu::ComputePipeline {
        self.render_entry("cull_tiles", Features::NONE)
    }

    /// The AOV kernel (`aov_main` of `aov.wgsl`).
    pub(crate) fn aov_pipeline(&self, features: Features) -> wgpu::ComputePipeline {
        self.render_entry("aov_main", features)
    }

    /// The wavefront path tracer's step (`trace` of `wavefront.wgsl`: one
    /// bounce; `trace_last` on the `last` step: every bounce left), bound
    /// with the render group and [`Gpu::wavefront_layout`]'s group 1.
    pub(crate) fn trace_pipeline(&self, features: Features, last: bool) -> wgpu::ComputePipeline {
        self.render_entry(if last { "trace_last" } else { "trace" }, features)
    }

    /// The sorted wavefront's kernels of one step, in their order:
    /// `trace_extend`, `trace_scatter`, `trace_shadow`
    /// (run where [`Features::shadows_ahead`]), `trace_shade`
    /// ([`PathKernel::Sorted`](crate::PathKernel::Sorted)).
    pub(crate) fn sorted_pipelines(&self, features: Features) -> [wgpu::ComputePipeline; 4] {
        [
            "trace_extend",
            "trace_scatter",
            "trace_shadow",
            "trace_shade",
        ]
        .map(|entry| self.render_entry(entry, features))
    }

    /// Group 1 of `trace` (paths, queues, step counters, all read-write
    /// storage) and the pipeline layout of groups 0 and 1.
    fn wavefront_layout(&self) -> &(wgpu::BindGroupLayout, wgpu::PipelineLayout) {
        self.wavefront_layout.get_or_init(|| {
            let rw = wgpu::BufferBindingType::Storage { read_only: false };
            let bgl = self.buffer_layout("wavefront bindings", &[rw; WAVEFRONT_BINDINGS], None);
            let pl = self
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("wavefront"),
                    bind_group_layouts: &[&self.render_layout().0, &bgl],
                    push_constant_ranges: &[],
                });
            (bgl, pl)
        })
    }

    /// A bind group of the wavefront's group 1 with `buffers` at bindings
    /// 0, 1, 2, 3.
    pub(crate) fn wavefront_bind_group(
        &self,
        buffers: &[&wgpu::Buffer; WAVEFRONT_BINDINGS],
    ) -> wgpu::BindGroup {
        self.buffer_bind_group("wavefront", &self.wavefront_layout().0, buffers, None)
    }

    /// A compute bind group layout of buffers of `kinds` at bindings 0, 1,
    /// 2, ... in order; binding `params` (where given) is a
    /// [`GpuParams`](crate::layout::GpuParams) block at a dynamic offset
    /// (see [`Gpu::params_stride`]).
    fn buffer_layout(
        &self,
        label: &str,
        kinds: &[wgpu::BufferBindingType],
        params: Option<u32>,
    ) -> wgpu::BindGroupLayout {
        let entries: Vec<wgpu::BindGroupLayoutEntry> = kinds
            .iter()
            .enumerate()
            .map(|(i, &ty)| {
                let block = params == Some(i as u32);
                wgpu::BindGroupLayoutEntry {
                    binding: i as u32,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty,
                        has_dynamic_offset: block,
                        min_binding_size: block.then(params_size),
                    },
                    count: None,
                }
            })
            .collect();
        self.device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries: &entries,
            })
    }

    /// A bind group of `layout` with `buffers` whole at bindings 0, 1, 2,
    /// ... in order, but for binding `params` (where given): one
    /// [`GpuParams`](crate::layout::GpuParams) block of it, at the dynamic
    /// offset each `set_bind_group` names.
    pub(crate) fn buffer_bind_group(
        &self,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        buffers: &[&wgpu::Buffer],
        params: Option<u32>,
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: if params == Some(i as u32) {
                    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: b,
                        offset: 0,
                        size: Some(params_size()),
                    })
                } else {
                    b.as_entire_binding()
                },
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &entries,
        })
    }

    /// Entry point `entry` with the part of `features` it reaches
    /// ([`Features::reached_by`]), compiled on first use (its module too).
    fn render_entry(&self, entry: &'static str, features: Features) -> wgpu::ComputePipeline {
        let features = features.reached_by(entry);
        let mut kernels = self.kernels.lock().unwrap_or_else(|e| e.into_inner());
        kernels
            .entry((entry, features))
            .or_insert_with(|| {
                let mut modules = self
                    .render_modules
                    .lock()
                    .unwrap_or_else(|e| e.into_inner());
                let module = modules.entry(features).or_insert_with(|| {
                    self.render_module(render_source_variant(self.precision, features))
                });
                self.device
                    .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(entry),
                        layout: Some(if binds_wavefront_group(entry) {
                            &self.wavefront_layout().1
                        } else {
                            &self.render_layout().1
                        }),
                        module,
                        entry_point: Some(entry),
                        compilation_options: Default::default(),
                        cache: None,
                    })
            })
            .clone()
    }

    pub(crate) fn render_bind_group(&self, buffers: &[&wgpu::Buffer]) -> wgpu::BindGroup {
        self.buffer_bind_group(
            "render",
            &self.render_layout().0,
            buffers,
            Some(PARAMS_BINDING),
        )
    }
}
