//! The GPU path tracer's host side: uploads a [`Scene`] once
//! ([`Gpu::prepare`]), runs passes of samples into an accumulation buffer
//! ([`GpuFrame::run`], progressive), and reads the image back
//! ([`GpuFrame::image`]). [`Gpu::render`] does all three for a whole film.

use crate::checks::{
    f32_shortfall, material_data_fits, material_values_fit, mix_of_waves, planar_wave,
    unsupported_material,
};
use crate::layout::{self, GpuLight, GpuMaterials, GpuParams, GpuScene};
use crate::{Features, Gpu, GpuError, ENV_CONSTANT, ENV_MAP};
use isolux_core::{Aovs, Image, Rgb};
use isolux_render::{Camera, Environment, MediumLightSampling, RenderStats, Scene};

mod env;
mod media;
mod passes;
mod wavefront;
use env::{env_levels, env_tables};
use media::{bounded, flat_routes, innermost, manifold_media, media_first, medium_of};
pub use media::{medium_bits, nested_too_deep, refracted_media};
use passes::{begin_pass, Clock, ParamBlocks, Stamps};
pub use passes::{DispatchTime, Profile, PARAM_BLOCKS};
pub use wavefront::{padded_pixels, SortedSteps, WF_TILE_MAX};
use wavefront::{Wavefront, WF_PATH_BYTES};

/// Workgroup edge of the render kernel (8 x 8 pixels; `render.wgsl`).
pub(crate) const TILE: u32 = 8;

/// Objects in a tile's list at most (`cull_tiles` in `camera.wgsl`); a
/// tile whose rays' pyramid meets more walks the hierarchy per ray.
pub(crate) const TILE_LIST_MAX: u32 = 16;

/// Bytes of the tile lists of a `width x height` film (`tile_lists` in
/// `render.wgsl`, written by `cull_tiles` in `camera.wgsl`: `TILE_LIST_MAX + 1` words per tile).
fn tile_list_bytes(width: u32, height: u32) -> u64 {
    width.div_ceil(TILE) as u64 * height.div_ceil(TILE) as u64 * (TILE_LIST_MAX as u64 + 1) * 4
}

/// Sample layers of one dispatch of `main` or `realtime` at most: a run of
/// more samples takes several dispatches ([`Gpu::render`] runs a film's
/// samples in up to 16 passes, for its progress reports: passes of
/// `spp / 16` samples, at least 4).
const LAYERS_MAX: u32 = 16;

/// Bytes of sample layers a frame holds at most (16 layers at 1920 x 1080
/// fit), so that a large film takes fewer samples per dispatch rather than
/// more memory.
const LAYER_BYTES_MAX: u64 = 512 << 20;

/// The megakernel's group 1 (the wavefront's layout, [`Gpu::wavefront_layout`]):
/// `main` counts the paths it ends at `MAX_MEDIUM_EVENTS` in the first
/// word of `ctl`, as `wf_end` does in the last four of the wavefront's
/// counters (camera.wgsl `count_capped`); the other three bindings are
/// stubs of one element, which `main` never reads.
struct MegaCount {
    bind: wgpu::BindGroup,
    ctl: wgpu::Buffer,
}

impl MegaCount {
    fn new(gpu: &Gpu) -> MegaCount {
        let paths = gpu.output("megakernel group 1 (paths stub)", WF_PATH_BYTES);
        let queue = gpu.output("megakernel group 1 (queue stub)", 16);
        let hits = gpu.output("megakernel group 1 (hits stub)", 16);
        // Created zeroed (wgpu clears new buffers), cleared by `reset`.
        let ctl = gpu.output("megakernel capped paths", 16);
        let bind = gpu.wavefront_bind_group(&[&paths, &queue, &ctl, &hits]);
        MegaCount { bind, ctl }
    }
}

/// Whether `materials` hold a random-walk medium's record.
pub(crate) fn random_walk(materials: &GpuMaterials) -> bool {
    materials
        .materials
        .iter()
        .any(|m| m.tag[0] == layout::tag::SUBSURFACE && m.tag[3] == 1)
}

/// The path kernel of a frame that runs as a wavefront or not, sorted or
/// not.
fn resolved_kernel(wavefront: bool, sorted: bool) -> crate::PathKernel {
    match (wavefront, sorted) {
        (false, _) => crate::PathKernel::Megakernel,
        (true, false) => crate::PathKernel::Wavefront,
        (true, true) => crate::PathKernel::Sorted,
    }
}

/// The world point the GPU takes as its origin for `scene`: the camera
/// (rounded to f32), so that f32 coordinates are finest where the image
/// is seen from, whatever the scene's place in the world; the world
/// origin when a material of the scene maps a `wave` heightfield by plain
/// world coordinates (`planar_wave`), which would move with it.
/// Lights, the camera, the objects' frames and the `wave` mappings'
/// centres are uploaded relative to it (`GpuScene::with_materials_at`).
pub fn rebase_point(scene: &Scene) -> glam::DVec3 {
    if planar_wave(scene) {
        return glam::DVec3::ZERO;
    }
    layout::f32_exact(scene.camera.position)
}

/// `m` with its world positions (a `wave` mapping's centre) moved by
/// `-at` ([`rebase_point`]).
fn rebased_material(m: &isolux_materials::Material, at: glam::DVec3) -> isolux_materials::Material {
    use isolux_materials::wave::Mapping;
    use isolux_materials::Material as M;
    match m {
        M::Wave(w) => {
            let mut w = w.clone();
            w.mapping = match w.mapping {
                Mapping::Spherical(c) => Mapping::Spherical(c - at),
                Mapping::Cylindrical(c) => Mapping::Cylindrical(c - at),
                planar => planar,
            };
            M::Wave(w)
        }
        M::Mix(x) => {
            let mut x = x.clone();
            for (c, _) in x.components.iter_mut() {
                *c = rebased_material(c, at);
            }
            M::Mix(x)
        }
        other => other.clone(),
    }
}

/// A scene on the device with its accumulation buffer.
pub struct GpuFrame {
    /// The real-time mode (each [`GpuFrame::run`] renders a whole frame)
    /// rather than the progressive path tracer.
    realtime: bool,
    /// The world point the frame's buffers take as their origin
    /// ([`rebase_point`]).
    rebase: glam::DVec3,
    /// The optional code the kernels carry: by default what the scene
    /// needs ([`Features::of`]), more after [`GpuFrame::set_features`].
    features: Features,
    /// What the scene needs.
    needed: Features,
    bind: wgpu::BindGroup,
    /// The buffers of `bind` but the last, the sample layers (for a new
    /// `bind` when the layers grow).
    buffers: Vec<wgpu::Buffer>,
    /// `layer_count` sample layers of `width x height` `vec4<f32>`
    /// (`layers` in render.wgsl), grown on first use
    /// ([`GpuFrame::dispatch_samples`]).
    layers: wgpu::Buffer,
    layer_count: u32,
    /// Samples per dispatch at most ([`GpuFrame::set_max_layers`]).
    max_layers: u32,
    accum: wgpu::Buffer,
    params_buf: wgpu::Buffer,
    params: GpuParams,
    /// The AOV buffer, when the frame was prepared with AOVs.
    aov: Option<wgpu::Buffer>,
    /// Samples per pixel accumulated so far.
    pub samples: u32,
    /// Path trace with the wavefront kernel (`trace`) rather than the
    /// megakernel (`main`); see [`GpuFrame::set_wavefront`].
    wavefront: bool,
    /// Its buffers, made on first use.
    wf: Option<Wavefront>,
    /// The megakernel's group 1 and its count of paths ended at
    /// `MAX_MEDIUM_EVENTS`, made on its first run ([`MegaCount`]).
    mega: Option<MegaCount>,
    /// The wavefront's hits shaded in order of their material
    /// ([`GpuFrame::set_sorted`]).
    sorted: bool,
    /// The sorted wavefront sorts by material (else it keeps the order
    /// its hits were found in: [`GpuFrame::set_sort_by_material`]).
    by_material: bool,
    /// The sorted wavefront's steps before it runs the rest as the plain
    /// wavefront ([`GpuFrame::set_sorted_steps`]).
    sorted_steps: u32,
    /// Paths per wavefront tile at most ([`GpuFrame::set_wavefront_tile`]).
    tile_max: u64,
    /// Samples per wavefront run at most
    /// ([`GpuFrame::set_wavefront_samples`]).
    wf_samples_max: u32,
    /// The last wavefront run's first sample and its samples (for the
    /// diagnostics).
    wf_last_run: (u32, u32),
    /// Runs trace first hits only ([`Gpu::prepare_first_hits`]).
    first_hits: bool,
    /// The scene has a random-walk medium (long paths: more wavefront
    /// steps, `WF_MEDIUM_STEPS` in render/wavefront.rs).
    random_walk: bool,
    /// The objects of random-walk media (world coordinates) and `1 +`
    /// their material: where [`GpuFrame::set_camera`] looks up the medium
    /// the camera is in ([`medium_of`]).
    media: Vec<(isolux_geometry::Object, u32)>,
}

/// The optional code the kernels of `scene` need (models, the candidate
/// list and many lights' shadow rays by its size, null boundaries,
/// refracted and manifold lights by its media), given its materials on
/// the GPU, its geometry, its lights' flat media ([`refracted_media`]) and
/// whether [`manifold_media`] listed any.
fn needed(
    scene: &Scene,
    materials: &GpuMaterials,
    geo: &GpuScene,
    refracted: &[Option<(usize, isolux_render::FlatBoundary)>],
    manifold: bool,
) -> Features {
    Features {
        null_boundaries: scene.may_have_null_boundaries(),
        refraction: refracted.iter().any(Option::is_some) || manifold,
        manifold,
        caustics: scene.casts_caustics(),
        ..Features::of(&materials.materials).fit_to(geo, scene.lights.len())
    }
}

/// The optional code of the kernels that render `scene` (tile lists on,
/// as on GPUs), as [`Gpu::prepare`] decides it, without a GPU: what
/// `kernel_stats` compiles, so that its figures are those of the kernels
/// the scene runs. An error names a material the GPU does not run.
pub fn scene_features(scene: &Scene) -> Result<Features, GpuError> {
    scene_needs(scene).map(|(features, _)| features)
}

/// [`scene_features`], and whether the scene has a random-walk medium
/// (as [`Gpu::prepare`] tells them).
fn scene_needs(scene: &Scene) -> Result<(Features, bool), GpuError> {
    let mut materials = GpuMaterials::new(&scene.materials).map_err(|i| {
        GpuError::Setup(format!(
            "material {:?} does not run on the GPU",
            scene.material_names.get(i).map_or("?", String::as_str)
        ))
    })?;
    let (refracted, listed) = flat_routes(scene).map_err(GpuError::Setup)?;
    let manifold = manifold_media(scene, &listed, &mut materials)?;
    let geo = GpuScene::with_materials(scene.geometry.objects(), &scene.object_material);
    let features = needed(scene, &materials, &geo, &refracted, manifold);
    Ok((features, random_walk(&materials)))
}

impl Gpu {
    /// Uploads `scene` for path tracing at its film size. Fails, naming
    /// it, on a material not on the GPU, and on an invalid camera.
    pub fn prepare(&self, scene: &Scene) -> Result<GpuFrame, GpuError> {
        self.prepare_mode(scene, false, false)
    }

    /// Uploads `scene` for the real-time mode (`isolux_render::realtime`):
    /// each [`GpuFrame::run`] renders a whole frame of `count` samples per
    /// pixel, replacing the last.
    pub fn prepare_realtime(&self, scene: &Scene) -> Result<GpuFrame, GpuError> {
        self.prepare_mode(scene, true, false)
    }

    /// Uploads `scene` for first hits alone: each [`GpuFrame::run`] traces
    /// `count` camera rays per pixel (`aov_main`: the nearest hit, its
    /// albedo, distance and normal added to the AOV layers) and shades
    /// nothing, so its time is what the camera rays' exact intersection
    /// costs by itself (`isolux bench gpu`'s "first hit" row, beside the
    /// modes that shade). [`GpuFrame::aovs`] reads the layers the runs
    /// added (the same as [`Gpu::render_with_aov`]'s for as many samples);
    /// [`GpuFrame::image`] is black.
    pub fn prepare_first_hits(&self, scene: &Scene) -> Result<GpuFrame, GpuError> {
        let mut frame = self.prepare_mode(scene, false, true)?;
        frame.first_hits = true;
        Ok(frame)
    }

    /// Renders `scene` in the real-time mode at its film's `spp`.
    pub fn render_realtime(&self, scene: &Scene) -> Result<(Image, RenderStats), GpuError> {
        self.render_realtime_with_aov(scene, false)
    }

    /// [`Gpu::render_realtime`], with the AOV layers when `aov` is set.
    pub fn render_realtime_with_aov(
        &self,
        scene: &Scene,
        aov: bool,
    ) -> Result<(Image, RenderStats), GpuError> {
        let mut frame = self.prepare_mode(scene, true, aov)?;
        frame.run(self, scene.film.spp);
        let (mut image, stats) = frame.image(self)?;
        if aov {
            image.aov = Some(frame.aovs(self)?);
        }
        Ok((image, stats))
    }

    /// The render bind group of a frame: `buffers` at bindings 0-12, the
    /// sample layers at 13.
    fn frame_bind_group(&self, buffers: &[wgpu::Buffer], layers: &wgpu::Buffer) -> wgpu::BindGroup {
        let all: Vec<&wgpu::Buffer> = buffers.iter().chain([layers]).collect();
        self.render_bind_group(&all)
    }

    fn prepare_mode(
        &self,
        scene: &Scene,
        realtime: bool,
        with_aov: bool,
    ) -> Result<GpuFrame, GpuError> {
        // The kernels name media by material, the media's first.
        let reordered = media_first(scene);
        let scene = reordered.as_ref().unwrap_or(scene);
        if let Some((name, type_name)) = unsupported_material(scene) {
            return Err(GpuError::Unsupported { name, type_name });
        }
        if self.miscompiles_loops() {
            if let Some((name, n)) = mix_of_waves(scene) {
                return Err(GpuError::Setup(format!(
                    "material \"{name}\" mixes {n} `wave` materials, which this driver ({}) \
                     miscompiles (the wave code diverging across a SIMD group: sampled lobes \
                     come out wrong; docs/gpu.md, \"Known defect\"): render without --gpu, or \
                     on another driver (Mesa 25 or later, or a GPU's)",
                    self.driver
                )));
            }
        }
        if let Some(why) = f32_shortfall(scene) {
            return Err(GpuError::Precision(why));
        }
        if let Some(why) = nested_too_deep(scene) {
            return Err(GpuError::Setup(why));
        }
        let film = scene.film;
        if let Some(why) = film.problem() {
            return Err(GpuError::Setup(why.to_string()));
        }
        if let Some(why) = scene.integrator.problem() {
            return Err(GpuError::Setup(why));
        }
        let [origin, forward, right, up] = scene
            .camera
            .rig(film.width, film.height)
            .map_err(GpuError::Setup)?
            .basis();
        let v4 = |v: glam::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
        // World positions go up relative to the camera (`rebase_point`).
        let at = rebase_point(scene);
        let origin = origin - at;

        // Unused materials may be unsupported (checked above for the used
        // ones): those become a black diffuse no object refers to.
        let used: Vec<_> = (0..scene.materials.len())
            .map(|i| {
                if layout::supported(&scene.materials[i]) {
                    rebased_material(&scene.materials[i], at)
                } else {
                    isolux_materials::Material::Diffuse(isolux_materials::Diffuse {
                        reflectance: Rgb::BLACK,
                    })
                }
            })
            .collect();
        let mut materials = GpuMaterials::new(&used).expect("unsupported materials replaced");
        let (refracted, listed) = flat_routes(scene).map_err(GpuError::Setup)?;
        let manifold = manifold_media(scene, &listed, &mut materials)?;
        let geo = GpuScene::with_materials_at(scene.geometry.objects(), &scene.object_material, at);
        // In the order they nest, outermost first (`medium_of`).
        let media: Vec<_> = scene
            .media_nested()
            .into_iter()
            .map(|(i, o, _)| (o.clone(), scene.object_material[i] as u32 + 1))
            .collect();
        let bits = medium_bits(scene);
        let lights: Vec<GpuLight> = scene
            .lights
            .iter()
            .zip(&refracted)
            .map(|(l, r)| GpuLight {
                // w: 1 + the material of the random-walk medium the light
                // lies in (0: none), whose scattering events gather it.
                position: {
                    let [x, y, z, _] = v4(l.position - at);
                    [
                        x,
                        y,
                        z,
                        innermost(medium_of(&media, l.position, bits), bits) as f32,
                    ]
                },
                intensity: [
                    l.intensity.r as f32,
                    l.intensity.g as f32,
                    l.intensity.b as f32,
                    r.map_or(0, |(i, _)| scene.object_material[i] + 1) as f32,
                ],
                plane: r.map_or([0.0; 4], |(_, b)| {
                    let [x, y, z, _] = v4(b.normal);
                    [x, y, z, (b.offset - b.normal.dot(at)) as f32]
                }),
                flat: [
                    r.filter(|(_, b)| bounded(b))
                        .map_or(0, |(i, _)| i as u32 + 1),
                    r.map_or(0, |(i, _)| i as u32 + 1),
                    0,
                    0,
                ],
            })
            .collect();
        let (env_kind, env_rgb, env_size, texels, cdf) = match &scene.environment {
            Environment::Constant(c) => (
                ENV_CONSTANT,
                [c.r as f32, c.g as f32, c.b as f32, 0.0],
                [0, 0, 0, 0],
                Vec::new(),
                Vec::new(),
            ),
            Environment::Map(m) => {
                let (w, h) = m.size();
                let (t, c) = env_tables(w, h, m.texels());
                (ENV_MAP, [0.0; 4], [w as u32, h as u32, 0, 0], t, c)
            }
        };
        let (levels, level_count) = if realtime {
            env_levels(&scene.environment)?
        } else {
            (Vec::new(), 0)
        };
        let env_size = [env_size[0], env_size[1], level_count, 0];
        let grid_m = (film.spp as f64).sqrt().ceil() as u32;
        let grid_n = film.spp.div_ceil(grid_m);
        let seed = isolux_core::rng::mix64(scene.integrator.seed ^ 0x1502_7a1e);
        let params = GpuParams {
            origin: {
                let [x, y, z, _] = v4(origin);
                [x, y, z, 0.0]
            },
            forward: v4(forward),
            right: v4(right),
            up: v4(up),
            film: [film.width, film.height, grid_m, grid_n],
            pass_info: [0, 0, seed as u32, (seed >> 32) as u32],
            counts: [
                geo.objects.len() as u32,
                lights.len() as u32,
                scene.integrator.max_depth,
                env_kind,
            ],
            env: env_rgb,
            env_size,
            wave: [0; 4],
            layers: [0; 4],
            camera: [
                medium_of(&media, scene.camera.position, bits),
                scene.may_have_null_boundaries() as u32,
                (scene.integrator.medium_lights == MediumLightSampling::Equiangular) as u32,
                bits,
            ],
        };

        let limit = self.binding_limit();
        material_data_fits(&materials, &used, &scene.material_names, limit)?;
        material_values_fit(&materials, &used, &scene.material_names)?;
        let npix = film.width as u64 * film.height as u64;
        for (what, bytes) in [
            (
                "the environment map".to_string(),
                std::mem::size_of_val(&texels[..]) as u64,
            ),
            (
                format!(
                    "the {} x {} film's accumulation buffer",
                    film.width, film.height
                ),
                npix * if with_aov { 32 } else { 16 },
            ),
            (
                "the geometry's perturbations".to_string(),
                std::mem::size_of_val(&geo.perturbations[..]) as u64,
            ),
            (
                format!("the {} x {} film's tile lists", film.width, film.height),
                tile_list_bytes(film.width, film.height),
            ),
        ] {
            if bytes > limit {
                return Err(GpuError::TooLarge {
                    what,
                    bytes,
                    limit,
                    hint: String::new(),
                });
            }
        }
        let objects = self.storage("objects", bytemuck::cast_slice(&geo.objects));
        let perts = self.storage("perturbations", bytemuck::cast_slice(&geo.perturbations));
        let mats = self.storage("materials", bytemuck::cast_slice(&materials.materials));
        let data = self.storage("material data", bytemuck::cast_slice(&materials.data));
        let lights = self.storage("lights", bytemuck::cast_slice(&lights));
        let texels = self.storage("env texels", bytemuck::cast_slice(&texels));
        let cdf = self.storage("env cdf", bytemuck::cast_slice(&cdf));
        let accum = self.output("accumulation", npix * 16);
        let params_buf = self.param_blocks_buffer();
        let levels = self.storage("env levels", bytemuck::cast_slice(&levels));
        let nodes = self.storage("bvh nodes", bytemuck::cast_slice(&geo.nodes));
        // Albedo per scene material (the CPU's `albedo()`, the AOV's
        // definition), and the AOV buffer when asked for (else a stub).
        let albedos: Vec<[f32; 4]> = scene
            .materials
            .iter()
            .map(|m| {
                let a = isolux_materials::BxdfModel::albedo(m);
                [a.r as f32, a.g as f32, a.b as f32, 0.0]
            })
            .collect();
        let albedos = self.storage("albedos", bytemuck::cast_slice(&albedos));
        let aov = with_aov.then(|| self.output("aov", npix * 32));
        let aov_stub = self.output("aov stub", 32);
        let tile_lists = self.output("tile lists", tile_list_bytes(film.width, film.height));
        let buffers = vec![
            objects,
            perts,
            mats,
            lights,
            texels,
            cdf,
            accum.clone(),
            params_buf.clone(),
            data,
            levels,
            nodes,
            aov.clone().unwrap_or(aov_stub),
            albedos,
            tile_lists,
        ];
        // No layers until a run needs them (the wavefront never does).
        let layers = self.output("sample layers (none yet)", 16);
        let bind = self.frame_bind_group(&buffers, &layers);
        let needed = needed(scene, &materials, &geo, &refracted, manifold);
        let random_walk = random_walk(&materials);
        let (wavefront, sorted) = self.kernel_choice(random_walk, needed);
        let frame = GpuFrame {
            realtime,
            rebase: at,
            // Tile lists on GPUs only (`Features::tiles`).
            features: Features {
                tiles: !self.cpu,
                ..needed
            },
            needed,
            bind,
            buffers,
            layers,
            layer_count: 0,
            max_layers: LAYERS_MAX,
            accum,
            params_buf,
            params,
            aov,
            samples: 0,
            wavefront,
            wf: None,
            mega: None,
            sorted,
            by_material: true,
            sorted_steps: u32::MAX,
            tile_max: WF_TILE_MAX,
            wf_samples_max: LAYERS_MAX,
            wf_last_run: (0, 1),
            first_hits: false,
            random_walk,
            media,
        };
        frame.cull_tiles(self);
        Ok(frame)
    }

    /// Renders `scene` on the GPU: the film's samples in passes (at most
    /// 16, of at least 4 samples), `progress(done, total)` after each. The
    /// image is the mean of the samples; dropped (non-finite) samples
    /// count as black, as on the CPU, and in
    /// [`RenderStats::rejected_samples`].
    pub fn render(
        &self,
        scene: &Scene,
        progress: &dyn Fn(usize, usize),
    ) -> Result<(Image, RenderStats), GpuError> {
        self.render_with_aov(scene, false, progress)
    }

    /// Whether a frame path traces as a wavefront, and sorted where it
    /// can be ([`GpuFrame::sorted`]), for a scene with (`random_walk`) or
    /// without a random-walk medium that needs `needed`
    /// ([`crate::PathKernel`]).
    fn kernel_choice(&self, random_walk: bool, needed: Features) -> (bool, bool) {
        match self.path_kernel() {
            crate::PathKernel::Auto => (!self.cpu || random_walk || needed.wave(), !self.cpu),
            crate::PathKernel::Megakernel => (false, false),
            crate::PathKernel::Wavefront => (true, false),
            crate::PathKernel::Sorted => (true, true),
        }
    }

    /// The kernel that path traces `scene` here ([`Gpu::render`], `isolux
    /// render --gpu`): [`crate::PathKernel::Megakernel`],
    /// [`crate::PathKernel::Wavefront`] or [`crate::PathKernel::Sorted`],
    /// as [`Gpu::set_path_kernel`] and the adapter choose for the scene
    /// (the same as [`GpuFrame::path_kernel`] of its frame).
    pub fn path_kernel_for(&self, scene: &Scene) -> Result<crate::PathKernel, GpuError> {
        let (needed, random_walk) = scene_needs(scene)?;
        let (wavefront, sorted) = self.kernel_choice(random_walk, needed);
        Ok(resolved_kernel(wavefront, sorted && !needed.subsurface()))
    }

    /// [`Gpu::render`], with the AOV layers (albedo, normal, depth of the
    /// first hit, averaged over each pixel's samples as on the CPU) when
    /// `aov` is set.
    pub fn render_with_aov(
        &self,
        scene: &Scene,
        aov: bool,
        progress: &dyn Fn(usize, usize),
    ) -> Result<(Image, RenderStats), GpuError> {
        let mut frame = self.prepare_mode(scene, false, aov)?;
        let spp = scene.film.spp;
        // Up to 16 passes for the progress reports, of at least 4 samples
        // each: a pass is a dispatch of its samples and a wait for it, and
        // the image is the same however the samples are grouped
        // (`GpuFrame::set_max_layers`).
        let per_pass = spp.div_ceil(16).max(4).min(spp);
        let passes = spp.div_ceil(per_pass) as usize;
        for k in 0..passes {
            let count = per_pass.min(spp - frame.samples);
            frame.run(self, count);
            self.wait()?;
            progress(k + 1, passes);
        }
        let (mut image, stats) = frame.image(self)?;
        if aov {
            image.aov = Some(frame.aovs(self)?);
        }
        Ok((image, stats))
    }
}

impl GpuFrame {
    /// The optional code this frame's kernels carry.
    pub fn features(&self) -> Features {
        self.features
    }

    /// Runs this frame with the kernels of `features` from now on (for
    /// example [`Features::ALL`], the general kernels, to compare them
    /// with the specialized ones: `isolux bench gpu --general`). Refused
    /// when `features` lacks code the scene needs; the image is the same
    /// either way, within the drivers' floating-point contraction.
    pub fn set_features(&mut self, features: Features) -> Result<(), GpuError> {
        if !features.covers(self.needed) {
            return Err(GpuError::Setup(format!(
                "kernels with {features} cannot render this scene: it needs {}",
                // Tile lists are optional (the same hits either way).
                Features {
                    tiles: false,
                    ..self.needed
                }
            )));
        }
        self.features = features;
        Ok(())
    }

    /// Queues a pass adding `count` samples to every pixel (returns at
    /// once; [`Gpu::wait`] or [`GpuFrame::image`] waits). In the real-time
    /// mode the pass is a whole new frame of `count` samples per pixel.
    pub fn run(&mut self, gpu: &Gpu, count: u32) {
        self.run_with(gpu, count, Clock::Off);
    }

    /// [`GpuFrame::run`] with GPU timestamps at the start of the pass's
    /// first dispatch and the end of its last, where the adapter offers
    /// them; [`GpuFrame::gpu_time`] reads them.
    pub fn run_timed(&mut self, gpu: &Gpu, count: u32) {
        self.run_with(gpu, count, Clock::Frame);
    }

    /// [`GpuFrame::run`] with each dispatch in a compute pass of its own,
    /// GPU timestamps at its start and end: the frame's time kernel by
    /// kernel (and in the wavefronts, step by step), for `isolux bench gpu
    /// --kernels`. `None` (and nothing run) where the adapter offers no
    /// timestamps. The samples and the image are those of `run`; the
    /// wavefronts run one submission per run of samples here
    /// ([`GpuFrame::set_wavefront_samples`]; `run` queues all runs in
    /// one), and the sorted wavefront's scatter, shadow and
    /// shading kernels a pass each (one pass in `run`), so the time
    /// between dispatches may differ from `run`'s a little, not the
    /// dispatches' own. Waits for the queue.
    pub fn profile(&mut self, gpu: &Gpu, count: u32) -> Result<Option<Profile>, GpuError> {
        let Some(ts) = gpu.timestamps.as_ref() else {
            return Ok(None);
        };
        let per = if self.wavefront && !self.realtime && !self.first_hits {
            // A run a submission (`set_wavefront_samples`).
            self.make_wavefront(gpu);
            self.wf.as_ref().map_or(1, |wf| wf.samples)
        } else {
            count.max(1)
        };
        let mut out = Profile::default();
        let mut done = 0;
        while done < count {
            let n = per.min(count - done);
            let mut stamps = Stamps::new(gpu);
            self.run_with(gpu, n, Clock::Each(&mut stamps));
            if stamps.full {
                return Err(GpuError::Setup(format!(
                    "profile: more than {} dispatches in one submission",
                    Stamps::MAX
                )));
            }
            let ticks: Vec<u64> = gpu.read_back(&stamps.resolve)?;
            let secs = |a: u64, b: u64| b.wrapping_sub(a) as f64 * ts.period * 1e-9;
            for (i, &(kernel, step)) in stamps.kernels.iter().enumerate() {
                out.dispatches.push(DispatchTime {
                    kernel,
                    step,
                    seconds: secs(ticks[2 * i], ticks[2 * i + 1]),
                });
            }
            if let Some(last) = stamps.kernels.len().checked_sub(1) {
                out.span += secs(ticks[0], ticks[2 * last + 1]);
            }
            done += n;
        }
        Ok(Some(out))
    }

    /// The GPU's own time of the last [`GpuFrame::run_timed`] pass, in
    /// seconds (waits for the queue); `None` where the adapter offers no
    /// timestamps. Its difference to the wall time around `run_timed` and
    /// [`Gpu::wait`] is what the host, the driver and the queue cost.
    pub fn gpu_time(&self, gpu: &Gpu) -> Result<Option<f64>, GpuError> {
        let Some(ts) = gpu.timestamps.as_ref() else {
            return Ok(None);
        };
        let ticks: Vec<u64> = gpu.read_back(&ts.resolve)?;
        Ok(Some(
            ticks[1].wrapping_sub(ticks[0]) as f64 * ts.period * 1e-9,
        ))
    }

    fn run_with(&mut self, gpu: &Gpu, count: u32, mut clock: Clock) {
        if count == 0 {
            return;
        }
        if self.first_hits {
            // One dispatch per sample, adding to the AOV layers in place
            // (as `aovs` does).
            let aov = gpu.aov_pipeline(self.features);
            let aov = ("aov_main", &aov);
            self.queue_dispatches(gpu, aov, self.samples, count, 1, 1, None, &mut clock);
            self.samples += count;
            return;
        }
        if self.realtime {
            self.dispatch_samples(
                gpu,
                ("realtime", &gpu.render_pipeline(true, self.features)),
                0,
                count,
                count,
                &mut clock,
            );
            self.params.pass_info[0] = 0;
            self.params.pass_info[1] = count;
            self.samples = count;
            return;
        }
        if self.wavefront {
            self.dispatch_wavefront(gpu, count, &mut clock);
            self.samples += count;
            return;
        }
        // One thread per sample, up to `LAYERS_MAX` samples per dispatch,
        // all in one submission: a kernel looping over several samples of
        // its pixel lost many of them on long paths (the loop defect of
        // docs/gpu.md: a random-walk medium at 16 samples per dispatch
        // came out 38% dark).
        if self.mega.is_none() {
            self.mega = Some(MegaCount::new(gpu));
        }
        self.dispatch_samples(
            gpu,
            ("main", &gpu.render_pipeline(false, self.features)),
            self.samples,
            count,
            1,
            &mut clock,
        );
        self.samples += count;
    }

    /// Camera rays test their tile's list of objects (`on`) or walk the
    /// object hierarchy each: kernels with or without [`Features::tiles`]
    /// (by default with on a GPU, without on a CPU driver). The lists
    /// (`cull_tiles` in `camera.wgsl`: one walk per 8 x 8 pixel tile
    /// against the pyramid of its rays) are made either way. The hits are
    /// the same: a list holds, in the walk's order, every object a ray of
    /// the tile can reach. For comparisons (`isolux bench gpu --tiles`)
    /// and tests.
    pub fn set_tile_lists(&mut self, on: bool) {
        self.features.tiles = on;
    }

    /// The kernel this frame path traces with: the megakernel, the
    /// wavefront or the sorted wavefront ([`GpuFrame::set_wavefront`],
    /// [`GpuFrame::set_sorted`]).
    pub fn path_kernel(&self) -> crate::PathKernel {
        resolved_kernel(self.wavefront, self.sorted())
    }

    /// Whether the path tracer runs as a wavefront ([`GpuFrame::set_wavefront`]).
    pub fn wavefront(&self) -> bool {
        self.wavefront
    }

    /// Path traces with the wavefront kernel (`on`) or the megakernel.
    /// Both trace the same paths with the same random numbers, so the
    /// image is the same within the drivers' floating-point contraction;
    /// the wavefront runs each bounce as a dispatch over the paths still
    /// alive (docs/gpu.md, "The wavefront path tracer"). No effect in the
    /// real-time mode.
    pub fn set_wavefront(&mut self, on: bool) {
        self.wavefront = on;
    }

    /// Whether the wavefront shades its hits in order of their material
    /// ([`GpuFrame::set_sorted`]; never with the subsurface integrator).
    pub fn sorted(&self) -> bool {
        self.sorted && !self.features.subsurface()
    }

    /// Runs the wavefront's steps as the sorted wavefront (`on`: four
    /// dispatches a step, the hits shaded in order of their material;
    /// [`crate::PathKernel::Sorted`]) or as one dispatch a step. The same
    /// image either way. Only where the path tracer runs as a wavefront
    /// ([`GpuFrame::set_wavefront`]); a scene with the subsurface
    /// integrator keeps one dispatch a step (`on` has no effect there).
    pub fn set_sorted(&mut self, on: bool) {
        self.sorted = on;
    }

    /// Whether the sorted wavefront sorts its hits by material (`on`, the
    /// default) or keeps them in the order they were found in: the same
    /// kernels and dispatches, every hit in one bin, so that a comparison
    /// (`isolux bench gpu --sorted`) tells the sort's part from the
    /// split's (the intersection in a kernel without the material code).
    /// The same image either way.
    pub fn set_sort_by_material(&mut self, on: bool) {
        self.by_material = on;
    }

    /// The sorted wavefront runs its first `n` steps (at least one: step
    /// 0, the camera rays) sorted and the rest as the plain wavefront, one
    /// dispatch a step: the same paths, so the same image. For
    /// comparisons and tests.
    pub fn set_sorted_steps(&mut self, n: u32) {
        self.sorted_steps = n.max(1);
    }

    /// Samples of one dispatch of the path tracer or the real-time mode
    /// at most, `n` from 1 (one dispatch per sample, as before
    /// 2026-12-02) to 16 (the default). The image is the same whatever
    /// `n`: the layers are added in sample order. For comparisons
    /// (`isolux bench gpu --per-sample`) and tests.
    pub fn set_max_layers(&mut self, n: u32) {
        self.max_layers = n.clamp(1, LAYERS_MAX);
    }

    /// Sample layers per dispatch for a run of `count` samples: all of
    /// them up to [`GpuFrame::set_max_layers`], fewer where their memory
    /// would pass [`LAYER_BYTES_MAX`] or the device's largest binding; at
    /// least one.
    fn layers_per_dispatch(&self, gpu: &Gpu, count: u32) -> u32 {
        let fit = gpu.binding_limit().min(LAYER_BYTES_MAX) / self.layer_bytes().max(1);
        (fit.min(self.max_layers as u64) as u32).min(count).max(1)
    }

    /// Workgroups of 8 x 8 pixels (`TILE`) that cover the film, per axis:
    /// a dispatch of a thread per pixel, or the number of tiles.
    fn film_groups(&self) -> (u32, u32) {
        (
            self.params.film[0].div_ceil(TILE),
            self.params.film[1].div_ceil(TILE),
        )
    }

    /// Bytes of one sample layer: a `vec4<f32>` per pixel.
    fn layer_bytes(&self) -> u64 {
        self.params.film[0] as u64 * self.params.film[1] as u64 * 16
    }

    /// Makes room for `n` sample layers (a new buffer and bind group when
    /// there are fewer).
    fn grow_layers(&mut self, gpu: &Gpu, n: u32) {
        if n <= self.layer_count {
            return;
        }
        self.layers = gpu.output("sample layers", n as u64 * self.layer_bytes());
        self.layer_count = n;
        self.bind = gpu.frame_bind_group(&self.buffers, &self.layers);
    }

    /// Queues samples `first .. first + count` of `pipeline` (`main` or
    /// `realtime`) in one submission: dispatches of up to
    /// [`GpuFrame::layers_per_dispatch`] samples, a thread per pixel and
    /// sample (`pass_info = [first + s, field]` and `gid.z` the sample's
    /// layer), each followed by `resolve`, which adds its layers to the
    /// pixels' sums in sample order (replacing them on a real-time
    /// frame's first dispatch). One dispatch for many samples pays the
    /// GPU's drain between dependent dispatches (the wait for the slowest
    /// workgroup) once: on the H100 at b93c7db a frame's time had a part
    /// that did not grow with its pixels, about 27 ms in 16 path-traced
    /// dispatches and 2.3 ms in 4 real-time ones (benchmarks.md).
    fn dispatch_samples(
        &mut self,
        gpu: &Gpu,
        pipeline: (&'static str, &wgpu::ComputePipeline),
        first: u32,
        count: u32,
        field: u32,
        clock: &mut Clock,
    ) {
        let per = self.layers_per_dispatch(gpu, count);
        self.grow_layers(gpu, per);
        let resolve = gpu.resolve_pipeline();
        self.queue_dispatches(
            gpu,
            pipeline,
            first,
            count,
            field,
            per,
            Some(&resolve),
            clock,
        );
    }

    /// Queues dispatches of `pipeline` over samples `first .. first +
    /// count`, `per` samples each (`gid.z`), each followed by `resolve`
    /// when there is one, in one submission. The dispatches' parameters
    /// are copied into the parameter buffer from a staging buffer inside
    /// the command stream ([`ParamBlocks`]), so no submission waits on a
    /// `write_buffer` (on an H100 four submissions cost about 2 ms).
    /// `clock`: how the passes are timed (`pipeline`'s name is its entry
    /// point, for [`GpuFrame::profile`]).
    #[allow(clippy::too_many_arguments)]
    fn queue_dispatches(
        &self,
        gpu: &Gpu,
        (name, pipeline): (&'static str, &wgpu::ComputePipeline),
        first: u32,
        count: u32,
        field: u32,
        per: u32,
        resolve: Option<&wgpu::ComputePipeline>,
        clock: &mut Clock,
    ) {
        let chunks: Vec<(u32, u32)> = (0..count)
            .step_by(per as usize)
            .map(|s| (s, per.min(count - s)))
            .collect();
        let blocks: Vec<GpuParams> = chunks
            .iter()
            .map(|&(s, n)| {
                let mut p = self.params;
                p.pass_info[0] = first + s;
                p.pass_info[1] = field;
                p.layers = [n, u32::from(self.realtime && s == 0), 0, 0];
                p
            })
            .collect();
        let staged = ParamBlocks::new(gpu, &blocks);
        let mut enc = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("samples"),
            });
        let groups = self.film_groups();
        // `main` counts its capped paths in group 1 ([`MegaCount`], made
        // by `run_with`); the other kernels here bind group 0 only.
        let group1 = self
            .mega
            .as_ref()
            .filter(|_| crate::binds_wavefront_group(name));
        for (i, &(_, n)) in chunks.iter().enumerate() {
            let at = staged.offset(&mut enc, &self.params_buf, i);
            let (first, last) = (i == 0, i + 1 == chunks.len());
            // `resolve` in the same pass, or when profiled in its own.
            let each = clock.each();
            let writes = clock.writes(gpu, name, None, first, last);
            let mut pass = begin_pass(&mut enc, "samples", writes);
            pass.set_bind_group(0, &self.bind, &[at]);
            if let Some(mega) = group1 {
                pass.set_bind_group(1, &mega.bind, &[]);
            }
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(groups.0, groups.1, n);
            if let Some(resolve) = resolve {
                if each {
                    drop(pass);
                    let writes = clock.writes(gpu, "resolve", None, false, false);
                    pass = begin_pass(&mut enc, "resolve", writes);
                    pass.set_bind_group(0, &self.bind, &[at]);
                }
                pass.set_pipeline(resolve);
                pass.dispatch_workgroups(groups.0, groups.1, 1);
            }
        }
        clock.resolve(gpu, &mut enc);
        gpu.queue.submit(Some(enc.finish()));
    }

    /// The AOVs of the first hit over the samples taken so far (at the
    /// same sub-pixel positions), for a frame prepared with AOVs.
    pub fn aovs(&self, gpu: &Gpu) -> Result<Aovs, GpuError> {
        let buf = self
            .aov
            .as_ref()
            .ok_or_else(|| GpuError::Setup("the frame was prepared without AOVs".into()))?;
        // Cleared first (submissions on one queue run in order), then one
        // dispatch per sample (see `aov_main`), adding in place; a
        // first-hits frame's runs did that already.
        let count = self.samples.max(1);
        if !self.first_hits {
            let mut enc = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("aov clear"),
                });
            enc.clear_buffer(buf, 0, None);
            gpu.queue.submit(Some(enc.finish()));
            let aov = gpu.aov_pipeline(self.features);
            let aov = ("aov_main", &aov);
            self.queue_dispatches(gpu, aov, 0, count, 1, 1, None, &mut Clock::Off);
        }
        let raw: Vec<[f32; 4]> = gpu.read_back(buf)?;
        let inv = 1.0 / count as f32;
        let mut out = Aovs::default();
        for px in raw.chunks_exact(2) {
            out.albedo
                .push([px[0][0] * inv, px[0][1] * inv, px[0][2] * inv]);
            out.depth.push(px[0][3] * inv);
            let n = [px[1][0], px[1][1], px[1][2]];
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            out.normal
                .push(if l > 0.0 { n.map(|c| c / l) } else { [0.0; 3] });
        }
        Ok(out)
    }

    /// Moves the camera (same film size) and clears the accumulation.
    pub fn set_camera(&mut self, gpu: &Gpu, camera: &Camera) -> Result<(), GpuError> {
        let [origin, forward, right, up] = camera
            .rig(self.params.film[0], self.params.film[1])
            .map_err(GpuError::Setup)?
            .basis();
        let v4 = |v: glam::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
        self.params.origin = v4(origin - self.rebase);
        self.params.camera[0] = medium_of(&self.media, origin, self.params.camera[3]);
        self.params.forward = v4(forward);
        self.params.right = v4(right);
        self.params.up = v4(up);
        self.cull_tiles(gpu);
        self.reset(gpu);
        Ok(())
    }

    /// Queues `cull_tiles` (`camera.wgsl`): each 8 x 8 pixel tile's list of
    /// the objects its camera rays can meet, for the camera of
    /// `self.params`. Runs before any later submission's samples.
    fn cull_tiles(&self, gpu: &Gpu) {
        let staged = ParamBlocks::new(gpu, std::slice::from_ref(&self.params));
        let mut enc = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("tile lists"),
            });
        let at = staged.offset(&mut enc, &self.params_buf, 0);
        let (gx, gy) = self.film_groups();
        let tiles = gx * gy;
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("tile lists"),
                timestamp_writes: None,
            });
            pass.set_bind_group(0, &self.bind, &[at]);
            pass.set_pipeline(&gpu.cull_pipeline());
            // Rows of at most 65535 workgroups (the per-dimension limit).
            let groups = tiles.div_ceil(64);
            pass.dispatch_workgroups(groups.min(65535), groups.div_ceil(65535), 1);
        }
        gpu.queue.submit(Some(enc.finish()));
    }

    /// The accumulation buffer: per pixel, row by row from the top, the
    /// sum of the samples' RGB and the count of dropped samples
    /// (`vec4<f32>`); divide by [`GpuFrame::samples`]. Storage usage, so a
    /// display shader can read it in place.
    pub fn accumulation(&self) -> &wgpu::Buffer {
        &self.accum
    }

    /// Film width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.params.film[0], self.params.film[1])
    }

    /// Clears the accumulation (progressive rendering restarts).
    pub fn reset(&mut self, gpu: &Gpu) {
        let mut enc = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        enc.clear_buffer(&self.accum, 0, None);
        if let Some(wf) = self.wf.as_ref() {
            enc.clear_buffer(&wf.ctl, wf.ctl_init.size(), None);
        }
        if let Some(mega) = self.mega.as_ref() {
            enc.clear_buffer(&mega.ctl, 0, None);
        }
        if let (true, Some(aov)) = (self.first_hits, self.aov.as_ref()) {
            enc.clear_buffer(aov, 0, None);
        }
        gpu.queue.submit(Some(enc.finish()));
        self.samples = 0;
    }

    /// The mean of the samples so far (waits for queued passes), and its
    /// counts: the samples dropped as not finite, and the paths ended at
    /// `MAX_MEDIUM_EVENTS` (counted by either path-tracing kernel, cleared
    /// by [`GpuFrame::reset`]; the wavefront's counter goes with its
    /// buffers, which a change of its tile, samples a run or sorting
    /// rebuilds).
    pub fn image(&self, gpu: &Gpu) -> Result<(Image, RenderStats), GpuError> {
        let acc: Vec<[f32; 4]> = gpu.read_back(&self.accum)?;
        let inv = 1.0 / self.samples.max(1) as f32;
        let mut rejected = 0u64;
        let rgb = acc
            .iter()
            .map(|a| {
                rejected += a[3] as u64;
                // A sum of finite samples can still overflow f32: clamp.
                [a[0], a[1], a[2]].map(|c| (c * inv).min(f32::MAX))
            })
            .collect();
        let (width, height) = (self.params.film[0], self.params.film[1]);
        // Counted by the wavefront (`wf_end`) and by the megakernel
        // (`count_capped`) in kernels with the subsurface integrator (no
        // other raises a path's medium events: nothing is read back for
        // them); a frame that ran both (`set_wavefront` between runs) adds
        // their counts.
        let mut capped_paths = 0;
        if self.features.subsurface() {
            if let Some(wf) = self.wf.as_ref() {
                let ctl: Vec<u32> = gpu.read_back(&wf.ctl)?;
                capped_paths += ctl[ctl.len() - 4] as u64;
            }
            if let Some(mega) = self.mega.as_ref() {
                let ctl: Vec<u32> = gpu.read_back(&mega.ctl)?;
                capped_paths += ctl[0] as u64;
            }
        }
        Ok((
            Image {
                width,
                height,
                rgb,
                aov: None,
            },
            RenderStats {
                samples: width as u64 * height as u64 * self.samples as u64,
                rejected_samples: rejected,
                capped_paths,
            },
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_features_are_the_code_a_scene_needs() {
        let load = |name: &str| {
            let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/scenes/");
            isolux_scene::load(&std::path::Path::new(dir).join(name)).unwrap()
        };
        let gallery = scene_features(&load("gallery.toml")).unwrap();
        assert!(!gallery.subsurface() && !gallery.null_boundaries && !gallery.refraction);
        assert!(!gallery.manifold && gallery.tiles);
        // A lamp beside curved random-walk media: manifold lights.
        let drops = scene_features(&load("translucent-random-walk.toml")).unwrap();
        assert!(drops.subsurface() && drops.refraction && drops.manifold);
        assert!(!drops.null_boundaries);
        // A lamp above flat water: refracted lights, no manifold solve.
        let flat = scene_features(&load("shallows.toml")).unwrap();
        assert!(flat.refraction && !flat.manifold && !flat.null_boundaries);
        // Fog of index 1: null boundaries.
        assert!(scene_features(&load("fog.toml")).unwrap().null_boundaries);
    }
}
