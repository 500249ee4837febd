//! Tiled, parallel, deterministic rendering.
//!
//! ## Sampling
//! Pixel `(x, y)` takes `spp` samples on a stratified sub-pixel grid of
//! `m x n` cells, `m = ceil(sqrt(spp))`, `n = ceil(spp / m)` (a square grid
//! for 4, 9, 16, 25 samples as in the seed), one jittered sample per cell.
//! When `spp < m n` the cells used are a random subset, so each sample is
//! still uniform over the pixel and the box-filtered estimate is unbiased.
//!
//! ## Determinism
//! Each pixel owns a PCG32 stream keyed by `(seed, pixel index)` and sums
//! its samples in order inside one task, so the image is bit-identical for
//! a fixed seed whatever the number of threads or the tile schedule.
//!
//! ## Robustness
//! A sample whose radiance is not finite (which the materials' guards should
//! prevent) is dropped and counted in [`RenderStats::rejected_samples`];
//! no NaN or Inf reaches the image.

use crate::integrator::{radiance_culled, Media};
use crate::realtime::{realtime_radiance, RealtimeEnv};
use crate::Scene;
use isolux_core::{rng::mix64, Aovs, DVec3, Image, Pcg32, Rgb};
use isolux_geometry::{Beam, Culled};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Tile edge in pixels.
pub const TILE: u32 = 16;

/// Render-time options that are not part of the scene.
#[derive(Clone, Copy, Debug, Default)]
pub struct RenderOptions {
    /// Also produce albedo, normal and depth layers.
    pub aov: bool,
    /// The real-time mode ([`crate::realtime`]) instead of path tracing.
    pub realtime: bool,
}

/// Counters from a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderStats {
    /// Camera samples traced.
    pub samples: u64,
    /// Samples dropped because their value was not finite.
    pub rejected_samples: u64,
    /// Paths ended at [`crate::integrator::MAX_MEDIUM_EVENTS`] events
    /// inside random-walk media, their light beyond lost: non-zero where
    /// a medium is too thick (optically) for the walk, whose part of the
    /// image is then darker than it should be. Counted by the CPU
    /// renderer and by both of the GPU's path-tracing kernels (the
    /// wavefront and the megakernel).
    pub capped_paths: u64,
}

/// Errors that prevent rendering.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// Invalid camera, film or integrator settings.
    #[error("{0}")]
    Setup(String),
}

struct TileResult {
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    rgb: Vec<[f32; 3]>,
    aov: Option<Aovs>,
    rejected: u64,
}

/// Renders `scene`. `progress(done, total)` is called after each tile.
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(Image, RenderStats), RenderError> {
    let film = scene.film;
    if let Some(why) = film.problem() {
        return Err(RenderError::Setup(why.to_string()));
    }
    if let Some(why) = scene.integrator.problem() {
        return Err(RenderError::Setup(why));
    }
    let rig = scene
        .camera
        .rig(film.width, film.height)
        .map_err(RenderError::Setup)?;
    let tiles_x = film.width.div_ceil(TILE);
    let tiles_y = film.height.div_ceil(TILE);
    let total = (tiles_x * tiles_y) as usize;
    let done = AtomicUsize::new(0);
    let seed = mix64(scene.integrator.seed ^ 0x1502_7a1e);
    let spp = film.spp;
    let m = (spp as f64).sqrt().ceil() as u32;
    let n = spp.div_ceil(m);
    // Camera paths start in the medium around the camera, if any.
    let media = Media::new(scene, rig.basis()[0]);
    let rt_env = options
        .realtime
        .then(|| RealtimeEnv::new(&scene.environment));

    let tiles: Vec<TileResult> = (0..total)
        .into_par_iter()
        .map(|ti| {
            let x0 = (ti as u32 % tiles_x) * TILE;
            let y0 = (ti as u32 / tiles_x) * TILE;
            let w = TILE.min(film.width - x0);
            let h = TILE.min(film.height - y0);
            let mut rgb = Vec::with_capacity((w * h) as usize);
            let mut aov = options.aov.then(Aovs::default);
            let mut rejected = 0;
            let mut cells: Vec<u32> = Vec::with_capacity((m * n) as usize);
            // Coherent culling: the tile's camera rays lie in the cone of
            // its four corner rays; one list of the objects and
            // perturbations that cone meets serves all their first hits.
            let corners = [(x0, y0), (x0 + w, y0), (x0, y0 + h), (x0 + w, y0 + h)]
                .map(|(x, y)| rig.ray(x as f64, y as f64).dir);
            let mut culled = Culled::default();
            let primary = Beam::cone(rig.basis()[0], &corners).map(|beam| {
                scene.geometry.cull(&beam, &mut culled);
                &culled
            });
            for y in y0..y0 + h {
                for x in x0..x0 + w {
                    let pixel = y as u64 * film.width as u64 + x as u64;
                    let mut rng = Pcg32::new(seed, pixel);
                    cells.clear();
                    cells.extend(0..m * n);
                    let mut sum = Rgb::BLACK;
                    let (mut alb, mut nor, mut dep) = (Rgb::BLACK, DVec3::ZERO, 0.0);
                    for s in 0..spp {
                        // Partial Fisher-Yates: a random subset of cells.
                        let j = s + rng.next_below(m * n - s);
                        cells.swap(s as usize, j as usize);
                        let c = cells[s as usize];
                        let [jx, jy] = rng.next_2d();
                        let fx = x as f64 + ((c % m) as f64 + jx) / m as f64;
                        let fy = y as f64 + ((c / m) as f64 + jy) / n as f64;
                        let ray = rig.ray(fx, fy);
                        let (l, first) = match &rt_env {
                            Some(env) => realtime_radiance(scene, env, ray, primary, spp, &mut rng),
                            None => radiance_culled(scene, ray, primary, &media, &mut rng),
                        };
                        if l.is_finite() && l.r >= 0.0 && l.g >= 0.0 && l.b >= 0.0 {
                            sum += l;
                        } else {
                            rejected += 1;
                        }
                        if let Some(fh) = first {
                            alb += fh.albedo;
                            nor += fh.normal;
                            dep += fh.depth;
                        }
                    }
                    let inv = 1.0 / spp as f64;
                    // Finite f64 beyond f32 range would become Inf: clamp.
                    let v = (sum * inv).map(|c| c.min(f32::MAX as f64));
                    rgb.push([v.r as f32, v.g as f32, v.b as f32]);
                    if let Some(a) = aov.as_mut() {
                        let al = alb * inv;
                        a.albedo.push([al.r as f32, al.g as f32, al.b as f32]);
                        let nv = nor.normalize_or_zero();
                        a.normal.push([nv.x as f32, nv.y as f32, nv.z as f32]);
                        a.depth.push((dep * inv) as f32);
                    }
                }
            }
            let k = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(k, total);
            TileResult {
                x0,
                y0,
                w,
                h,
                rgb,
                aov,
                rejected,
            }
        })
        .collect();

    let npix = (film.width * film.height) as usize;
    let mut image = Image {
        width: film.width,
        height: film.height,
        rgb: vec![[0.0; 3]; npix],
        aov: options.aov.then(|| Aovs {
            albedo: vec![[0.0; 3]; npix],
            normal: vec![[0.0; 3]; npix],
            depth: vec![0.0; npix],
        }),
    };
    let mut stats = RenderStats {
        samples: npix as u64 * spp as u64,
        rejected_samples: 0,
        capped_paths: media.capped.load(Ordering::Relaxed),
    };
    for t in tiles {
        stats.rejected_samples += t.rejected;
        for j in 0..t.h {
            for i in 0..t.w {
                let src = (j * t.w + i) as usize;
                let dst = ((t.y0 + j) * film.width + t.x0 + i) as usize;
                image.rgb[dst] = t.rgb[src];
                if let (Some(out), Some(a)) = (image.aov.as_mut(), t.aov.as_ref()) {
                    out.albedo[dst] = a.albedo[src];
                    out.normal[dst] = a.normal[src];
                    out.depth[dst] = a.depth[src];
                }
            }
        }
    }
    Ok((image, stats))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::IntegratorSettings;

    /// A library caller is held to the bounds a scene file is: a film or a
    /// depth past them is refused before anything is allocated or traced.
    #[test]
    fn render_refuses_settings_past_their_bounds() {
        let mut scene = Scene::default();
        scene.film.width = 4;
        scene.film.height = 3;
        scene.film.spp = 1;
        scene.integrator.max_depth = IntegratorSettings::MAX_DEPTH;
        assert!(render(&scene, &RenderOptions::default(), &|_, _| {}).is_ok());
        scene.integrator.max_depth = IntegratorSettings::MAX_DEPTH + 1;
        let err = render(&scene, &RenderOptions::default(), &|_, _| {}).unwrap_err();
        assert!(err.to_string().contains("max_depth 1000001"), "{err}");
        scene.integrator.max_depth = 8;
        scene.film.spp = 0;
        assert!(render(&scene, &RenderOptions::default(), &|_, _| {}).is_err());
    }
}
