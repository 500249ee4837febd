//! Draws a [`GpuFrame`]'s accumulation buffer into a rectangle of the
//! window (`shaders/display.wgsl`): no copy, the fragment shader reads the
//! buffer the compute kernels wrote.

use isolux_gpu::wgpu;
use isolux_gpu::GpuFrame;

/// The display shader's source: the flag constants generated from the
/// Rust values, then `shaders/display.wgsl`.
pub fn source() -> String {
    format!(
        "const REINHARD: u32 = {REINHARD}u;\nconst ENCODE_SRGB: u32 = {ENCODE_SRGB}u;\n{}",
        include_str!("shaders/display.wgsl")
    )
}

/// Mirror of `Display` in `display.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DisplayParams {
    /// Top-left corner of the area, framebuffer pixels.
    pub origin: [f32; 2],
    /// Size of the area, framebuffer pixels.
    pub size: [f32; 2],
    /// Film width and height.
    pub film: [u32; 2],
    /// `2^exposure / samples`.
    pub scale: f32,
    /// Bit 0: Reinhard tone map (else clamp); bit 1: encode sRGB in the
    /// shader (for surfaces whose format does not).
    pub flags: u32,
}

const _: () = assert!(std::mem::size_of::<DisplayParams>() == 32);

/// Flag: Reinhard tone map.
pub const REINHARD: u32 = 1;
/// Flag: encode sRGB in the shader.
pub const ENCODE_SRGB: u32 = 2;

/// The display pipeline for one surface format.
pub struct Display {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
}

impl Display {
    /// Compiles the pipeline for `format`.
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("display"),
            source: wgpu::ShaderSource::Wgsl(source().into()),
        });
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("display"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Storage { read_only: true }),
                entry(1, wgpu::BufferBindingType::Uniform),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("display"),
            bind_group_layouts: &[&layout],
            push_constant_ranges: &[],
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("display"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            multiview: None,
            cache: None,
        });
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("display params"),
            size: std::mem::size_of::<DisplayParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            pipeline,
            layout,
            params,
        }
    }

    /// Records the drawing of `frame` into `area` (`x, y, width, height`
    /// in framebuffer pixels) of `pass`, with `params` (its `origin`,
    /// `size` and `film` are filled in here).
    pub fn draw(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pass: &mut wgpu::RenderPass<'_>,
        frame: &GpuFrame,
        area: [f32; 4],
        mut params: DisplayParams,
    ) {
        let (w, h) = frame.size();
        params.origin = [area[0], area[1]];
        params.size = [area[2].max(1.0), area[3].max(1.0)];
        params.film = [w, h];
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("display"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: frame.accumulation().as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.params.as_entire_binding(),
                },
            ],
        });
        pass.set_viewport(area[0], area[1], area[2], area[3], 0.0, 1.0);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.draw(0..3, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shader validates, and its `Display` struct has the Rust
    /// mirror's size.
    #[test]
    fn display_shader_validates_and_matches_the_mirror() {
        let module = naga::front::wgsl::parse_str(&source()).expect("display.wgsl parses");
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .expect("display.wgsl validates");
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).unwrap();
        let (handle, _) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("Display"))
            .expect("struct Display");
        assert_eq!(
            layouter[handle].size as usize,
            std::mem::size_of::<DisplayParams>()
        );
        let names: Vec<_> = module
            .entry_points
            .iter()
            .map(|e| e.name.as_str())
            .collect();
        assert_eq!(names, ["vs_main", "fs_main"]);
    }
}
