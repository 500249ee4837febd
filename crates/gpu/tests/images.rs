//! Whole images: the GPU path tracer against physics and against the CPU.
//!
//! - **White furnaces** (closed forms): a white diffuse object, however
//!   perturbed, and a glass object (lossless dielectric) under uniform
//!   radiance 1 render 1 in every pixel, within 2e-3. The glass furnace
//!   runs with `max_depth = 100000`: light trapped by total internal
//!   reflection in the bump circulates for thousands of bounces, and a
//!   depth limit truncates it (the CPU loses 12 of 196,608 paths at the
//!   scene's 256, 1 at 4096, none at 100,000; physics, not a defect).
//!   **Known driver defect**: Mesa 22.3's lavapipe, the driver `.ci/run`
//!   installs, miscompiles long loops, and a few paths of many bounces
//!   end with nothing (docs/gpu.md); Mesa 25.0.7 runs the same SPIR-V
//!   exactly. On Mesa 22 the test asserts instead that losses come in
//!   whole paths only (every pixel a multiple of 1/spp, so nothing but
//!   that defect), at most 1% of the pixels, the mean within 0.5%.
//! - **The gallery** (`examples/scenes/gallery.toml`, its environment map,
//!   point light, every object and all 16 materials, each on the GPU):
//!   GPU and CPU agree within noise. The noise
//!   is measured, not guessed: two CPU renders with different seeds give
//!   the typical difference of 8 x 8 blocks between independent renders,
//!   and the GPU's difference to the CPU must not exceed 1.5 times it
//!   (mean over blocks), nor the whole-image means differ by more than 2%.
//!
//! Skipped without an adapter, except under CI (as the other GPU tests).

mod common;

use isolux_core::Image;
use isolux_gpu::Gpu;
use isolux_materials::Material;
use isolux_render::{render, MediumLightSampling, RenderOptions, Scene};
use std::path::Path;

fn gpu_image(gpu: &Gpu, scene: &Scene) -> Image {
    let (img, stats) = gpu.render(scene, &|_, _| {}).unwrap();
    assert_eq!(stats.rejected_samples, 0);
    assert!(img.rgb.iter().flatten().all(|c| c.is_finite() && *c >= 0.0));
    img
}

fn cpu_image(scene: &Scene) -> Image {
    render(scene, &RenderOptions::default(), &|_, _| {})
        .unwrap()
        .0
}

/// The path tracer's image of `scene` on the GPU against the CPU's
/// ([`common::compare_with_cpu`]).
fn compare(gpu: &Gpu, scene: &mut Scene, label: &str) -> (f64, f64, f64, f64) {
    common::compare_with_cpu(scene, |s| gpu_image(gpu, s), cpu_image, label)
}

/// [`compare`] with the usual verdict ([`common::assert_within_noise`]).
fn assert_matches_cpu(gpu: &Gpu, scene: &mut Scene, name: &str, floor: f64) {
    common::assert_within_noise(compare(gpu, scene, name), name, floor);
}

/// The mean of all channels of all pixels.
fn image_mean(img: &Image) -> f64 {
    img.rgb.iter().flatten().map(|&c| c as f64).sum::<f64>() / (3 * img.rgb.len()) as f64
}

/// Mean and standard error of the mean of per-seed image means.
fn stats(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// Renders `scene` with seeds `first_seed..first_seed + seeds` on both back
/// ends and asserts that the means of their image means agree within three
/// standard errors of the difference (from the renders' spread) or
/// `floor` of the CPU's mean.
fn means_agree_over_seeds(
    gpu: &Gpu,
    scene: &mut Scene,
    first_seed: u64,
    seeds: u64,
    floor: f64,
    label: &str,
) {
    let (mut g, mut c) = (Vec::new(), Vec::new());
    for seed in 0..seeds {
        scene.integrator.seed = first_seed + seed;
        g.push(image_mean(&gpu_image(gpu, scene)));
        c.push(image_mean(&cpu_image(scene)));
    }
    let ((mg, sg), (mc, sc)) = (stats(&g), stats(&c));
    eprintln!("{label}: means over {seeds} seeds GPU {mg:.5} +- {sg:.5}, CPU {mc:.5} +- {sc:.5}");
    assert!(mc > 0.0);
    let tol = (3.0 * (sg * sg + sc * sc).sqrt()).max(floor * mc);
    assert!(
        (mg - mc).abs() <= tol,
        "{label}: {mg} vs {mc} (tolerance {tol})"
    );
}

/// `(worst |pixel - 1|, fraction of pixels within 2e-3, mean, max)`.
fn furnace_stats(img: &Image, what: &str) -> (f32, f64, f64, f32) {
    let v: Vec<f32> = img.rgb.iter().flatten().copied().collect();
    let worst = v.iter().map(|c| (c - 1.0).abs()).fold(0.0f32, f32::max);
    let good = v.iter().filter(|c| (*c - 1.0).abs() < 2e-3).count() as f64 / v.len() as f64;
    let mean = v.iter().map(|&c| c as f64).sum::<f64>() / v.len() as f64;
    let max = v.iter().copied().fold(0.0f32, f32::max);
    eprintln!(
        "{what}: worst |pixel - 1| {worst:.2e}, {:.2}% within 2e-3, mean {mean:.5}, max {max}",
        100.0 * good
    );
    (worst, good, mean, max)
}

/// The furnace's perturbed object in glass (index 1.5) with `max_depth`:
/// everything entering leaves, if the depth limit lets it.
fn glass_furnace(max_depth: u32) -> Scene {
    let mut scene = common::example("furnace.toml");
    scene.materials[0] = Material::Dielectric(isolux_materials::Dielectric { ior: 1.5 });
    scene.integrator.max_depth = max_depth;
    scene
}

fn furnace_images(gpu: &Gpu) -> Vec<(&'static str, Image, u32)> {
    let mut diffuse = common::example("furnace.toml");
    let mut glass = glass_furnace(100_000);
    for (scene, spp) in [(&mut diffuse, 4), (&mut glass, 8)] {
        scene.film.width = 64;
        scene.film.height = 48;
        scene.film.spp = spp;
    }
    vec![
        ("diffuse furnace", gpu_image(gpu, &diffuse), 4),
        ("glass furnace", gpu_image(gpu, &glass), 8),
    ]
}

/// Mesa 22.3's lavapipe miscompiles long loops (docs/gpu.md): the one
/// driver known to lose whole paths.
fn loses_whole_paths(gpu: &Gpu) -> bool {
    gpu.miscompiles_loops()
}

#[test]
fn white_furnaces_render_one() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    eprintln!("driver: {}", gpu.driver);
    for (what, img, spp) in furnace_images(&gpu) {
        let (worst, good, mean, max) = furnace_stats(&img, what);
        if !loses_whole_paths(&gpu) {
            assert!(worst < 2e-3, "{what}: {worst}");
            continue;
        }
        assert!((mean - 1.0).abs() < 0.005, "{what}: mean {mean}");
        assert!(good >= 0.99, "{what}: {good}");
        assert!(max < 1.0 + 2e-3, "{what}: {max}");
        // A path lost whole takes 1/spp; a path cut short by a wrong
        // intersection inside glass would take a fraction (it escapes
        // with the radiance scale 1/eta^2 of the inside).
        for c in img.rgb.iter().flatten() {
            let lost = (1.0 - c) * spp as f32;
            assert!((lost - lost.round()).abs() < 0.02, "{what}: pixel {c}");
        }
    }
}

/// Subsurface scattering (`examples/scenes/translucent*.toml`): the
/// dipole BSSRDF with single scattering under point lights and a dim sky,
/// and the volumetric random walk under an environment map and (in
/// `underwater.toml`) around the camera, GPU against CPU within noise (as
/// the gallery). A translucent object's light comes
/// from elsewhere on its surface (probe rays, reservoir choice of the
/// hit) or from hundreds of scattering events, all of it on the GPU.
#[test]
fn translucent_scenes_match_the_cpu_within_noise() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    for (name, spp) in [
        ("translucent.toml", 16),
        // (32: at 16 its heavy tails made one pair of CPU images a poor
        // measure of the noise.)
        ("translucent-random-walk.toml", 32),
        // The camera inside the medium.
        ("underwater.toml", 16),
        // The camera in fog, a lamp outside it (a null boundary).
        ("fog.toml", 16),
        // The sun above flat water, refracted into it.
        ("shallows.toml", 16),
        // A lamp behind curved media, refracted into them (manifold
        // next-event estimation).
        ("lamplit-milk.toml", 16),
    ] {
        let mut scene = common::example(name);
        assert!(isolux_gpu::unsupported_material(&scene).is_none());
        scene.film.width = 128;
        scene.film.height = 72;
        scene.film.spp = spp;
        assert_matches_cpu(&gpu, &mut scene, name, 0.0);
    }
}

/// Wave optics (`examples/scenes/wave-*.toml`): a silver grating's
/// diffraction orders under a point light, and brushed aluminium on a
/// perturbed sphere under a light and a sky (spherical mapping, coherence
/// areas narrowed to the pixel footprint on camera rays), GPU against CPU
/// within noise. Both render the spectral hero combs of their own random
/// offsets, so the colour noise is part of the measured noise.
///
/// The image means are compared over several seeds, not one: the brushed
/// metal's light comes in rare bright glints, so at 8 samples per pixel
/// one image's mean moves by about 7% from seed to seed (measured on the
/// CPU: 0.109 to 0.126). The means of `SEEDS` renders on each side must
/// agree within three standard errors of their difference, estimated
/// from the same renders' spread, or within 1%.
///
/// `#[ignore]`d in CI: four seeds of two wave scenes on both back ends
/// take about 4 minutes on lavapipe (231 s on 2 cores, 2026-12-02, of
/// which the kernels' compile is now about 12 s; before the material
/// library's call sites were merged it was minutes, docs/gpu.md); run
/// with `--ignored`.
#[test]
#[ignore = "renders four seeds of two wave scenes on both back ends: about 4 minutes on lavapipe"]
fn wave_scenes_match_the_cpu_within_noise() {
    const SEEDS: u64 = 4;
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    for (name, w, h, spp) in [
        ("wave-grating.toml", 96, 72, 16),
        ("wave-brushed.toml", 96, 72, 8),
    ] {
        let mut scene = common::example(name);
        assert!(isolux_gpu::unsupported_material(&scene).is_none());
        scene.film.width = w;
        scene.film.height = h;
        scene.film.spp = spp;
        let (diff, noise, _, _) = compare(&gpu, &mut scene.clone(), name);
        assert!(diff <= 1.5 * noise, "{name}: {diff} vs noise {noise}");
        means_agree_over_seeds(&gpu, &mut scene, 100, SEEDS, 0.01, name);
    }
}

/// A non-absorbing random-walk medium behind a glass boundary, a sphere
/// under a white sky: every photon that enters leaves again, so each
/// channel's expected radiance is exactly 1 (closed form; spectral MIS
/// spreads a path over its channels, which adds noise only). With absorption every
/// channel loses energy, most where it absorbs most. The same check as the
/// CPU's (`crates/isolux/tests/analytic.rs`), on the GPU.
#[test]
fn random_walk_medium_conserves_energy_on_the_gpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let src = r#"
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov_y = 30.0
[film]
width = 96
height = 64
spp = 32
[integrator]
max_depth = 16
[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]
[[material]]
name = "medium"
type = "subsurface"
sigma_s = [2.0, 1.0, 0.5]
sigma_a = [0.0, 0.0, 0.0]
g = 0.3
scale = 1.0
mode = "random_walk"
[[object]]
material = "medium"
base = { type = "sphere", center = [0.3, -0.2, 0.0], radius = 0.8 }
"#;
    // Per-channel mean and standard error over the sphere's pixels (those
    // that differ from the white background).
    let stats = |img: &Image| {
        let px: Vec<&[f32; 3]> = img
            .rgb
            .iter()
            .filter(|p| p.iter().any(|v| (v - 1.0).abs() > 1e-6))
            .collect();
        let n = px.len() as f64;
        assert!(n > 500.0, "too few sphere pixels: {n}");
        let mut out = [(0.0, 0.0); 3];
        for (c, o) in out.iter_mut().enumerate() {
            let m = px.iter().map(|p| p[c] as f64).sum::<f64>() / n;
            let v = px.iter().map(|p| (p[c] as f64 - m).powi(2)).sum::<f64>() / n;
            *o = (m, (v / n).sqrt());
        }
        out
    };
    let scene = common::parse(src, "furnace.toml");
    let s = stats(&gpu_image(&gpu, &scene));
    eprintln!("non-absorbing, GPU: {s:?}");
    for (c, (m, se)) in s.iter().enumerate() {
        assert!(
            (m - 1.0).abs() < 4.0 * se + 2e-3,
            "channel {c}: {m} +- {se}"
        );
    }
    let src = src.replace("sigma_a = [0.0, 0.0, 0.0]", "sigma_a = [0.05, 0.5, 2.0]");
    let scene = common::parse(&src, "furnace.toml");
    let s = stats(&gpu_image(&gpu, &scene));
    eprintln!("absorbing, GPU: {s:?}");
    for (c, (m, se)) in s.iter().enumerate() {
        assert!(*m < 1.0 - 4.0 * se, "channel {c}: {m}");
    }
    assert!(s[0].0 > s[1].0 && s[1].0 > s[2].0, "{s:?}");
}

/// A non-absorbing dipole medium with its single-scattering term, under a
/// white sky, optically thick (16 reduced mean free paths in radius).
/// Jensen's published sum `S^(1) + S_d` rendered 1.054 on the CPU; the
/// single-scattering term is now scaled per channel to keep energy
/// (`Subsurface::single_scattering_scale`, carried to the GPU after the
/// dipoles; 0 without absorption). The GPU must render it within energy,
/// and as the CPU does (measured on the CPU: 0.918).
#[test]
fn dipole_medium_with_single_scattering_keeps_energy_on_the_gpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let src = r#"
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov_y = 30.0
[film]
width = 64
height = 48
spp = 16
[integrator]
max_depth = 32
[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]
[[material]]
name = "medium"
type = "subsurface"
sigma_s_reduced = [20.0, 20.0, 20.0]
sigma_a = [0.0, 0.0, 0.0]
mode = "dipole"
[[object]]
material = "medium"
base = { type = "sphere", center = [0.0, 0.0, 0.0], radius = 0.8 }
"#;
    let scene = common::parse(src, "dipole.toml");
    // The mean over the sphere's pixels (those that differ from the white
    // background) and its standard error.
    let stats = |img: &Image| {
        let px: Vec<f64> = img
            .rgb
            .iter()
            .filter(|p| p.iter().any(|v| (v - 1.0).abs() > 1e-6))
            .map(|p| p.iter().map(|&v| v as f64).sum::<f64>() / 3.0)
            .collect();
        let n = px.len() as f64;
        assert!(n > 300.0, "too few sphere pixels: {n}");
        let m = px.iter().sum::<f64>() / n;
        let v = px.iter().map(|p| (p - m).powi(2)).sum::<f64>() / n;
        (m, (v / n).sqrt())
    };
    let (g, gse) = stats(&gpu_image(&gpu, &scene));
    let (c, cse) = stats(&cpu_image(&scene));
    eprintln!("dipole + single scattering, no absorption: GPU {g} +- {gse}, CPU {c} +- {cse}");
    assert!(g > 0.85 && g < 1.0 + 4.0 * gse + 1e-3, "GPU {g} +- {gse}");
    let se = (gse * gse + cse * cse).sqrt();
    assert!(
        (g - c).abs() < 4.0 * se + 5e-3,
        "GPU {g} against CPU {c} +- {se}"
    );
}

/// A point light inside a medium (the CPU's closed-form checks in
/// `crates/isolux/tests/analytic.rs`): through an absorbing medium onto a
/// diffuse floor (shadow rays attenuated), and scattered once or more in
/// a scattering medium around the camera (next-event estimation at the
/// scattering events), and onto a dipole floor (its exit and entry
/// points). GPU against CPU within noise, at 128 spp: scattering events
/// near the lamp make rare bright samples (`I / r^2`), and since grey
/// media carry every channel, Russian roulette ends more of the paths
/// (their throughput is no longer the one channel's 3x), so 32 spp left
/// CPU renders of two seeds 4% apart (measured over 16 seeds at 32 spp:
/// CPU 0.1924 +- 0.0008; GPU 0.1951 without one seed's firefly at 0.249,
/// 0.1985 with it; before the change, over 6 seeds, CPU 0.1925 and GPU
/// 0.1952).
#[test]
fn lamps_in_media_match_the_cpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    // examples/tests/lamp-in-medium.toml with the coefficients, with or
    // without its floor.
    let lamp = |sigma_s: f64, sigma_a: f64, floor: bool| {
        let mut src = common::test_scene_text("lamp-in-medium.toml")
            .replace(
                "sigma_s = [0.3, 0.3, 0.3]",
                &format!("sigma_s = [{sigma_s}, {sigma_s}, {sigma_s}]"),
            )
            .replace(
                "sigma_a = [0.2, 0.2, 0.2]",
                &format!("sigma_a = [{sigma_a}, {sigma_a}, {sigma_a}]"),
            );
        if !floor {
            src.truncate(src.find("\n# floor\n").unwrap());
        }
        src
    };
    // The floor a dipole medium (the CPU's check against clear water:
    // `a_dipole_floor_under_water_sees_the_lamp_through_the_water`).
    let dipole = lamp(0.0, 0.6, true).replace(
        "type = \"diffuse\"\nreflectance = [0.8, 0.8, 0.8]",
        "type = \"subsurface\"\nsigma_s = [200.0, 200.0, 200.0]\n\
         sigma_a = [20.0, 20.0, 20.0]\ng = 0.0\nior = 1.3\nscale = 1.0",
    );
    assert!(dipole.contains("sigma_s = [200.0"));
    for (name, src) in [
        ("absorbing, floor", lamp(0.0, 0.6, true)),
        ("scattering", lamp(0.3, 0.2, false)),
        ("scattering, floor", lamp(0.3, 0.2, true)),
        ("absorbing, dipole floor", dipole),
    ] {
        let mut scene = common::parse(&src, "lamp.toml");
        (scene.film.width, scene.film.height, scene.film.spp) = (96, 64, 128);
        scene.integrator.max_depth = 4;
        assert_matches_cpu(&gpu, &mut scene, name, 0.01);
    }
}

/// Equiangular sampling of a lamp's light in a medium on the GPU (the
/// CPU's check against single scattering:
/// `equiangular_sampling_quiets_a_lamps_glow`): the lamp of
/// `lamp-in-medium.toml`, turned into view, in a thin fog of albedo 0.02.
/// The GPU's image agrees with the CPU's within noise, and its noise (the
/// RMS difference of two seeds' images) is at least 2 times smaller than
/// with `medium_light_sampling = "distance"`, whose mean agrees too.
#[test]
fn equiangular_sampling_quiets_lamps_on_the_gpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let src = common::test_scene_text("lamp-in-medium.toml")
        .replace("sigma_s = [0.3, 0.3, 0.3]", "sigma_s = [0.02, 0.02, 0.02]")
        .replace("sigma_a = [0.2, 0.2, 0.2]", "sigma_a = [0.98, 0.98, 0.98]")
        .replace("look_at = [0.0, -0.6, 0.0]", "look_at = [0.6, 0.8, -0.4]");
    let mut src = src.replace("max_depth = 1", "max_depth = 4");
    src.truncate(src.find("\n# floor\n").unwrap());
    let mut scene = common::parse(&src, "lamp.toml");
    (scene.film.width, scene.film.height, scene.film.spp) = (48, 36, 32);
    let (diff, noise, _, _) = compare(&gpu, &mut scene, "lamp in view");
    assert!(diff <= 1.5 * noise, "{diff} vs noise {noise}");
    // The pixels whose rays pass within 0.05 of the lamp are left out of
    // the means and the noise: the glow's `1 / D` there makes the image
    // mean of either strategy wander by a few percent between seeds.
    let light = scene.lights[0].position;
    let rig = scene
        .camera
        .rig(scene.film.width, scene.film.height)
        .unwrap();
    let keep: Vec<usize> = (0..scene.film.height)
        .flat_map(|y| (0..scene.film.width).map(move |x| (x, y)))
        .enumerate()
        .filter(|&(_, (x, y))| {
            let ray = rig.ray(x as f64 + 0.5, y as f64 + 0.5);
            let to = light - ray.origin;
            (to - to.dot(ray.dir) * ray.dir).length() > 0.05
        })
        .map(|(i, _)| i)
        .collect();
    assert!(keep.len() < 48 * 36 && keep.len() > 48 * 36 - 10);
    let kept_mean = |img: &Image| {
        keep.iter()
            .map(|&i| img.rgb[i].iter().map(|&c| c as f64).sum::<f64>())
            .sum::<f64>()
            / (3 * keep.len()) as f64
    };
    let mc = kept_mean(&cpu_image(&scene));
    let mut rms = Vec::new();
    for strategy in [
        MediumLightSampling::Equiangular,
        MediumLightSampling::Distance,
    ] {
        scene.integrator.medium_lights = strategy;
        let mut imgs = Vec::new();
        for seed in [11, 12] {
            scene.integrator.seed = seed;
            imgs.push(gpu_image(&gpu, &scene));
        }
        let d2: f64 = keep
            .iter()
            .flat_map(|&i| (0..3).map(move |c| (i, c)))
            .map(|(i, c)| (imgs[0].rgb[i][c] as f64 - imgs[1].rgb[i][c] as f64).powi(2))
            .sum();
        let r = (d2 / (2.0 * 3.0 * keep.len() as f64)).sqrt();
        let m = (kept_mean(&imgs[0]) + kept_mean(&imgs[1])) / 2.0;
        eprintln!("{strategy:?}: GPU mean {m} (CPU {mc}), noise per pixel {r}");
        assert!((m - mc).abs() <= 0.03 * mc, "{strategy:?}: {m} vs {mc}");
        rms.push(r);
    }
    assert!(rms[0] * 2.0 < rms[1], "noise {rms:?}");
}

/// A lamp above water lights the floor and the water under the flat
/// surface by refraction (`examples/tests/sun-above-water.toml`; the
/// CPU's closed forms in `crates/isolux/tests/analytic.rs`): GPU against
/// CPU within noise, the floor's mean against the closed form's
/// (0.041059), the lit water's, and the floor under a pool whose plane
/// has `bounds`.
#[test]
fn lamps_above_water_match_the_cpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let floor = common::test_scene_text("sun-above-water.toml");
    let scene = common::parse(&floor, "sun.toml");
    let m = image_mean(&gpu_image(&gpu, &scene));
    eprintln!("floor under water: GPU {m}");
    assert!((m - 0.041059).abs() < 0.02 * 0.041059, "{m}");
    let mut water = floor
        .replace("sigma_s = [0.0, 0.0, 0.0]", "sigma_s = [0.1, 0.1, 0.1]")
        .replace("sigma_a = [0.3, 0.3, 0.3]", "sigma_a = [0.2, 0.2, 0.2]")
        .replace("max_depth = 1", "max_depth = 4");
    water.truncate(water.find("\n# floor\n").unwrap());
    let pool = floor.replace(
        "normal = [0.0, 1.0, 0.0] }\n\n# floor",
        "normal = [0.0, 1.0, 0.0] }\nbounds = { min = [-1.0, -10.0, -1.0], max = [1.0, 1.0, 2.0] }\n\n# floor",
    );
    assert_ne!(pool, floor);
    for (name, src) in [
        (
            "floor under water",
            floor.replace("max_depth = 1", "max_depth = 4"),
        ),
        ("water under a lamp", water),
        // A pool: the water's plane cut by a box that holds the camera
        // but not every crossing point toward the floor in view (those
        // beyond it are dark; without the GPU's test of the box they were
        // lit, and this comparison failed).
        ("floor under a pool with bounds", pool),
    ] {
        let mut scene = common::parse(&src, "sun.toml");
        assert_matches_cpu(&gpu, &mut scene, name, 0.001);
    }
}

/// A lamp above a drop of water lights the floor inside it through the
/// curved surface, by manifold next-event estimation
/// (`examples/tests/lamp-above-drop.toml`; the CPU's closed form in
/// `crates/isolux/tests/analytic.rs`, 0.22456): the GPU's mean against
/// it, and GPU against CPU within noise for the floor, for scattering
/// water under the lamp (no floor), and for two drops of one material
/// (the GPU finds the one the path is in among the material's objects).
/// With `refracted_lights = "flat"` the floor is black on both.
#[test]
fn lamps_above_drops_match_the_cpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let floor = common::test_scene_text("lamp-above-drop.toml");
    let scene = common::parse(&floor, "drop.toml");
    let m = image_mean(&gpu_image(&gpu, &scene));
    eprintln!("floor in a drop: GPU {m}");
    assert!((m - 0.22456).abs() < 0.02 * 0.22456, "{m}");
    let mut water = floor
        .replace("sigma_s = [0.0, 0.0, 0.0]", "sigma_s = [0.3, 0.4, 0.5]")
        .replace("max_depth = 1", "max_depth = 4");
    water.truncate(water.find("\n[[material]]\nname = \"floor\"").unwrap());
    // The other drop listed first: the material's first object is not
    // the one the paths are in.
    let drop = "[[object]]\nmaterial = \"water\"\n";
    assert!(floor.contains(drop));
    let twin = floor.replace("max_depth = 1", "max_depth = 4").replacen(
        drop,
        &format!(
            "{drop}base = {{ type = \"sphere\", center = [6.0, 0.0, 0.0], radius = 1.0 }}\n\n{drop}"
        ),
        1,
    );
    for (name, src) in [
        (
            "floor in a drop",
            floor.replace("max_depth = 1", "max_depth = 4"),
        ),
        ("scattering drop under a lamp", water),
        ("two drops of one material", twin),
    ] {
        let mut scene = common::parse(&src, "drop.toml");
        assert_matches_cpu(&gpu, &mut scene, name, 0.001);
    }
    let flat = floor.replace(
        "[integrator]\n",
        "[integrator]\nrefracted_lights = \"flat\"\n",
    );
    let scene = common::parse(&flat, "drop.toml");
    assert_eq!(image_mean(&gpu_image(&gpu, &scene)), 0.0);
}

/// Lamps above flat water whose medium the light's record cannot name
/// (`refracted_media`; no adapter needed): the water's material on a
/// second object (the GPU's media are materials), a lamp above two flat
/// media. With `refracted_lights = "manifold"` (the default) they go by
/// the medium's list of objects, as curved media do, the kernels finding
/// the plane there (`flat_water_shared_by_a_drop_matches_the_cpu`); with
/// `"flat"` they are refused by name. The plain scene passes, with the lamp refracted
/// into the water, object 0, and so does a plane with `bounds` (refused
/// until 2026-12-04).
#[test]
fn flat_media_the_lights_records_cannot_name_go_by_the_media_lists() {
    let src = common::test_scene_text("sun-above-water.toml");
    let parse = |s: &str| common::parse(s, "sun.toml");
    let flat = |s: &str| {
        s.replace(
            "[integrator]\n",
            "[integrator]\nrefracted_lights = \"flat\"\n",
        )
    };
    let ok = isolux_gpu::refracted_media(&parse(&src)).unwrap();
    assert_eq!(
        ok.iter().map(|r| r.map(|(i, _)| i)).collect::<Vec<_>>(),
        [Some(0)]
    );
    assert!(!isolux_gpu::scene_features(&parse(&src)).unwrap().manifold);
    let water = "[[object]]\nmaterial = \"water\"\nbase = { type = \"plane\", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }\n";
    assert!(src.contains(water));
    let drop = "[[object]]\nmaterial = \"water\"\nbase = { type = \"sphere\", center = [5.0, -5.0, 0.0], radius = 1.0 }\n";
    let shared = src.replace(water, &format!("{water}\n{drop}"));
    assert_eq!(
        isolux_gpu::refracted_media(&parse(&shared)).unwrap(),
        [None]
    );
    assert!(
        isolux_gpu::scene_features(&parse(&shared))
            .unwrap()
            .manifold
    );
    let shared_why = isolux_gpu::refracted_media(&parse(&flat(&shared))).unwrap_err();
    assert!(
        shared_why.contains("object[1] has the same material")
            && shared_why.contains("refracted_lights = \"manifold\""),
        "{shared_why}"
    );
    // A plane with bounds is followed (`lamps_above_water_match_the_cpu`).
    let bounded = src.replace(
        water,
        &format!("{water}bounds = {{ min = [-5.0, -10.0, -5.0], max = [5.0, 1.0, 5.0] }}\n"),
    );
    let ok = isolux_gpu::refracted_media(&parse(&bounded)).unwrap();
    assert_eq!(ok[0].map(|(i, _)| i), Some(0));
    let pool = "[[material]]\nname = \"pool\"\ntype = \"subsurface\"\nsigma_s = [0.0, 0.0, 0.0]\nsigma_a = [0.1, 0.1, 0.1]\nior = 1.2\nmode = \"random_walk\"\n\n[[object]]\nmaterial = \"pool\"\nbase = { type = \"plane\", point = [0.0, -20.0, 0.0], normal = [0.0, 1.0, 0.0] }\n";
    let two = format!("{src}\n{pool}");
    assert_eq!(isolux_gpu::refracted_media(&parse(&two)).unwrap(), [None]);
    assert!(isolux_gpu::scene_features(&parse(&two)).unwrap().manifold);
    let two_why = isolux_gpu::refracted_media(&parse(&flat(&two))).unwrap_err();
    assert!(two_why.contains("two random-walk media"), "{two_why}");
    // Each message one line of single spaces (no source indentation).
    for why in [&shared_why, &two_why] {
        assert!(!why.contains("  ") && !why.contains('\n'), "{why:?}");
    }
}

/// Flat water whose material a drop shares (the light's record cannot
/// name the water, `flat_media_the_lights_records_cannot_name_go_by_the_media_lists`):
/// the lamp reaches the floor under it by the plane's closed form, the
/// kernels finding the plane among the material's objects: the GPU's
/// mean against the closed form (`lamps_above_water_match_the_cpu`,
/// 0.041059), and GPU against CPU within noise, also for a pool (the
/// plane with `bounds`, whose box cuts off crossing points beyond it, and
/// beyond which paths in the water still find its plane: 0.02418 against
/// the CPU's 0.02878 when they did not).
#[test]
fn flat_water_shared_by_a_drop_matches_the_cpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let floor = common::test_scene_text("sun-above-water.toml");
    let water = "[[object]]\nmaterial = \"water\"\nbase = { type = \"plane\", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }\n";
    let drop = "[[object]]\nmaterial = \"water\"\nbase = { type = \"sphere\", center = [4.0, 1.0, 3.0], radius = 0.4 }\n";
    let shared = floor.replace(water, &format!("{water}\n{drop}"));
    assert_ne!(shared, floor);
    let scene = common::parse(&shared, "sun.toml");
    assert!(isolux_gpu::scene_features(&scene).unwrap().manifold);
    let m = image_mean(&gpu_image(&gpu, &scene));
    eprintln!("floor under shared water: GPU {m}");
    assert!((m - 0.041059).abs() < 0.02 * 0.041059, "{m}");
    let pool = shared.replace(
        "normal = [0.0, 1.0, 0.0] }\n\n[[object]]\nmaterial = \"water\"",
        "normal = [0.0, 1.0, 0.0] }\nbounds = { min = [-1.0, -10.0, -1.0], max = [1.0, 1.0, 2.0] }\n\n[[object]]\nmaterial = \"water\"",
    );
    assert_ne!(pool, shared);
    for (name, src) in [
        (
            "floor under shared water",
            shared.replace("max_depth = 1", "max_depth = 4"),
        ),
        ("floor under a shared pool with bounds", pool),
    ] {
        let mut scene = common::parse(&src, "sun.toml");
        assert_matches_cpu(&gpu, &mut scene, name, 0.001);
    }
}

/// Surfaces under water meet water (the CPU's closed-form check in
/// `crates/isolux/tests/analytic.rs`): the camera in a half-space of water
/// sees a black plastic wall (`examples/tests/plastic-under-water.toml`),
/// a rough gold sphere, a glass sphere, a mix of a rough plastic and gold
/// and a dipole marble, all
/// with their indices relative to the water's (each its own record,
/// reached through the medium's table). GPU against CPU within noise,
/// the wall alone against the closed form's mean (0.00626; against
/// vacuum, 0.0694).
#[test]
fn surfaces_under_water_match_the_cpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let wall = common::test_scene_text("plastic-under-water.toml");
    let mut scene = common::parse(&wall, "wall.toml");
    let m = image_mean(&gpu_image(&gpu, &scene));
    eprintln!("plastic wall under water: GPU {m}");
    assert!((m - 0.00626).abs() < 0.0004, "{m}");
    let src = format!(
        "{wall}{}",
        r#"
[[material]]
name = "gold"
type = "ggx"
roughness = 0.2
metal = "Au"

[[material]]
name = "glass"
type = "dielectric"
ior = 1.5

[[material]]
name = "satin"
type = "plastic"
ior = 1.5
roughness = 0.3
reflectance = [0.2, 0.4, 0.6]

[[material]]
name = "both"
type = "mix"
components = [{ material = "satin", weight = 0.5 }, { material = "gold", weight = 0.5 }]

[[object]]
material = "gold"
base = { type = "sphere", center = [-2.2, 0.2, 0.1], radius = 0.2 }

[[object]]
material = "glass"
base = { type = "sphere", center = [-2.2, -0.2, -0.1], radius = 0.2 }

[[material]]
name = "marble"
type = "subsurface"
sigma_s = [60.0, 70.0, 80.0]
sigma_a = [0.5, 1.0, 3.0]
ior = 1.7
scale = 1.0

[[object]]
material = "both"
base = { type = "sphere", center = [-2.5, 0.0, 0.25], radius = 0.15 }

[[object]]
material = "marble"
base = { type = "sphere", center = [-2.4, -0.3, 0.3], radius = 0.15 }
"#
    );
    scene = common::parse(&src, "under-water.toml");
    (scene.film.width, scene.film.height, scene.film.spp) = (48, 32, 64);
    let (diff, noise, mg, mc) = compare(&gpu, &mut scene, "surfaces under water");
    assert!(diff <= 1.5 * noise, "{diff} vs noise {noise}");
    assert!((mg - mc).abs() <= 0.03 * mc, "{mg} vs {mc}");
}

/// A lamp outside fog of index 1 (`examples/tests/fog-lamp-outside.toml`;
/// the CPU's closed forms in `crates/isolux/tests/analytic.rs`): its
/// shadow rays pass the fog's boundary, which bends no ray, attenuated
/// inside it, onto the floor and at the fog's scattering events. GPU
/// against CPU within noise, and the floor's mean against the closed
/// form's (0.19617).
#[test]
fn lamps_through_fog_match_the_cpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let floor = common::test_scene_text("fog-lamp-outside.toml");
    let scene = common::parse(&floor, "fog.toml");
    let m = image_mean(&gpu_image(&gpu, &scene));
    eprintln!("floor through fog: GPU {m}");
    assert!((m - 0.19617).abs() < 0.002, "{m}");
    let mut glow = floor
        .replace("sigma_s = [0.0, 0.0, 0.0]", "sigma_s = [0.3, 0.3, 0.3]")
        .replace("sigma_a = [0.8, 0.8, 0.8]", "sigma_a = [0.2, 0.2, 0.2]")
        .replace("max_depth = 1", "max_depth = 8");
    glow.truncate(glow.find("\n# floor\n").unwrap());
    for (name, src) in [
        (
            "fog with its floor",
            floor.replace("max_depth = 1", "max_depth = 4"),
        ),
        ("glowing fog", glow),
    ] {
        let mut scene = common::parse(&src, "fog.toml");
        assert_matches_cpu(&gpu, &mut scene, name, 0.001);
    }
}

/// A sphere of two `wave` leaves (the GPU places one per hit, chosen by
/// weight: docs/gpu.md, "Inside a `mix`") renders the CPU's image in
/// expectation: per channel, the mean difference over the sphere's
/// pixels lies within four standard errors (measured on Mesa 25's
/// lavapipe at 64 x 48, 64 spp: within one). Mesa 22.3's lavapipe, CI's,
/// miscompiles such a mix and refuses it by name, which is checked there
/// instead.
#[test]
fn a_mix_of_two_waves_renders_the_cpus_image() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/tests/two-waves.toml");
    let scene = isolux_scene::load(&path).unwrap();
    if gpu.miscompiles_loops() {
        let Err(e) = gpu.render(&scene, &|_, _| {}) else {
            panic!("a mix of two waves rendered on {}", gpu.driver);
        };
        assert!(
            e.to_string()
                .contains("material \"blend\" mixes 2 `wave` materials"),
            "{e}"
        );
        return;
    }
    let (g, c) = (gpu_image(&gpu, &scene), cpu_image(&scene));
    // The sphere's pixels: those the sky (1) does not fill on the CPU.
    let px: Vec<usize> = (0..c.rgb.len())
        .filter(|&i| c.rgb[i].iter().any(|v| (v - 1.0).abs() > 1e-6))
        .collect();
    let n = px.len() as f64;
    assert!(n > 500.0, "{n} sphere pixels");
    for ch in 0..3 {
        let d: Vec<f64> = px
            .iter()
            .map(|&i| (g.rgb[i][ch] - c.rgb[i][ch]) as f64)
            .collect();
        let m = d.iter().sum::<f64>() / n;
        let se = (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n / n).sqrt();
        eprintln!("channel {ch}: GPU - CPU {m:.4} +- {se:.4}");
        assert!(
            m.abs() < 4.0 * se + 1e-3,
            "channel {ch}: GPU - CPU {m} +- {se}"
        );
    }
}

/// A camera inside a non-absorbing random-walk medium of index `n` under
/// a white sky sees the radiance of equilibrium there, `n^2` (closed form;
/// the CPU's check in `crates/isolux/tests/analytic.rs`): each path brings
/// exactly `3 n^2` in the channel it carries, so every pixel's channels
/// sum to `3 n^2` to rounding, in the wavefront and the megakernel alike.
/// A frame prepared with the camera outside and then moved inside
/// (`GpuFrame::set_camera`, the viewer's orbit) starts its paths in the
/// medium too; moved out again, it sees the sky around the sphere.
#[test]
fn a_camera_inside_a_random_walk_medium_sees_it_on_the_gpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let src = common::test_scene_text("medium-around-camera.toml");
    let mut scene = common::parse(&src, "inside.toml");
    // Prepared with the camera outside, then moved in.
    let inside = scene.camera.position;
    scene.camera.position.z = 3.0;
    let check = |img: &Image, what: &str| {
        for p in &img.rgb {
            let sum = p.iter().map(|&v| v as f64).sum::<f64>();
            assert!((sum - 6.75).abs() < 1e-4, "{what}: {p:?}");
        }
        let n = img.rgb.len() as f64;
        for c in 0..3 {
            let m = img.rgb.iter().map(|p| p[c] as f64).sum::<f64>() / n;
            let v = img
                .rgb
                .iter()
                .map(|p| (p[c] as f64 - m).powi(2))
                .sum::<f64>()
                / n;
            let se = (v / n).sqrt();
            eprintln!("{what}, channel {c}: {m} +- {se}");
            assert!(
                (m - 2.25).abs() < 4.0 * se + 1e-3,
                "{what}, channel {c}: {m} +- {se}"
            );
        }
    };
    let mut frame = gpu.prepare(&scene).unwrap();
    scene.camera.position = inside;
    frame.set_camera(&gpu, &scene.camera).unwrap();
    for wavefront in [true, false] {
        frame.set_wavefront(wavefront);
        frame.reset(&gpu);
        frame.run(&gpu, 16);
        let (img, stats) = frame.image(&gpu).unwrap();
        assert_eq!(stats.rejected_samples, 0);
        check(&img, if wavefront { "wavefront" } else { "megakernel" });
    }
    check(&gpu_image(&gpu, &scene), "render");
    // Out again: the sky (1) shows around the sphere.
    scene.camera.position.z = 3.0;
    frame.set_camera(&gpu, &scene.camera).unwrap();
    frame.run(&gpu, 4);
    let (img, _) = frame.image(&gpu).unwrap();
    let sky = img
        .rgb
        .iter()
        .filter(|p| p.iter().all(|&v| v == 1.0))
        .count();
    assert!(
        sky > img.rgb.len() / 4,
        "{sky} sky pixels of {}",
        img.rgb.len()
    );
}

/// Media nest on the GPU as on the CPU (`media_nest` in
/// `crates/isolux/tests/analytic.rs`): the camera inside a sphere of
/// index 1.5 inside a sphere of scattering water (1.33) under a white sky
/// sees `1.5^2`, every path bringing exactly `3 n^2` in its channel, in
/// the wavefront and the megakernel; in the water, `1.33^2`; inside a grey
/// medium, which carries every channel, `1.5^2` in each. A jelly in
/// the water seen from it renders the CPU's image within noise. A third
/// medium overlapping both is refused by name.
#[test]
fn media_nest_on_the_gpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let src = common::test_scene_text("medium-around-camera.toml");
    let nested = common::test_scene_text("nested-media.toml");
    // Every path of every pixel brings 3 n^2 over its channels, in both
    // path tracers, with the camera at `camera` in `text` (moved from
    // `at`).
    let closed_form = |text: &str, at: &str, camera: &str, n: f64| {
        let text = text.replacen(at, camera, 1);
        let scene = common::parse(&text, "media.toml");
        let mut frame = gpu.prepare(&scene).unwrap();
        for wavefront in [true, false] {
            frame.set_wavefront(wavefront);
            frame.reset(&gpu);
            frame.run(&gpu, 8);
            let (img, stats) = frame.image(&gpu).unwrap();
            assert_eq!(stats.rejected_samples, 0);
            let want = 3.0 * n * n;
            for p in &img.rgb {
                let sum = p.iter().map(|&v| v as f64).sum::<f64>();
                assert!(
                    (sum - want).abs() < 1e-4 * want,
                    "camera at {camera}, wavefront {wavefront}: {p:?}"
                );
            }
        }
    };
    for (camera, n) in [("[0.1, -0.2, 0.3]", 1.5), ("[0.1, -0.2, 2.0]", 1.33)] {
        closed_form(&nested, "[0.1, -0.2, 0.3]", camera, n);
    }
    // A grey medium carries every channel: each is 1.5^2 exactly.
    let grey = src.replace("sigma_s = [2.0, 1.0, 0.5]", "sigma_s = [1.0, 1.0, 1.0]");
    let scene = common::parse(&grey, "grey.toml");
    for p in &gpu_image(&gpu, &scene).rgb {
        for &v in p {
            assert!((v as f64 - 2.25).abs() < 1e-4, "grey medium: {p:?}");
        }
    }
    // A jelly in clear water, seen from the water, with a lamp and a
    // floor (examples/tests/lamp-in-medium.toml, the water of index 1.33).
    let jelly = common::test_scene_text("lamp-in-medium.toml")
        .replace("sigma_s = [0.3, 0.3, 0.3]", "sigma_s = [0.0, 0.0, 0.0]")
        .replace("sigma_a = [0.2, 0.2, 0.2]", "sigma_a = [0.02, 0.02, 0.02]")
        .replace("ior = 1.0", "ior = 1.33")
        + r#"
[[material]]
name = "jelly"
type = "subsurface"
sigma_s = [3.0, 4.0, 5.0]
sigma_a = [0.5, 0.3, 0.2]
g = 0.3
ior = 1.9
scale = 1.0
mode = "random_walk"

[[object]]
material = "jelly"
base = { type = "sphere", center = [0.0, -0.5, 0.0], radius = 0.45 }
"#;
    let mut scene = common::parse(&jelly, "jelly.toml");
    // 128 spp: at 64 a block lit through the jelly by one rare path
    // put |GPU - CPU| at 1.57 times the CPU's own seed-to-seed difference
    // for one seed, where five others gave 0.80-1.14 (the GPU's mean
    // within 0.1% of the CPU's at 1024 spp, the same noise per render).
    (scene.film.width, scene.film.height, scene.film.spp) = (48, 36, 128);
    scene.integrator.max_depth = 8;
    let (diff, noise, mg, mc) = compare(&gpu, &mut scene, "jelly under water");
    assert!(diff <= 1.5 * noise, "{diff} vs noise {noise}");
    assert!((mg - mc).abs() <= 0.03 * mc, "{mg} vs {mc}");
    // Four and eight deep (`media_nest_four_and_eight_deep` in
    // crates/isolux/tests/analytic.rs): 4-bit slots hold them, the camera
    // sees its medium's index squared.
    let deep = common::test_scene_text("deep-media.toml");
    let deeper = deep.clone() + &common::test_scene_text("deeper-media.toml");
    for (text, camera, n) in [
        (&deep, "[0.5, 0.0, 0.3]", 1.9),
        (&deep, "[0.1, 0.0, 0.3]", 1.7),
        (&deeper, "[0.5, 0.0, 0.3]", 1.1),
        (&deeper, "[0.5, 0.0, 0.25]", 1.2),
    ] {
        closed_form(text, "[0.5, 0.0, 0.3]", camera, n);
    }
    // The GPU lists the media's materials first (`media_first`): behind
    // eleven other materials the slots are still 4 bits wide, and five
    // deep render, the camera in the fifth seeing its index squared (until
    // 2026-12-05, refused: 8-bit slots).
    let behind = |n: usize, text: &str| {
        let padding: String = (0..n)
            .map(|k| format!("[[material]]\nname = \"pad{k}\"\ntype = \"diffuse\"\n"))
            .collect();
        text.replacen("[[material]]", &format!("{padding}[[material]]"), 1)
    };
    let fifth = behind(11, &deep) + &deeper_medium("fifth", 1.6, 0.14);
    let scene = common::parse(&fifth, "fifth.toml");
    assert_eq!(isolux_gpu::medium_bits(&scene), 4);
    closed_form(&fifth, "[0.5, 0.0, 0.3]", "[0.5, 0.0, 0.3]", 1.6);
    // Media of 15 materials: the slots are 8 bits wide, four deep still
    // render, five are refused. (The other media: grey spheres of index 1
    // that scatter and do not absorb, side by side far above, each of its
    // own material; under the white sky a path through one keeps its
    // radiance.)
    let pad = |n: usize, text: &str| {
        let padding: String = (0..n)
            .map(|k| {
                format!(
                    "[[material]]\nname = \"pad{k}\"\ntype = \"subsurface\"\n\
                     mode = \"random_walk\"\nior = 1.0\nsigma_s = [1.0, 1.0, 1.0]\n\
                     sigma_a = [0.0, 0.0, 0.0]\n[[object]]\nmaterial = \"pad{k}\"\n\
                     base = {{ type = \"sphere\", center = [{}, 50.0, 0.0], radius = 0.1 }}\n",
                    0.3 * k as f64
                )
            })
            .collect();
        format!("{text}\n{padding}")
    };
    let padded = pad(11, &deep);
    closed_form(&padded, "[0.5, 0.0, 0.3]", "[0.5, 0.0, 0.3]", 1.9);
    let scene = common::parse(&padded, "padded.toml");
    assert_eq!(isolux_gpu::medium_bits(&scene), 8);
    let fifth = padded.clone() + &deeper_medium("fifth", 1.6, 0.14);
    let scene = common::parse(&fifth, "fifth.toml");
    let Err(e) = gpu.prepare(&scene) else {
        panic!("five nested media accepted in 8-bit slots")
    };
    assert!(
        e.to_string()
            .contains("nested 4 deep (the scene's random-walk media take 16 materials; eight"),
        "{e}"
    );
    // Media of 256 materials: the slots are 16 bits wide, two deep still
    // render, three are refused.
    let late = pad(254, &nested);
    let scene = common::parse(&late, "late.toml");
    assert_eq!(isolux_gpu::medium_bits(&scene), 16);
    for p in &gpu_image(&gpu, &scene).rgb {
        let sum = p.iter().map(|&v| v as f64).sum::<f64>();
        assert!((sum - 6.75).abs() < 1e-4 * 6.75, "16-bit slots: {p:?}");
    }
    let third = format!(
        "{late}{}",
        r#"
[[object]]
material = "water"
base = { type = "sphere", center = [0.3, 0.0, 0.0], radius = 0.5 }
"#
    );
    let scene = common::parse(&third, "third.toml");
    let Err(e) = gpu.prepare(&scene) else {
        panic!("three nested media accepted in 16-bit slots")
    };
    assert!(e.to_string().contains("nested 2 deep"), "{e}");
    // Overlapping media (the sphere of index 1.7 moved half out of the
    // one of 1.5): no closed form (the renderer's convention, the
    // innermost by box volume wins, does not make the index a function of
    // position), but a path leaves media from below the top of its packed
    // list; the GPU's image agrees with the CPU's within noise.
    let overlapping = deep.replace("center = [0.3, 0.0, 0.2]", "center = [0.6, 0.0, 0.0]");
    let mut scene = common::parse(&overlapping, "overlapping.toml");
    (scene.film.width, scene.film.height, scene.film.spp) = (48, 32, 64);
    let (diff, noise, mg, mc) = compare(&gpu, &mut scene, "overlapping media");
    assert!(diff <= 1.5 * noise, "{diff} vs noise {noise}");
    assert!((mg - mc).abs() <= 0.02 * mc, "{mg} vs {mc}");
    // Nine deep: refused.
    let ninth = deeper.clone() + &deeper_medium("ninth", 1.3, 0.01);
    let scene = common::parse(&ninth, "ninth.toml");
    let Err(e) = gpu.prepare(&scene) else {
        panic!("nine nested media accepted")
    };
    assert!(e.to_string().contains("nested 8 deep: render"), "{e}");
}

/// A random-walk sphere named `name` of index `ior` and radius `r` about
/// the camera of deep-media.toml, as TOML to append to a scene.
fn deeper_medium(name: &str, ior: f64, r: f64) -> String {
    format!(
        "[[material]]\nname = \"{name}\"\ntype = \"subsurface\"\nsigma_s = [1.0, 1.0, 1.0]\n\
         sigma_a = [0.0, 0.0, 0.0]\nior = {ior}\nmode = \"random_walk\"\n\
         [[object]]\nmaterial = \"{name}\"\n\
         base = {{ type = \"sphere\", center = [0.5, 0.0, 0.3], radius = {r} }}\n"
    )
}

/// The random walk at many samples (`--ignored`: minutes on Mesa 22.3's
/// lavapipe, CI's driver, whose loop miscompile loses some of these long
/// paths, docs/gpu.md): the image means of `SEEDS` renders on each side
/// agree within three standard errors of their difference (from the
/// renders' spread) or 0.5%, and one render's blocks differ from the
/// CPU's by at most twice the CPU's own render-to-render difference (the
/// GPU's per-seed image means spread 5x wider when it carried one colour
/// channel per path and the CPU all three). Measured on Mesa 25.0.7's lavapipe after the root-isolation
/// fix (docs/gpu.md): GPU 0.43031 +- 0.00079 against CPU 0.42965 +-
/// 0.00015 over six seeds, 6 s per GPU render; before it, on Mesa 22,
/// -1.9%, and -38% when a dispatch looped over 16 samples. On Mesa
/// 22.3 (CI's) at 5f794cd it passes with both path tracers: over four
/// seeds GPU 0.42956 +- 0.00084 (megakernel) and 0.42951 +- 0.00081
/// (wavefront) against CPU 0.43036 +- 0.00045; 352 s and 232 s in all.
#[test]
#[ignore = "about 6 minutes on lavapipe (2 cores): five renders at 256 spp on each back end"]
fn translucent_random_walk_converges_to_the_cpu() {
    const SEEDS: u64 = 4;
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut scene = common::example("translucent-random-walk.toml");
    scene.film.width = 64;
    scene.film.height = 40;
    scene.film.spp = 256;
    let (diff, noise, _, _) = compare(&gpu, &mut scene.clone(), "random walk, 256 spp");
    assert!(diff <= 2.0 * noise, "{diff} vs noise {noise}");
    means_agree_over_seeds(&gpu, &mut scene, 200, SEEDS, 0.005, "random walk");
}

/// The two example scenes that no other test renders on both back ends:
/// `metals.toml` (measured silver, rough and anisotropic GGX, Beckmann;
/// perturbed bases under the sky map and a lamp) and `quadrics.toml`
/// (every base quadric of the scene format, each perturbed, among them
/// the unbounded ones within `bounds`): GPU against CPU within noise, as
/// the gallery. The differential fuzzing (`scripts/gpu-diff-fuzz.py`)
/// renders them changed; this renders them as shipped.
#[test]
fn metals_and_quadrics_match_the_cpu_within_noise() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    for name in ["metals.toml", "quadrics.toml"] {
        let mut scene = common::example(name);
        assert!(isolux_gpu::unsupported_material(&scene).is_none());
        scene.film.width = 128;
        scene.film.height = 72;
        scene.film.spp = 16;
        assert_matches_cpu(&gpu, &mut scene, name, 0.01);
    }
}

#[test]
fn gallery_matches_the_cpu_within_noise() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut scene = common::example("gallery.toml");
    // Every material of the gallery runs on the GPU: none may be replaced.
    let replaced = isolux_gpu::replace_unsupported(&mut scene);
    assert!(replaced.is_empty(), "not on the GPU: {replaced:?}");
    scene.film.width = 160;
    scene.film.height = 96;
    scene.film.spp = 16;
    let (diff, noise, mg, mc) = compare(&gpu, &mut scene, "gallery");
    assert!(diff <= 1.5 * noise, "{diff} vs noise {noise}");
    assert!((mg - mc).abs() <= 0.02 * mc, "{mg} vs {mc}");
}

/// Each frame runs the kernels specialized to its scene's features
/// (`isolux_gpu::Features`): the material models it uses (diffuse alone
/// for the furnace), with the subsurface integrator for the translucent
/// scenes and the `wave` code for the wave scenes; a frame refuses
/// kernels that lack any model its scene needs and accepts the general
/// ones. (The images of each variant are checked against the CPU by the
/// tests above; this one compiles nothing.)
#[test]
fn frames_choose_the_kernels_their_scenes_need() {
    use isolux_gpu::layout::tag;
    use isolux_gpu::Features;
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    for (name, models, wave, subsurface) in [
        ("gallery.toml", 13, false, false),
        ("furnace.toml", 1, false, false),
        ("translucent.toml", 4, false, true),
        ("translucent-random-walk.toml", 4, false, true),
        ("wave-grating.toml", 1, true, false),
    ] {
        let scene = common::example(name);
        for mut frame in [
            gpu.prepare(&scene).unwrap(),
            gpu.prepare_realtime(&scene).unwrap(),
        ] {
            let needed = frame.features();
            assert_eq!(needed.models.count_ones(), models, "{name}: {needed}");
            assert_eq!(
                (needed.wave(), needed.subsurface()),
                (wave, subsurface),
                "{name}"
            );
            assert_eq!(
                needed.has(tag::SSS_ENTRY_LOBE) && needed.has(tag::SSS_SINGLE_LOBE),
                subsurface,
                "{name}"
            );
            assert!(needed.has(tag::DIFFUSE) || wave, "{name}: {needed}");
            // No example's object has more than 32 perturbations.
            assert!(!needed.list, "{name}: {needed}");
            for (_, t) in tag::ALL.iter().filter(|(_, t)| needed.has(*t)) {
                let lacking = Features {
                    models: needed.models & !(1 << t),
                    ..needed
                };
                let e = frame.set_features(lacking).unwrap_err().to_string();
                // (Tile lists, optional, go unnamed among the needs.)
                let named = Features {
                    tiles: false,
                    ..needed
                };
                assert!(e.ends_with(&format!("it needs {named}")), "{name}: {e}");
            }
            frame.set_features(Features::ALL).unwrap();
            assert_eq!(frame.features(), Features::ALL);
            frame.set_features(needed).unwrap();
        }
    }
}

/// `PathKernel::Auto` (the default) path traces every scene as a
/// wavefront on GPUs (since 2026-12-04: 0.62x the megakernel's time on
/// the gallery on an NVIDIA H200), sorted unless the scene needs the
/// subsurface integrator, and on CPU drivers only scenes with a
/// random-walk medium or a `wave` material, unsorted; `Megakernel`,
/// `Wavefront` and `Sorted` hold whatever the scene (`Sorted` but for the
/// subsurface integrator). (Compiles nothing; all give the same image,
/// `wavefront_traces_the_megakernels_paths`,
/// `sorted_wavefront_traces_the_wavefronts_paths`.)
#[test]
fn path_kernel_follows_the_scene_unless_chosen() {
    use isolux_gpu::PathKernel;
    let Some(mut gpu) = common::open("GPU image tests") else {
        return;
    };
    assert_eq!(gpu.path_kernel(), PathKernel::Auto);
    // The wavefront by default on GPUs whatever the scene; on CPU drivers
    // for long paths (a random-walk medium) and `wave` materials
    // (`paths_meeting_wave_surfaces_twice_go_on`).
    for (name, long, subsurface) in [
        ("gallery.toml", false, false),
        ("translucent.toml", false, true),
        ("translucent-random-walk.toml", true, true),
        ("wave-brushed.toml", true, false),
        ("wave-grating.toml", true, false),
    ] {
        let scene = common::example(name);
        let gpu_sorts = !gpu.is_cpu() && !subsurface;
        for (kernel, wavefront, sorted) in [
            (PathKernel::Auto, long || !gpu.is_cpu(), gpu_sorts),
            (PathKernel::Megakernel, false, false),
            (PathKernel::Wavefront, true, false),
            (PathKernel::Sorted, true, !subsurface),
        ] {
            gpu.set_path_kernel(kernel);
            let frame = gpu.prepare(&scene).unwrap();
            assert_eq!(frame.wavefront(), wavefront, "{name} {kernel:?}");
            assert_eq!(frame.sorted(), sorted, "{name} {kernel:?}");
            // What `render --gpu` reports: the frame's kernel.
            let ran = frame.path_kernel();
            assert_eq!(
                gpu.path_kernel_for(&scene).unwrap(),
                ran,
                "{name} {kernel:?}"
            );
            assert_ne!(ran, PathKernel::Auto);
        }
        gpu.set_path_kernel(PathKernel::Auto);
    }
}

/// The wavefront path tracer (`GpuFrame::set_wavefront`) traces the
/// megakernel's paths with the same random numbers, one dispatch per
/// bounce: the two images agree pixel for pixel, up to the drivers'
/// floating-point contraction (the kernels are compiled apart) and the
/// rare path that rounding sends another way. Checked on the gallery
/// (every material of the library, paths to the depth limit), on the
/// dipole and random-walk media (a path's medium, channel, events and
/// dipole entry point cross the steps in `WfPath`), and on the glass
/// furnace, whose paths of thousands of bounces end in the last step,
/// on the caustics example (a light's caustic gathered after its shadow
/// ray, in the same step), and at a film size that is not a multiple of
/// the 8 x 8 blocks (the padded pixels of the last block row and column
/// trace nothing).
#[test]
fn wavefront_traces_the_megakernels_paths() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    for (name, mut scene) in [
        ("gallery", common::example("gallery.toml")),
        ("translucent", common::example("translucent.toml")),
        (
            "random walk",
            common::example("translucent-random-walk.toml"),
        ),
        ("glass furnace", glass_furnace(100_000)),
        ("caustics", common::example("caustics.toml")),
    ] {
        scene.film.width = 61;
        scene.film.height = 35;
        scene.film.spp = 4;
        if loses_whole_paths(&gpu) {
            // Mesa 22.3 miscompiles the manifold solve's loops inside the
            // megakernel's (its mean 1% low, where the wavefront's and the
            // CPU's agree; on Mesa 25.0.7 both kernels give the same image
            // bit for bit): compare the paths without it there.
            scene.integrator.refracted_lights = isolux_render::RefractedLights::Flat;
        }
        let run = |wavefront: bool| {
            let mut frame = gpu.prepare(&scene).unwrap();
            frame.set_wavefront(wavefront);
            frame.set_sorted(false);
            assert_eq!(frame.wavefront(), wavefront);
            frame.run(&gpu, 3);
            frame.run(&gpu, 1);
            if let Some(steps) = frame.wavefront_steps(&gpu).unwrap() {
                eprintln!("{name}: paths per step {steps:?}");
            }
            let (img, stats) = frame.image(&gpu).unwrap();
            assert_eq!(stats.rejected_samples, 0, "{name}");
            // No walk here comes near the cap of its medium events, which
            // both kernels count (`paths_ended_at_the_cap_...`).
            assert_eq!(stats.capped_paths, 0, "{name}");
            img
        };
        let (mega, wave) = (run(false), run(true));
        same_paths(name, ("megakernel", &mega), ("wavefront", &wave));
    }
}

/// The sorted wavefront (`PathKernel::Sorted`: each step's hits found in
/// one kernel, shaded in order of their material in another) traces the
/// wavefront's paths with the same random numbers: the same image up to
/// the drivers' floating-point contraction. Checked on the gallery (13
/// models), the caustics example (a light's caustic through glass), a
/// `wave` material (placed at the hit with a random comb offset, drawn in
/// the shading kernel), the glass furnace (paths that outlive the sorted
/// steps end in the last, unsorted one) and a scene of 70 materials,
/// whose records beyond the sort's 63rd share its last bin; and on the
/// gallery, the same split without the sort (`set_sort_by_material`: one
/// bin), and the sorted wavefront for its first two steps, then the plain
/// one (`set_sorted_steps`: nothing listed from step 2 on). A scene with
/// the subsurface integrator keeps the plain wavefront.
#[test]
fn sorted_wavefront_traces_the_wavefronts_paths() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut many = common::example("gallery.toml");
    let first = many.materials.len();
    for i in first..70 {
        many.materials.push(many.materials[i % first].clone());
        many.material_names.push(format!("copy {i}"));
    }
    for (i, m) in many.object_material.iter_mut().enumerate() {
        *m = (*m + first * (i % 5)) % 70;
    }
    for (name, mut scene) in [
        ("gallery", common::example("gallery.toml")),
        ("caustics", common::example("caustics.toml")),
        ("wave", common::example("wave-brushed.toml")),
        ("glass furnace", glass_furnace(100_000)),
        ("70 materials", many),
    ] {
        scene.film.width = 61;
        scene.film.height = 35;
        scene.film.spp = 4;
        let mut sorted_bins = Vec::new();
        let mut run = |sorted: bool, by_material: bool, steps: u32| {
            let mut frame = gpu.prepare(&scene).unwrap();
            frame.set_wavefront(true);
            frame.set_sorted(sorted);
            frame.set_sort_by_material(by_material);
            frame.set_sorted_steps(steps);
            assert_eq!(frame.sorted(), sorted);
            frame.run(&gpu, 3);
            frame.run(&gpu, 1);
            if let Some(sort) = frame.sorted_steps(&gpu).unwrap() {
                let used = |c: &Vec<u32>| c.iter().filter(|&&n| n > 0).count();
                eprintln!(
                    "{name}: paths listed per step {:?}, bins used {:?}, the last list's length {}",
                    sort.lengths,
                    sort.counts.iter().map(used).collect::<Vec<_>>(),
                    sort.last.len()
                );
                for (k, (n, c)) in sort.lengths.iter().zip(&sort.counts).enumerate() {
                    assert_eq!(*n, c.iter().sum::<u32>(), "{name}");
                    // The paths' stamps: as many listed at step k.
                    let stamped = sort.listed.iter().filter(|&&l| l as usize > k).count();
                    assert_eq!(*n as usize, stamped, "{name}: step {k}");
                }
                assert!(sort.lengths[0] > 0, "{name}");
                if steps < sort.lengths.len() as u32 {
                    assert!(sort.lengths[1] > 0, "{name}");
                    let late = &sort.lengths[steps as usize..];
                    assert!(late.iter().all(|&n| n == 0), "{name}: {:?}", sort.lengths);
                    assert!(sort.listed.iter().all(|&l| l <= steps), "{name}");
                }
                assert!(!sort.last.is_empty() && sort.last.is_sorted(), "{name}");
                sorted_bins.push(used(&sort.counts[0]));
            }
            let (img, stats) = frame.image(&gpu).unwrap();
            assert_eq!(stats.rejected_samples, 0, "{name}");
            img
        };
        let (wave, sorted) = (run(false, true, u32::MAX), run(true, true, u32::MAX));
        same_paths(name, ("wavefront", &wave), ("sorted", &sorted));
        if name == "gallery" {
            let unsorted = run(true, false, u32::MAX);
            same_paths(name, ("wavefront", &wave), ("unsorted", &unsorted));
            // The sorted bins' count below is the first run's.
            let two = run(true, true, 2);
            same_paths(name, ("wavefront", &wave), ("sorted to step 1", &two));
        }
        // Camera rays meet the scene's materials (12 of the gallery's 16
        // at least), one per bin; without the sort, every hit in one.
        let least = scene.materials.len().min(12);
        assert!(sorted_bins[0] >= least, "{name}: {sorted_bins:?}");
        if name == "gallery" {
            assert_eq!(sorted_bins[1], 1);
        }
    }
    let mut frame = gpu.prepare(&common::example("translucent.toml")).unwrap();
    frame.set_sorted(true);
    assert!(!frame.sorted(), "the subsurface integrator is not sorted");
}

/// A film in several wavefront tiles (`GpuFrame::set_wavefront_tile`:
/// 640 paths a tile, so 61 x 35, 2,560 padded pixels, in four) traces the
/// same paths as in one tile, with the plain and the sorted wavefront:
/// each tile clears its counters (the sorted lists' too), starts its own
/// pixels and ends its paths before the next. So do several samples in
/// one tile (`set_wavefront_samples`: three samples in runs of 3, 2 + 1
/// and 1 + 1 + 1), each sample's paths ending in its layer and the layers
/// added in sample order: the same image bit for bit.
#[test]
fn wavefront_tiles_trace_the_films_paths() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut scene = common::example("gallery.toml");
    scene.film.width = 61;
    scene.film.height = 35;
    scene.film.spp = 3;
    for sorted in [false, true] {
        let run = |tile: Option<u64>, samples: u32| {
            let mut frame = gpu.prepare(&scene).unwrap();
            frame.set_wavefront(true);
            frame.set_sorted(sorted);
            frame.set_wavefront_samples(samples);
            if let Some(tile) = tile {
                frame.set_wavefront_tile(tile);
            }
            frame.run(&gpu, 3);
            // The last run's step 0: its samples' padded pixels.
            let steps = frame.wavefront_steps(&gpu).unwrap().unwrap();
            let last = match (tile, samples) {
                (Some(t), _) => t as u32,
                (None, 2) => 2560,
                (None, n) => n.min(3) * 2560,
            };
            assert_eq!(steps[0], last, "{tile:?} {samples}");
            frame.image(&gpu).unwrap().0
        };
        let name = if sorted { "sorted" } else { "wavefront" };
        let one = run(None, 1);
        for (label, tile, samples) in [
            ("four tiles", Some(640), 16),
            ("three samples a run", None, 16),
            ("two samples a run", None, 2),
        ] {
            let other = run(tile, samples);
            same_paths(name, ("one tile, one sample a run", &one), (label, &other));
            assert_eq!(one.rgb, other.rgb, "{name}: {label}");
        }
    }
}

/// Each dispatch of a submission binds its own block of the frame's
/// parameter buffer, which holds `PARAM_BLOCKS` blocks; a submission of
/// more dispatches copies the next blocks in after the dispatches that
/// read the last ones. A run of more dispatches than that (the megakernel
/// one sample a dispatch, the wavefront one sample a run, each step a
/// dispatch) gives the image of a run of a few dispatches bit for bit. A
/// block read at the wrong offset (the wrong sample, step or layer
/// count), or a copy that lands before the last reads, fails it.
#[test]
fn dispatches_past_the_parameter_blocks_read_their_own() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut scene = common::example("gallery.toml");
    scene.film.width = 8;
    scene.film.height = 8;
    let blocks = isolux_gpu::PARAM_BLOCKS as u32;
    for wavefront in [false, true] {
        let steps = if wavefront {
            let mut frame = gpu.prepare(&scene).unwrap();
            frame.set_wavefront(true);
            frame.run(&gpu, 1);
            frame.wavefront_steps(&gpu).unwrap().unwrap().len() as u32
        } else {
            1
        };
        // One dispatch (one wavefront step) per block, past the buffer.
        let count = blocks / steps + 3;
        let run = |few: bool| {
            let mut frame = gpu.prepare(&scene).unwrap();
            frame.set_wavefront(wavefront);
            frame.set_max_layers(if few { 16 } else { 1 });
            frame.set_wavefront_samples(if few { 16 } else { 1 });
            frame.run(&gpu, count);
            let (img, stats) = frame.image(&gpu).unwrap();
            assert_eq!(stats.rejected_samples, 0);
            img
        };
        let (many, few) = (run(false), run(true));
        assert!(many.rgb.iter().flatten().any(|&c| c > 0.0));
        assert!(
            many.rgb == few.rgb,
            "wavefront {wavefront}: {count} samples of {steps} dispatches each differ"
        );
    }
}

/// `GpuFrame::profile` times each dispatch of a frame and runs the same
/// samples as `run`: the image (or the first hits) bit for bit, each
/// path kernel's dispatches in the order it queues them (the wavefronts'
/// steps one after another, run by run, the sorted wavefront's four
/// kernels a step, `trace_last` and `resolve` at the end of each), and
/// times that are finite, not negative and within the frame's span.
#[test]
fn profiles_time_each_dispatch_of_the_same_frame() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut scene = common::example("gallery.toml");
    scene.film.width = 40;
    scene.film.height = 24;
    scene.film.spp = 3;
    let depth = scene.integrator.max_depth;
    for mode in [
        "megakernel",
        "wavefront",
        "sorted",
        "real-time",
        "first hits",
    ] {
        let frame = |profiled: bool| {
            let mut f = match mode {
                "real-time" => gpu.prepare_realtime(&scene),
                "first hits" => gpu.prepare_first_hits(&scene),
                _ => gpu.prepare(&scene),
            }
            .unwrap();
            if !matches!(mode, "real-time" | "first hits") {
                f.set_wavefront(mode != "megakernel");
                f.set_sorted(mode == "sorted");
                // Runs of two samples and one.
                f.set_wavefront_samples(2);
            }
            let profile = if profiled {
                f.profile(&gpu, 3).unwrap()
            } else {
                f.run(&gpu, 3);
                None
            };
            let values: Vec<f32> = if mode == "first hits" {
                f.aovs(&gpu).unwrap().depth
            } else {
                f.image(&gpu).unwrap().0.rgb.into_iter().flatten().collect()
            };
            (values, profile, f.features().shadows_ahead())
        };
        let (plain, _, _) = frame(false);
        let (profiled, profile, shadows) = frame(true);
        assert!(plain.iter().all(|v| v.is_finite()), "{mode}");
        assert_eq!(
            plain, profiled,
            "{mode}: profile ran other samples than run"
        );
        // Lavapipe and GPUs offer timestamps; an adapter without gets None.
        let Some(profile) = profile else {
            eprintln!("{mode}: the adapter offers no timestamps");
            continue;
        };
        let kernels: Vec<&str> = profile.dispatches.iter().map(|d| d.kernel).collect();
        let steps: Vec<Option<u32>> = profile.dispatches.iter().map(|d| d.step).collect();
        let expected: Vec<(&str, Option<u32>)> = match mode {
            "megakernel" => vec![("main", None), ("resolve", None)],
            "real-time" => vec![("realtime", None), ("resolve", None)],
            "first hits" => vec![("aov_main", None); 3],
            _ => {
                // As many steps as the scene's depth takes (at most 16
                // and the last), the same for each run.
                let last = (depth + 1).min(16);
                let mut per = Vec::new();
                for k in 0..last {
                    if mode == "wavefront" {
                        per.push(("trace", Some(k)));
                        continue;
                    }
                    per.extend([("trace_extend", Some(k)), ("trace_scatter", Some(k))]);
                    if shadows {
                        per.push(("trace_shadow", Some(k)));
                    }
                    per.push(("trace_shade", Some(k)));
                }
                per.push(("trace_last", Some(last)));
                per.push(("resolve", None));
                per.repeat(2)
            }
        };
        let got: Vec<(&str, Option<u32>)> = kernels.iter().copied().zip(steps).collect();
        assert_eq!(got, expected, "{mode}");
        let sum = profile.dispatch_seconds();
        eprintln!(
            "{mode}: {} dispatches, {:.3} ms in them, {:.3} ms from the first's start to the last's end",
            got.len(),
            sum * 1e3,
            profile.span * 1e3
        );
        // Each dispatch within the frame's span. Their sum within it too
        // where passes run one after another (lavapipe); a GPU may write
        // a pass's first timestamp before the previous pass has drained,
        // so that the intervals overlap there.
        for d in &profile.dispatches {
            assert!(d.seconds.is_finite() && d.seconds >= 0.0, "{mode}: {d:?}");
            assert!(d.seconds <= profile.span * (1.0 + 1e-9), "{mode}: {d:?}");
        }
        assert!(sum > 0.0, "{mode}");
        if gpu.is_cpu() {
            assert!(
                sum <= profile.span * (1.0 + 1e-9),
                "{mode}: {sum} > {}",
                profile.span
            );
        }
    }
}

/// Asserts that two renders of the same paths agree: at least 97% of the
/// values within 1e-4 (relative above 1), the means within 1%, the
/// second all finite and non-negative.
fn same_paths(name: &str, (la, a): (&str, &Image), (lb, b): (&str, &Image)) {
    let (a, b): (Vec<f32>, Vec<f32>) = a
        .rgb
        .iter()
        .flatten()
        .zip(b.rgb.iter().flatten())
        .map(|(a, b)| (*a, *b))
        .unzip();
    let same = a
        .iter()
        .zip(&b)
        .filter(|(a, b)| (*a - *b).abs() <= 1e-4 * a.abs().max(1.0))
        .count() as f64
        / a.len() as f64;
    let mean = |v: &[f32]| v.iter().map(|&c| c as f64).sum::<f64>() / v.len() as f64;
    let (ma, mb) = (mean(&a), mean(&b));
    eprintln!(
        "{name}: {:.2}% of the values agree, means {ma:.5} ({la}) {mb:.5} ({lb})",
        100.0 * same
    );
    assert!(b.iter().all(|c| c.is_finite() && *c >= 0.0), "{name}");
    assert!(same >= 0.97, "{name}: {same}");
    assert!((ma - mb).abs() <= 0.01 * ma, "{name}: {ma} vs {mb}");
}

/// The kernels specialized to a scene's models trace the general kernels'
/// paths (the same random numbers, so the same image within the drivers'
/// floating-point contraction), in both modes: a model that `Features::of`
/// missed, or a guard in `materials.wgsl` that drops a model the scene
/// uses, renders it black in the specialized image. Scenes: the gallery
/// (13 models, a mix), the translucent one (the subsurface integrator and
/// its internal lobes), two furnaces of one model each, whose kernels
/// dispatch to it without a switch (`model` in `materials.wgsl`), and a
/// sphere of 600 bumps under a point light, whose object lists its
/// candidates (the others keep theirs in a bit mask) and whose hierarchy
/// of 600 supports the skip links walk (layout.rs,
/// `skip_links_walk_the_hierarchy_as_a_stack_would`, checks the walk
/// itself). On Mesa 22.3 (CI's lavapipe) the general kernel of that
/// sphere leaves out the caustics' code, which it never runs (no glass):
/// with it the driver's loop miscompile darkens the sphere by 0.9% in
/// both modes, real time included, where the code is unreachable (docs/gpu.md,
/// "Known defect"); the specialized kernels and the CPU agree.
#[test]
fn specialized_kernels_trace_the_general_kernels_paths() {
    use isolux_gpu::Features;
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut bumpy = common::example("perturbed-sphere.toml");
    bumpy.geometry =
        isolux_geometry::Aggregate::new(vec![isolux_geometry::samples::bumpy_sphere(600)]);
    bumpy.object_material = vec![0];
    let fitted = gpu.prepare(&bumpy).unwrap().features();
    assert!(fitted.list);
    for (name, mut scene) in [
        ("600 bumps", bumpy),
        ("gallery", common::example("gallery.toml")),
        ("translucent", common::example("translucent.toml")),
        ("diffuse furnace", common::example("furnace.toml")),
        ("glass furnace", glass_furnace(64)),
    ] {
        scene.film.width = 40;
        scene.film.height = 24;
        scene.film.spp = 4;
        for realtime in [false, true] {
            let run = |general: bool| {
                let mut frame = if realtime {
                    gpu.prepare_realtime(&scene).unwrap()
                } else {
                    gpu.prepare(&scene).unwrap()
                };
                assert_ne!(frame.features(), Features::ALL, "{name}");
                if general {
                    let all = if gpu.miscompiles_loops() && name == "600 bumps" {
                        Features {
                            caustics: false,
                            ..Features::ALL
                        }
                    } else {
                        Features::ALL
                    };
                    frame.set_features(all).unwrap();
                }
                frame.run(&gpu, 4);
                let (img, stats) = frame.image(&gpu).unwrap();
                assert_eq!(stats.rejected_samples, 0, "{name}");
                img
            };
            let label = format!(
                "{name}, {}",
                if realtime { "real time" } else { "path traced" }
            );
            same_paths(
                &label,
                ("general", &run(true)),
                ("specialized", &run(false)),
            );
        }
    }
}

/// A run's samples go to the GPU as dispatches of up to 16 samples, a
/// thread per pixel and sample writing its own layer, which `resolve`
/// adds to the pixel in sample order (`GpuFrame::set_max_layers`). The
/// image does not depend on how the samples are grouped: one dispatch per
/// sample, dispatches of 3 and one of all of them give the same bits, in
/// the path tracer (also across runs: 7 then 2 samples) and in the
/// real-time mode (each run a whole frame that replaces the last: a
/// second run gives the first's image). A layer read twice, skipped, or
/// added out of order, or a real-time frame added to the last, fails it.
#[test]
fn sample_layers_sum_as_one_dispatch_per_sample_would() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut scene = common::example("gallery.toml");
    scene.film.width = 61;
    scene.film.height = 35;
    scene.film.spp = 7;
    let bits = common::bits;
    for realtime in [false, true] {
        let run = |layers: u32| {
            let mut frame = if realtime {
                gpu.prepare_realtime(&scene).unwrap()
            } else {
                gpu.prepare(&scene).unwrap()
            };
            frame.set_max_layers(layers);
            frame.run(&gpu, 7);
            if realtime {
                let (first, _) = frame.image(&gpu).unwrap();
                frame.run(&gpu, 7);
                let (second, _) = frame.image(&gpu).unwrap();
                assert_eq!(
                    bits(&first),
                    bits(&second),
                    "a real-time frame replaces the last"
                );
            } else {
                frame.run(&gpu, 2);
            }
            let (img, stats) = frame.image(&gpu).unwrap();
            assert_eq!(stats.rejected_samples, 0);
            assert!(img.rgb.iter().flatten().any(|&c| c > 0.0));
            img
        };
        let one = bits(&run(1));
        for layers in [3, 16] {
            let same = one
                .iter()
                .zip(bits(&run(layers)))
                .filter(|(a, b)| **a == *b)
                .count();
            assert_eq!(
                same,
                one.len(),
                "{}: {layers} samples per dispatch against one",
                if realtime { "real time" } else { "path traced" }
            );
        }
    }
}

/// The real-time kernel traces the shadow rays of up to 32 point lights
/// before it shades the vertex, their answers in a bit mask
/// (`trace_shadows`); a scene of more lights gets kernels that trace them
/// in the shading loop (`Features::many_lights`), as the general kernels
/// do for every scene. With 32 lights (the mask's last bit) and 33, each
/// lighting the sphere from its own side, the fitted kernels render what
/// the general ones do, value for value. A light's bit read from the
/// wrong place (a shift off by one, the mask cut at 31) fails it.
#[test]
fn lights_up_to_the_mask_and_beyond_shade_as_the_general_kernels() {
    use isolux_core::Rgb;
    use isolux_gpu::Features;
    use isolux_render::PointLight;
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut scene = common::example("perturbed-sphere.toml");
    scene.film.width = 40;
    scene.film.height = 24;
    scene.film.spp = 4;
    for n in [32usize, 33] {
        scene.lights = (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                let y = 0.3 + 3.0 * (k % 4) as f64 / 3.0;
                PointLight {
                    position: glam::DVec3::new(3.0 * a.cos(), y, 3.0 * a.sin()),
                    intensity: Rgb::new(30.0, 28.0, 25.0) * (4.0 / n as f64),
                }
            })
            .collect();
        let run = |general: bool| {
            let mut frame = gpu.prepare_realtime(&scene).unwrap();
            assert_eq!(frame.features().many_lights, n > 32, "{n} lights");
            if general {
                frame.set_features(Features::ALL).unwrap();
            }
            frame.run(&gpu, 4);
            let (img, stats) = frame.image(&gpu).unwrap();
            assert_eq!(stats.rejected_samples, 0);
            img
        };
        same_paths(
            &format!("{n} lights, real time"),
            ("general", &run(true)),
            ("fitted", &run(false)),
        );
    }
}

/// A sphere of radius 1 with a bump, on a sphere of radius 100, lit by a
/// point light and a constant sky, all moved `shift` units along x.
fn moved_scene(shift: f64, with_camera: bool) -> Scene {
    use glam::DVec3;
    use isolux_core::Rgb;
    use isolux_geometry::{Aggregate, Object, Perturbation, Quadric};
    use isolux_materials::diffuse::Diffuse;
    use isolux_render::{Camera, Environment, PointLight};
    let at = |x: f64, y: f64, z: f64| DVec3::new(shift + x, y, z);
    let bump = Perturbation {
        quadric: Quadric::sphere(at(0.0, 0.3, 0.9), 0.3),
        factor: 300.0,
    };
    let objects = vec![
        Object::new(Quadric::sphere(at(0.0, 0.0, 0.0), 1.0), vec![bump], None).unwrap(),
        Object::new(Quadric::sphere(at(0.0, -101.0, 0.0), 100.0), vec![], None).unwrap(),
    ];
    let mut scene = Scene {
        camera: Camera {
            position: if with_camera {
                at(0.0, 1.0, 5.0)
            } else {
                DVec3::new(0.0, 1.0, 5.0)
            },
            look_at: at(0.0, 0.0, 0.0),
            up: DVec3::Y,
            fov_y: 40.0,
        },
        lights: vec![PointLight {
            position: at(2.0, 4.0, 3.0),
            intensity: Rgb::new(20.0, 20.0, 20.0),
        }],
        environment: Environment::Constant(Rgb::new(0.2, 0.3, 0.4)),
        materials: vec![Material::Diffuse(Diffuse {
            reflectance: Rgb::new(0.7, 0.7, 0.7),
        })],
        material_names: vec!["m".into()],
        object_material: vec![0, 0],
        geometry: Aggregate::new(objects),
        ..Scene::default()
    };
    scene.film.width = 96;
    scene.film.height = 64;
    scene.film.spp = 16;
    scene
}

/// An object thinner than a few of the GPU's ray offsets is warned about
/// (`thin_object_warning`), naming it: the translucent example's milk
/// ellipsoid flattened to a disc 2e-6 thick, which the GPU rendered dark
/// (its rays leaving one face started beyond the other). Not the example
/// scenes, nor the same disc 2e-3 thick.
#[test]
fn thin_objects_are_warned_about() {
    let examples = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/scenes");
    for entry in std::fs::read_dir(examples).unwrap() {
        let path = entry.unwrap().path();
        let scene = isolux_scene::load(&path).unwrap();
        assert_eq!(
            isolux_gpu::thin_object_warning(&scene),
            None,
            "{}",
            path.display()
        );
    }
    let source = std::fs::read_to_string(format!("{examples}/translucent.toml")).unwrap();
    let ellipsoid = "radii = [0.45, 0.6, 0.45]";
    assert!(source.contains(ellipsoid));
    let dir = std::env::temp_dir().join(format!("isolux-thin-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // The scene's environment map is named relative to its file.
    let env = std::path::Path::new(examples).join("../env");
    let disc = |thickness: f64| {
        let text = source
            .replace(
                ellipsoid,
                &format!("radii = [0.45, 0.6, {}]", thickness / 2.0),
            )
            // Without its bump, whose reach the box allows for.
            .replace("factor = 2000.0", "factor = 0.0")
            .replace("../env/", &format!("{}/", env.display()));
        let file = dir.join("disc.toml");
        std::fs::write(&file, text).unwrap();
        isolux_scene::load(&file).unwrap()
    };
    let why = isolux_gpu::thin_object_warning(&disc(2e-6)).expect("a warning");
    assert!(
        why.starts_with("object[1]'s box is 2.00e-6 units thick"),
        "{why}"
    );
    assert_eq!(isolux_gpu::thin_object_warning(&disc(2e-3)), None);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Paths ended at `MAX_MEDIUM_EVENTS` are counted by both path-tracing
/// kernels, the wavefront and the megakernel (`RenderStats::capped_paths`,
/// `count_capped`), as by the CPU: a camera inside a white sphere of
/// medium whose mean free path is 1e-4 of its radius (some 1e8 events to
/// leave it) ends every path at the cap, 4 of 4 at 2 x 2 pixels and 1
/// spp; at 1e-2 (some 1e4) none. Not on Mesa 22.3's lavapipe, which ends
/// such walks early (docs/gpu.md, "Known defect"), and takes a minute a
/// walk of 1e5 events there.
#[test]
fn paths_ended_at_the_cap_of_medium_events_are_counted() {
    use isolux_gpu::PathKernel;
    let Some(mut gpu) = common::open("GPU image tests") else {
        return;
    };
    if gpu.miscompiles_loops() {
        eprintln!("skipped: {} ends long walks early", gpu.driver);
        return;
    }
    // Shared with the CLI's test of the warning (cli.rs), `sigma_s`
    // replaced.
    let text = common::test_scene_text("medium-too-thick.toml");
    assert!(text.contains("sigma_s = [1e4, 1e4, 1e4]"));
    let scene = |sigma: f64| {
        let src = text.replace(
            "sigma_s = [1e4, 1e4, 1e4]",
            &format!("sigma_s = [{sigma:e}, {sigma:e}, {sigma:e}]"),
        );
        common::parse(&src, "thick.toml")
    };
    for (sigma, capped) in [(1e4, 4), (1e2, 0)] {
        let s = scene(sigma);
        let (_, cpu) = render(&s, &RenderOptions::default(), &|_, _| {}).unwrap();
        assert_eq!(cpu.capped_paths, capped, "sigma_s {sigma}");
        for kernel in [PathKernel::Wavefront, PathKernel::Megakernel] {
            gpu.set_path_kernel(kernel);
            let (_, stats) = gpu.render(&s, &|_, _| {}).unwrap();
            eprintln!(
                "sigma_s {sigma}: capped CPU {}, GPU {kernel:?} {}",
                cpu.capped_paths, stats.capped_paths
            );
            assert_eq!(stats.capped_paths, capped, "sigma_s {sigma} {kernel:?}");
        }
    }
}

/// A random-walk medium whose mean free path spans fewer than ten ray
/// offsets off its surface is warned about, on each back end by its own
/// offset (`fine_medium_warning` for the GPU, `Scene::finest_medium` with
/// `Scene::cpu_spawn_offset` for the CPU; docs/subsurface.md, "Media too
/// thick for the walk"): `lamplit-milk.toml`'s milk with its `scale`
/// raised from 10 (a mean free path of 5.2e-3 units) to 1e4 (5.2e-5,
/// where the GPU's image came out 2% dark) is named by the GPU's check
/// alone, at 1e7 (5.2e-8, 2% dark on the CPU) by both. The example scenes
/// are warned about by neither.
#[test]
fn media_finer_than_the_ray_offset_are_warned_about() {
    let examples = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/scenes");
    let cpu = |scene: &isolux_render::Scene| {
        scene
            .finest_medium(|o| scene.cpu_spawn_offset(o))
            .map(|f| f.describe(scene, "the CPU"))
    };
    for entry in std::fs::read_dir(examples).unwrap() {
        let path = entry.unwrap().path();
        let scene = isolux_scene::load(&path).unwrap();
        let name = path.display();
        assert_eq!(isolux_gpu::fine_medium_warning(&scene), None, "{name}");
        assert_eq!(cpu(&scene), None, "{name}");
    }
    let source = std::fs::read_to_string(format!("{examples}/lamplit-milk.toml")).unwrap();
    let line = "scale = 10.0          # 1 scene unit = 10 mm";
    assert!(source.contains(line));
    let at = |scale: &str| {
        let text = source.replacen(line, &format!("scale = {scale}"), 1);
        isolux_scene::parse_str(&text, Path::new("milk.toml"), Path::new(examples)).unwrap()
    };
    let milk = "the random-walk medium of object[0] (material \"milk\") has a mean free path of";
    let scene = at("1e4");
    let why = isolux_gpu::fine_medium_warning(&scene).expect("a warning");
    assert!(why.starts_with(&format!("{milk} 5.22e-5 units")), "{why}");
    assert!(why.contains("the GPU starts rays"), "{why}");
    assert_eq!(cpu(&scene), None);
    let scene = at("1e7");
    assert!(isolux_gpu::fine_medium_warning(&scene).is_some());
    let why = cpu(&scene).expect("a warning");
    assert!(why.starts_with(&format!("{milk} 5.22e-8 units")), "{why}");
    assert!(why.contains("the CPU starts rays"), "{why}");
    let scene = at("10.0");
    assert_eq!(isolux_gpu::fine_medium_warning(&scene), None);
}

/// The GPU takes the camera as its origin (`isolux_gpu::rebase_point`)
/// and intersects each object in its own frame (docs/gpu.md,
/// "Precision"), so a scene moved far from the world origin, camera
/// included, renders as it does at the origin: moved 1e6 units, the GPU's
/// image against the CPU's of the scene at the origin, within noise (block
/// differences at most 1.5 times the CPU's own between seeds, as the
/// gallery's; 1.13 measured, 35.9 with the world origin as the GPU's,
/// and 3.07 for the CPU's own image there, whose spawn offset grows with
/// the coordinates). What f32 still cannot hold is an object far from the
/// camera for its size: the same objects moved just beyond
/// `MAX_SCALE_RATIO` times the small sphere's size, the camera left at the
/// origin, are refused, naming the small sphere.
#[test]
fn scenes_far_from_the_origin_render_as_at_the_origin() {
    let far = 1.0e6;
    assert!(isolux_gpu::f32_shortfall(&moved_scene(far, true)).is_none());
    // The small object is about 2.1 units across (its box: the sphere
    // grown by the bump's reach, docs/geometry.md) and reaches about
    // shift + 1 along x.
    let (size, reach) = {
        let s = moved_scene(0.0, true);
        let b = s.geometry.objects()[0].bbox();
        ((b.max - b.min).max_element(), b.max.x)
    };
    let inside = 0.95 * isolux_gpu::MAX_SCALE_RATIO * size - reach;
    let beyond = 1.05 * isolux_gpu::MAX_SCALE_RATIO * size - reach;
    assert!(isolux_gpu::f32_shortfall(&moved_scene(inside, false)).is_none());
    let why = isolux_gpu::f32_shortfall(&moved_scene(beyond, false)).expect("refused");
    assert!(
        why.starts_with(&format!("object[0] is {size:.4e}")),
        "{why}"
    );
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut at_origin = moved_scene(0.0, true);
    let (diff, noise, mg, mc) = common::compare_with_cpu(
        &mut at_origin,
        |s| {
            let mut moved = moved_scene(far, true);
            moved.integrator.seed = s.integrator.seed;
            gpu_image(&gpu, &moved)
        },
        cpu_image,
        "moved 1e6 (GPU) against the origin (CPU)",
    );
    assert!(diff <= 1.5 * noise, "{diff} vs noise {noise}");
    assert!((mg - mc).abs() <= 0.02 * mc, "{mg} vs {mc}");
    match gpu.render(&moved_scene(beyond, false), &|_, _| {}) {
        Err(isolux_gpu::GpuError::Precision(m)) => assert_eq!(m, why),
        other => panic!("moved {beyond:.0}: {:?}", other.map(|_| ())),
    }
}

/// The test scene `examples/tests/small-units.toml` with its lengths
/// multiplied by `10^exponent`, and its light's intensity by `10^(2
/// exponent)`: the file writes them, and nothing else, with the exponents
/// `e+0` and `E+0` (its comment says how; isolux's analytic.rs renders it
/// on the CPU alike).
fn scaled_scene(exponent: i32) -> Scene {
    parsed_scene(&scaled_text(exponent))
}

/// The path of `examples/tests/small-units.toml`.
const SMALL_UNITS: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../examples/tests/small-units.toml"
);

/// The text of [`scaled_scene`].
fn scaled_text(exponent: i32) -> String {
    let text = std::fs::read_to_string(SMALL_UNITS).unwrap();
    assert!(text.matches("e+0").count() >= 4 && text.contains("E+0"));
    let text = text.replace("E+0", &format!("e{}", 2 * exponent));
    text.replace("e+0", &format!("e{exponent}"))
}

/// `text` parsed as a scene beside `small-units.toml`.
fn parsed_scene(text: &str) -> Scene {
    common::parse(text, SMALL_UNITS)
}

/// [`scaled_scene`] at `10^exponent` beside a clay sphere 2 units across,
/// 100 units behind the camera (out of the picture, a 4e-5 share of the
/// sky hidden): the scene's length is 1, its objects' 1e4 times smaller.
/// With `bounded`, the floor plane is clipped to a box 16 x 1.5 x 16
/// times the scale under the spheres, which gives it its own length.
fn small_beside_large(exponent: i32, bounded: bool) -> Scene {
    let mut text = scaled_text(exponent);
    let plane = "normal = [0.0, 1.0, 0.0] }\n";
    assert!(text.ends_with(plane));
    if bounded {
        let s = 10f64.powi(exponent);
        text += &format!(
            "bounds = {{ min = [{}, {}, {}], max = [{}, {}, {}] }}\n",
            -8.0 * s,
            -2.0 * s,
            -8.0 * s,
            8.0 * s,
            -0.5 * s,
            8.0 * s
        );
    }
    text += "\n[[object]]\nmaterial = \"clay\"\n\
             base = { type = \"sphere\", center = [0.0, 0.0, 100.0], radius = 1.0 }\n";
    parsed_scene(&text)
}

/// Each object starts its rays off its own surface at its own length's
/// floor (`object_floor`, render.wgsl), as on the CPU, not at the
/// scene's: the small-units scene at 1e-4 beside a sphere 2 units across
/// (its floor bounded) matches the CPU's image of the same scene within
/// 1.5 times the CPU's seed-to-seed noise (1.2 times on lavapipe). Until
/// 2026-12-06 every object took the scene's floor, 1e-4 here, the radius
/// of the clay sphere: warned about as thin, 6.1 times the noise at 1e-4,
/// 12.5 times at 1e-5 (means 1.4% dark and 1.2% bright). With the floor
/// plane unbounded it keeps the scene's floor (as on the CPU, an
/// unbounded object's length is the scene's), 5.4 times the noise: the
/// thin-object warning names the plane and `bounds`.
#[test]
fn small_objects_beside_large_ones_keep_their_own_offset() {
    let bounded = small_beside_large(-4, true);
    assert_eq!(isolux_gpu::thin_object_warning(&bounded), None);
    let floors: Vec<f64> = bounded
        .geometry
        .objects()
        .iter()
        .map(isolux_gpu::object_floor)
        .collect();
    assert!(floors[..3].iter().all(|&f| f < 2e-7), "{floors:?}");
    assert_eq!(floors[3], isolux_gpu::SPAWN_OFFSET as f64);
    let why = isolux_gpu::thin_object_warning(&small_beside_large(-4, false)).expect("a warning");
    assert!(
        why.contains("object[1]")
            && why.contains("unbounded object[2]")
            && why.contains("`bounds`"),
        "{why}"
    );
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let mut scene = small_beside_large(-4, true);
    let (diff, noise, mg, mc) = common::compare_with_cpu(
        &mut scene,
        |s| gpu_image(&gpu, s),
        cpu_image,
        "small objects beside a large one",
    );
    assert!(diff <= 1.5 * noise, "{diff} vs noise {noise}");
    assert!((mg - mc).abs() <= 0.02 * mc, "{mg} vs {mc}");
}

/// A scene renders the same on the GPU in any unit: the spawn offset's
/// floor and the walk's tolerances scale with the length of the scene's
/// bounded objects and of each object, at most 1 (`spawn_floor`,
/// `GpuObject::origin.w`). Until 2026-12-06 they were absolute (1e-4
/// units off a surface): the perturbed-sphere example scaled by 1e-4
/// rendered 1.4% brighter than on the CPU, by 1e-5 12% darker; this
/// scene at 1e-6 differed from the CPU's at 1 by 9.1 times the CPU's
/// seed-to-seed noise (8 x 8 blocks), its mean 1.1% darker, and was
/// warned about as thin. Now 1.25 times at 1e-3 and 1e-6, the means
/// within 0.16% (lavapipe).
#[test]
fn scenes_in_small_units_render_as_in_large_ones() {
    for exponent in [-3, -6] {
        let scene = scaled_scene(exponent);
        assert_eq!(isolux_gpu::thin_object_warning(&scene), None);
        let floor = isolux_gpu::spawn_floor(&scene);
        assert!(floor < 1e-4 * 10f64.powi(exponent + 1), "{floor}");
    }
    assert_eq!(
        isolux_gpu::spawn_floor(&scaled_scene(0)),
        isolux_gpu::SPAWN_OFFSET as f64
    );
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    for exponent in [-3, -6] {
        let mut unit = scaled_scene(0);
        let (diff, noise, mg, mc) = common::compare_with_cpu(
            &mut unit,
            |s| {
                let mut small = scaled_scene(exponent);
                small.integrator.seed = s.integrator.seed;
                gpu_image(&gpu, &small)
            },
            cpu_image,
            &format!("1e{exponent} (GPU) against 1 (CPU)"),
        );
        assert!(diff <= 1.5 * noise, "1e{exponent}: {diff} vs noise {noise}");
        assert!((mg - mc).abs() <= 0.02 * mc, "1e{exponent}: {mg} vs {mc}");
    }
}

/// Every example scene runs with `--gpu`: none is refused for f32's
/// resolution (their largest object ratios, from the GPU's origin, are
/// printed; docs/gpu.md "Precision" quotes them), and none needs the f64
/// intersection for its conditioning (`f32_ill_conditioned`).
#[test]
fn every_example_scene_fits_the_gpus_f32() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    for dir in ["scenes", "bench"] {
        for e in std::fs::read_dir(root.join(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_none_or(|x| x != "toml") {
                continue;
            }
            let scene = isolux_scene::load(&p).unwrap();
            let ratio = isolux_gpu::worst_scale_ratio(&scene).map_or(0.0, |w| w.ratio);
            eprintln!("{}: largest ratio {ratio:.2}", p.display());
            assert!(
                isolux_gpu::f32_shortfall(&scene).is_none(),
                "{}: {ratio}",
                p.display()
            );
            let bump = isolux_gpu::worst_bump_condition(&scene).map_or(0.0, |w| w.ratio);
            eprintln!("{}: largest bump condition {bump:.3e}", p.display());
            assert_eq!(
                isolux_gpu::f32_ill_conditioned(&scene),
                None,
                "{}",
                p.display()
            );
        }
    }
}

/// Paths that meet a `wave` surface more than once: the camera inside a
/// brushed-aluminium sphere of radius 5 (`wave-brushed.toml` grown), its
/// point light inside too, the floor left out. On Mesa 22.3's lavapipe the megakernel, which
/// runs the `wave` code at every bounce of its loop, ended every path at
/// its second `wave` vertex (the known loop miscompile, docs/gpu.md): the
/// image at `max_depth = 3` equalled the one at 2 (+0.0000%; a fuzzed
/// scene rendered 20% darker than the CPU). Such scenes now run as a
/// wavefront by default (one bounce per dispatch), which Mesa 25's
/// megakernel matches bit for bit. With the same random numbers a third
/// bounce only adds light: every pixel at depth 3 is at least its value at
/// depth 2, and the mean gains at least 3% (7.7% measured; +0.00% with the megakernel on Mesa 22.3).
#[test]
fn paths_meeting_wave_surfaces_twice_go_on() {
    let Some(gpu) = common::open("wave vertices") else {
        return;
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let source = std::fs::read_to_string(root.join("scenes/wave-brushed.toml")).unwrap();
    // Without the floor: every vertex lies on the sphere.
    let floor = source
        .rfind("[[object]]\nmaterial = \"floor\"")
        .expect("the floor");
    let text = source[..floor]
        .to_string()
        .replace(
            "center = [0.0, 0.0, 0.0], radius = 0.7",
            "center = [0.0, 0.0, 0.0], radius = 5.0",
        )
        .replace(
            "\"../heightfields/",
            &format!("\"{}/heightfields/", root.display()),
        );
    assert!(text.contains("radius = 5.0") && text.contains("/heightfields/brushed.exr"));
    let dir = std::env::temp_dir().join(format!("isolux-wave-twice-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("inside.toml");
    std::fs::write(&file, text).unwrap();
    let mut scene = isolux_scene::load(&file).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    (scene.film.width, scene.film.height, scene.film.spp) = (40, 30, 4);
    let mut at_depth = |d: u32| {
        scene.integrator.max_depth = d;
        gpu_image(&gpu, &scene)
    };
    let (two, three) = (at_depth(2), at_depth(3));
    for (a, b) in two.rgb.iter().zip(&three.rgb) {
        for c in 0..3 {
            assert!(b[c] >= a[c] - 1e-6 * a[c].abs(), "{} then {}", a[c], b[c]);
        }
    }
    let gain = image_mean(&three) / image_mean(&two) - 1.0;
    eprintln!("depth 3 against depth 2: {:+.2}%", 100.0 * gain);
    assert!(gain > 0.03, "{gain}");
}

/// A `wave` heightfield is placed in f32 on the GPU (`place_wave`), so a
/// spherical mapping centred far from its object gives coordinates whose
/// ulp exceeds the heightfield's texel: `wave-brushed.toml`'s mapping
/// centre moved 1e7 units away (a fuzzed scene) rendered the sphere half
/// as bright as the CPU. `f32_shortfall` refuses where an ulp of the
/// largest coordinate on the object's box (`pi` times its farthest
/// corner's distance from the centre, in um) exceeds a quarter texel, and
/// names the material: the centre moved to 0.95 of that distance is
/// accepted, to 1.05 of it refused, and the GPU's `render` refuses it with
/// the same words.
#[test]
fn far_wave_mappings_are_refused() {
    use glam::DVec3;
    use isolux_materials::wave::Mapping;
    let with_centre = |c: DVec3| {
        let mut scene = common::example("wave-brushed.toml");
        match &mut scene.materials[scene.object_material[0]] {
            Material::Wave(w) => w.mapping = Mapping::Spherical(c),
            other => panic!("{}", other.type_name()),
        }
        scene
    };
    let scene = with_centre(DVec3::ZERO);
    assert!(isolux_gpu::f32_shortfall(&scene).is_none());
    let (texel, um) = match &scene.materials[scene.object_material[0]] {
        Material::Wave(w) => (w.surface.texel_um, w.um_per_unit),
        _ => unreachable!(),
    };
    // The farthest corner's distance at which an ulp of pi r um is a
    // quarter texel; the centre at (0, 0, z) beyond the box's near face.
    let b = scene.geometry.objects()[0].bbox();
    let r = 0.25 * texel / (f32::EPSILON as f64 * std::f64::consts::PI * um);
    let (x, y) = (
        b.min.x.abs().max(b.max.x.abs()),
        b.min.y.abs().max(b.max.y.abs()),
    );
    let z_at = |r: f64| b.min.z + (r * r - x * x - y * y).sqrt();
    assert!(
        isolux_gpu::f32_shortfall(&with_centre(DVec3::new(0.0, 0.0, z_at(0.95 * r)))).is_none()
    );
    let far = with_centre(DVec3::new(0.0, 0.0, z_at(1.05 * r)));
    let why = isolux_gpu::f32_shortfall(&far).expect("refused");
    assert!(
        why.starts_with("object[0] wears the `wave` material \"brushed\" and lies far from its spherical mapping's centre"),
        "{why}"
    );
    let Some(gpu) = common::open("far wave mappings") else {
        return;
    };
    match gpu.render(&far, &|_, _| {}) {
        Err(isolux_gpu::GpuError::Precision(m)) => assert_eq!(m, why),
        other => panic!("{:?}", other.map(|_| ())),
    }
}

/// Camera rays test their 8 x 8 tile's list of objects (`cull_tiles` and
/// `use_tile` in camera.wgsl) instead of walking the object hierarchy
/// each, and find the same hits: the list holds, in the walk's order, every
/// object whose box the pyramid of the tile's rays meets. So the images are
/// the walk's bit for bit, path traced (megakernel and wavefront) and real
/// time, and so are the first hits' AOVs, on
/// the gallery (partial tiles at its right and bottom edges), with the
/// camera inside the floor's box and among the spheres (boxes behind it and
/// around it), and with a crowd of 400 small spheres that fills some tiles'
/// lists past their 16 entries (those tiles walk). It fails when the list
/// misses an object a ray hits: with a side plane of the pyramid turned
/// the wrong way 61% of the gallery's path-traced values agree, with each
/// list's last entry dropped 57%. A camera moved after the frame was
/// prepared gets lists of its own.
#[test]
fn tile_lists_give_the_walks_hits() {
    use glam::DVec3;
    use isolux_geometry::{Aggregate, Object, Quadric};
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let gallery = common::example("gallery.toml");
    let mut scenes = vec![("gallery", gallery.clone())];
    let mut inside = gallery.clone();
    inside.camera.position = DVec3::new(0.3, -0.2, 0.6);
    inside.camera.look_at = DVec3::new(0.0, 0.0, -1.35);
    scenes.push(("camera among the spheres, inside the floor's box", inside));
    let mut crowd = gallery.clone();
    let mut objects: Vec<Object> = crowd.geometry.objects().to_vec();
    for i in 0..20 {
        for j in 0..20 {
            let c = DVec3::new(-1.0 + 0.1 * i as f64, 1.2 + 0.1 * j as f64, -2.5);
            objects.push(Object::new(Quadric::sphere(c, 0.04), vec![], None).unwrap());
            crowd.object_material.push(0);
        }
    }
    crowd.geometry = Aggregate::new(objects);
    scenes.push(("a crowd past the lists' 16 entries", crowd));
    let bits = common::bits;
    for (name, mut scene) in scenes {
        scene.film.width = 61;
        scene.film.height = 35;
        scene.film.spp = 4;
        for mode in ["path traced", "wavefront", "real time", "first hits"] {
            let run = |lists: bool| {
                let mut frame = match mode {
                    "real time" => gpu.prepare_realtime(&scene).unwrap(),
                    "first hits" => gpu.prepare_first_hits(&scene).unwrap(),
                    _ => gpu.prepare(&scene).unwrap(),
                };
                frame.set_wavefront(mode == "wavefront");
                frame.set_tile_lists(lists);
                frame.run(&gpu, 4);
                if mode == "first hits" {
                    let a = frame.aovs(&gpu).unwrap();
                    let mut v: Vec<u32> = a.depth.iter().map(|d| d.to_bits()).collect();
                    v.extend(a.normal.iter().flatten().map(|c| c.to_bits()));
                    assert!(a.depth.iter().any(|&d| d > 0.0), "{name}: no hit");
                    v
                } else {
                    let (img, _) = frame.image(&gpu).unwrap();
                    assert!(img.rgb.iter().flatten().any(|&c| c > 0.0), "{name}");
                    bits(&img)
                }
            };
            common::all_equal(&run(false), &run(true), &format!("{name}, {mode}"));
        }
    }
    // A camera moved after the frame was prepared (the viewer's orbit)
    // gets lists of its own: the frame renders what its rays' walks find.
    // Lists left from the first camera lose objects (the camera among the
    // spheres sees others than the gallery's view): 25% of the values agree.
    let mut scene = gallery;
    scene.film.width = 61;
    scene.film.height = 35;
    scene.film.spp = 4;
    let mut moved = gpu.prepare(&scene).unwrap();
    scene.camera.position = DVec3::new(0.3, -0.2, 0.6);
    scene.camera.look_at = DVec3::new(0.0, 0.0, -1.35);
    moved.set_camera(&gpu, &scene.camera).unwrap();
    let mut image = |lists: bool| {
        moved.set_tile_lists(lists);
        moved.reset(&gpu);
        moved.run(&gpu, 4);
        bits(&moved.image(&gpu).unwrap().0)
    };
    let walk = image(false);
    common::all_equal(&walk, &image(true), "a moved camera");
}

/// The kernels are compiled without wgpu's run-time checks by default
/// (`Gpu::set_runtime_checks`: no index clamping, no loop counters), which
/// is sound only if no index leaves its array and every loop ends. With
/// the checks on, an out-of-bounds index would be clamped and read
/// another element, and a loop cut short: the images would differ. They
/// are the same bit for bit, path traced (megakernel and wavefront) and in
/// real time, on the gallery (13 models, tile lists where the adapter
/// takes them), the dipole scene (subsurface probes) and the grating
/// (`wave`'s loops over the heightfield).
#[test]
fn runtime_checks_change_nothing() {
    let Some(mut gpu) = common::open("GPU image tests") else {
        return;
    };
    assert!(!gpu.runtime_checks(), "off by default");
    for (file, modes) in [
        (
            "gallery.toml",
            &["megakernel", "wavefront", "real time"][..],
        ),
        ("translucent.toml", &["megakernel"][..]),
        ("wave-grating.toml", &["megakernel"][..]),
    ] {
        let scene = common::small_example(file);
        for mode in modes {
            gpu.set_runtime_checks(false);
            let unchecked = common::render_bits(&gpu, &scene, mode);
            gpu.set_runtime_checks(true);
            let checked = common::render_bits(&gpu, &scene, mode);
            common::all_equal(&unchecked, &checked, &format!("{file}, {mode}"));
        }
    }
    gpu.set_runtime_checks(false);
}

/// Every path tracer renders the same image every run, bit for bit, though
/// the wavefront's paths share SIMD groups in the order the queues'
/// atomics give them, which changes from run to run: three renders of
/// `translucent-random-walk.toml` (a lamp refracted into random-walk
/// media through curved boundaries, `manifold_refraction`) by the
/// megakernel and by the wavefront, and of the gallery by the sorted
/// wavefront (whose bins' atomics order the hits too).
///
/// Mesa 22.3's lavapipe (`loses_whole_paths`) renders the random-walk
/// scene by the wavefront differently from run to run (a few pixels, up
/// to 15% in a channel; with or without the lamp, with either
/// `refracted_lights`), where Mesa 25.0.7's renders the same file every
/// run: its miscompile of long loops makes a lane's result depend on the
/// other lanes of its group (docs/gpu.md, "The wavefront is
/// deterministic: Mesa 22.3's lanes are not"). There the wavefront is
/// checked on `fog.toml` (a scattering medium lit by a lamp) alone.
#[test]
fn path_tracers_render_the_same_image_every_run() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    for (file, mode) in [
        ("translucent-random-walk.toml", "megakernel"),
        ("translucent-random-walk.toml", "wavefront"),
        ("fog.toml", "wavefront"),
        // (A scene with the subsurface integrator is never sorted.)
        ("gallery.toml", "sorted"),
    ] {
        if file == "translucent-random-walk.toml" && mode == "wavefront" && loses_whole_paths(&gpu)
        {
            eprintln!("{file}, {mode}: not on Mesa 22.3 (its lanes are not independent)");
            continue;
        }
        let scene = common::small_example(file);
        let first = common::render_bits(&gpu, &scene, mode);
        for run in 1..3 {
            let again = common::render_bits(&gpu, &scene, mode);
            common::all_equal(
                &first,
                &again,
                &format!("{file}, {mode}, run {run} against run 0"),
            );
        }
    }
}

/// Caustics (`integrator.caustics = "manifold"`): a lamp lights a floor
/// through a glass slab (`examples/tests/lamp-above-glass.toml`; the
/// CPU's closed form in `crates/isolux/tests/analytic.rs`, 0.40040), in
/// air, under absorbing water and in scattering water (whose scattering
/// points gather the lamp through the glass too, `medium_light`): the
/// GPU's mean against the closed form, and GPU against CPU within noise;
/// the same for a glass sphere and
/// a perturbed glass blob over a floor under a lamp
/// (`examples/scenes/caustics.toml`, small), and a marble whose caustic's
/// rim leaves it at grazing angles (`examples/tests/marble-caustic.toml`:
/// with the leg to the exit crossing tested short of it, as the one-crossing
/// refraction is, the GPU lost the rim: block differences 0.00020 against the
/// CPU's own 0.00009, now 0.00009). With `"none"` the slab's
/// floor is black on the GPU too. The kernels carry the solve only where
/// a scene asks for it (the default) and has glass and a point light.
#[test]
fn caustics_match_the_cpu() {
    let Some(gpu) = common::open("GPU image tests") else {
        return;
    };
    let slab = common::test_scene_text("lamp-above-glass.toml");
    let scene = common::parse(&slab, "glass.toml");
    let m = image_mean(&gpu_image(&gpu, &scene));
    eprintln!("floor under a glass slab: GPU {m}");
    assert!((m - 0.40040).abs() < 0.01 * 0.40040, "{m}");
    let water = "[[material]]\nname = \"water\"\ntype = \"subsurface\"\n\
                 sigma_s = [0.0, 0.0, 0.0]\nsigma_a = [0.1, 0.1, 0.1]\nior = 1.33\n\
                 mode = \"random_walk\"\n[[object]]\nmaterial = \"water\"\n\
                 base = { type = \"sphere\", center = [0.0, 0.0, 0.0], radius = 10.0 }\n";
    // Water that scatters: its scattering points under the slab gather
    // the lamp through the glass too (on the CPU 0.211 against 0.127
    // without, 64 spp).
    let fog = water.replace("sigma_s = [0.0, 0.0, 0.0]", "sigma_s = [0.3, 0.3, 0.3]");
    let mut example = common::example("caustics.toml");
    example.film.width = 96;
    example.film.height = 64;
    example.film.spp = 16;
    for (name, src) in [
        ("floor under a glass slab", slab.clone()),
        ("floor under a glass slab under water", slab.clone() + water),
        (
            "floor and water under a glass slab in scattering water",
            slab.clone() + &fog,
        ),
        (
            "a marble's caustic and its rim",
            common::test_scene_text("marble-caustic.toml"),
        ),
    ] {
        let mut scene = common::parse(&src, "glass.toml");
        assert!(isolux_gpu::scene_features(&scene).unwrap().caustics);
        assert_matches_cpu(&gpu, &mut scene, name, 0.01);
    }
    assert_matches_cpu(&gpu, &mut example, "caustics.toml", 0.01);
    let none = slab.replace("caustics = \"manifold\"", "caustics = \"none\"");
    let scene = common::parse(&none, "glass.toml");
    assert!(!isolux_gpu::scene_features(&scene).unwrap().caustics);
    assert_eq!(image_mean(&gpu_image(&gpu, &scene)), 0.0);
    // The gallery has glass and a point light, and keeps "none" for its
    // benchmark; without that line it would carry the solve.
    let mut gallery = common::example("gallery.toml");
    assert!(!isolux_gpu::scene_features(&gallery).unwrap().caustics);
    gallery.integrator.caustics = isolux_render::Caustics::Manifold;
    assert!(isolux_gpu::scene_features(&gallery).unwrap().caustics);
}

/// `examples/scenes/underwater.toml` and variants of it, each taking one
/// of its parts away, GPU against CPU: the table a device session reads
/// to find which part an adapter gets wrong. On an NVIDIA H200
/// (2026-12-04, commit 6f93828) the scene rendered without its sky
/// (image mean 0.028 against the CPU's 0.391, megakernel and wavefront
/// alike; docs/gpu.md, "NVIDIA: open defects"), while lavapipe matches.
/// Each variant's GPU image is rendered four ways: the default kernels,
/// with wgpu's run-time checks (array indices clamped, loops bounded:
/// a difference there points at an index out of bounds or a loop that
/// never ends), without the camera rays' tile lists (the default on
/// GPUs, not on CPU drivers), and with the intersection in f64 (where
/// the adapter offers it: a difference there points at f32's
/// intersection). `ISOLUX_UNDERWATER_VARIANTS` (names, comma-separated)
/// runs some of them. Ignored: about 8 minutes on lavapipe (each
/// column compiles its kernels), a minute on NVIDIA.
#[test]
#[ignore]
fn underwater_variants_match_the_cpu() {
    let Some(mut gpu) = common::open("GPU image tests") else {
        return;
    };
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenes");
    let base = std::fs::read_to_string(dir.join("underwater.toml")).unwrap();
    let light = base.find("[[light]]").unwrap();
    let env = base.find("[environment]").unwrap();
    let jelly = base.rfind("[[object]]").unwrap();
    let edit = |from: &str, to: &str| {
        assert!(base.contains(from), "{from}");
        base.replace(from, to)
    };
    let integrator = "[integrator]\nmax_depth = 8\nseed = 3\n";
    let variants: Vec<(&str, String)> = vec![
        ("as is", base.clone()),
        ("no lamp", format!("{}{}", &base[..light], &base[env..])),
        ("no jellyfish", base[..jelly].to_string()),
        (
            "no marble",
            edit(
                "material = \"glass\"\nbase = { type = \"sphere\", center = [0.35",
                "material = \"stone\"\nbase = { type = \"sphere\", center = [0.35",
            ),
        ),
        (
            "grey water",
            edit(
                "sigma_s = [0.03, 0.04, 0.05]   # per unit (metres, say): clear sea water, scaled up\nsigma_a = [0.45, 0.07, 0.03]",
                "sigma_s = [0.04, 0.04, 0.04]\nsigma_a = [0.1, 0.1, 0.1]",
            ),
        ),
        (
            "water that does not scatter",
            edit(
                "sigma_s = [0.03, 0.04, 0.05]",
                "sigma_s = [0.0, 0.0, 0.0]",
            ),
        ),
        (
            "distance sampling",
            edit(integrator, &format!("{integrator}medium_light_sampling = \"distance\"\n")),
        ),
        (
            "flat refraction",
            edit(integrator, &format!("{integrator}refracted_lights = \"flat\"\n")),
        ),
        (
            "no caustics",
            edit(integrator, &format!("{integrator}caustics = \"none\"\n")),
        ),
    ];
    let only = std::env::var("ISOLUX_UNDERWATER_VARIANTS").ok();
    eprintln!("| variant | CPU | GPU | GPU, run-time checks | GPU, no tile lists | GPU, f64 |");
    eprintln!("|---|---:|---:|---:|---:|---:|");
    let mut worst: (f64, &str) = (0.0, "");
    for (name, text) in &variants {
        if only
            .as_deref()
            .is_some_and(|o| !o.split(',').any(|n| n.trim() == *name))
        {
            continue;
        }
        let mut scene =
            isolux_scene::parse_str(text, &dir.join("underwater-variant.toml"), &dir).unwrap();
        (scene.film.width, scene.film.height, scene.film.spp) = (48, 32, 64);
        let cpu = image_mean(&cpu_image(&scene));
        let gpu_mean = |gpu: &Gpu, tiles: bool| {
            let mut frame = gpu.prepare(&scene).unwrap();
            if !tiles {
                frame.set_tile_lists(false);
            }
            frame.run(gpu, scene.film.spp);
            let (img, _) = frame.image(gpu).unwrap();
            assert!(img.rgb.iter().flatten().all(|c| c.is_finite()), "{name}");
            image_mean(&img)
        };
        let plain = gpu_mean(&gpu, true);
        gpu.set_runtime_checks(true);
        let checked = gpu_mean(&gpu, true);
        gpu.set_runtime_checks(false);
        let untiled = gpu_mean(&gpu, false);
        let wide = gpu
            .set_precision(isolux_gpu::Precision::F64)
            .ok()
            .map(|()| gpu_mean(&gpu, true));
        gpu.set_precision(isolux_gpu::Precision::F32).unwrap();
        let f64_cell = wide.map_or("-".to_string(), |m| format!("{m:.5}"));
        eprintln!("| {name} | {cpu:.5} | {plain:.5} | {checked:.5} | {untiled:.5} | {f64_cell} |");
        for g in [plain, checked, untiled].into_iter().chain(wide) {
            let off = (g - cpu).abs() / cpu;
            if off > worst.0 {
                worst = (off, name);
            }
        }
    }
    assert!(worst.0 < 0.05, "{}: {:.1}% off", worst.1, 100.0 * worst.0);
}
