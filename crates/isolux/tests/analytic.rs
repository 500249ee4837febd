//! Whole-image tests against answers known in closed form.
//!
//! Ray geometry here is recomputed independently of `CameraRig` (the
//! pinhole formula written out again), so a camera bug cannot hide itself.

use isolux_core::{DVec3, Image};
use isolux_render::integrator::MAX_NESTED_MEDIA;
use isolux_render::{render, MediumLightSampling, RenderOptions, Scene};
use std::path::Path;

fn scene(src: &str) -> Scene {
    isolux_scene::parse_str(src, Path::new("test.toml"), Path::new(".")).expect("valid scene")
}

fn render_with(scene: &Scene, threads: usize) -> Image {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| render(scene, &RenderOptions::default(), &|_, _| {}))
        .unwrap()
        .0
}

/// Independent pinhole: direction through film point (fx, fy) in pixels,
/// for a camera at `eye` looking down -z with up +y.
fn pinhole_dir(fx: f64, fy: f64, w: u32, h: u32, fov_y: f64) -> DVec3 {
    let t = (fov_y.to_radians() / 2.0).tan();
    let sx = (2.0 * fx / w as f64 - 1.0) * t * w as f64 / h as f64;
    let sy = (1.0 - 2.0 * fy / h as f64) * t;
    DVec3::new(sx, sy, -1.0).normalize()
}

/// Distance from `c` to the line `eye + s d`.
fn line_distance(eye: DVec3, d: DVec3, c: DVec3) -> f64 {
    let v = c - eye;
    (v - v.dot(d) * d).length()
}

const SPHERE_SCENE: &str = r#"
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov_y = 30.0
[film]
width = 96
height = 64
spp = 4
[integrator]
max_depth = 16
[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]
[[material]]
name = "grey"
type = "diffuse"
reflectance = [REFL, REFL, REFL]
[[object]]
material = "grey"
base = { type = "sphere", center = [0.3, -0.2, 0.0], radius = 0.8 }
"#;

#[test]
fn diffuse_sphere_under_constant_sky_is_exactly_its_reflectance() {
    // Convex sphere: every first bounce escapes, so L = rho * 1 exactly,
    // and cosine sampling makes each sample exact (no noise).
    let s = scene(&SPHERE_SCENE.replace("REFL", "0.5"));
    let img = render_with(&s, 2);
    let (w, h) = (img.width, img.height);
    let eye = DVec3::new(0.0, 0.0, 4.0);
    let c = DVec3::new(0.3, -0.2, 0.0);
    let (mut inside, mut outside) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)];
            let dists: Vec<f64> = corners
                .iter()
                .map(|(cx, cy)| {
                    line_distance(
                        eye,
                        pinhole_dir(x as f64 + cx, y as f64 + cy, w, h, 30.0),
                        c,
                    )
                })
                .collect();
            let p = img.pixel(x, y);
            if dists.iter().all(|&d| d < 0.8) {
                inside += 1;
                for v in p {
                    assert!((v - 0.5).abs() < 1e-6, "sphere pixel ({x},{y}) = {p:?}");
                }
            } else if dists.iter().all(|&d| d > 0.8 + 0.02) {
                outside += 1;
                for v in p {
                    assert!((v - 1.0).abs() < 1e-6, "background pixel ({x},{y}) = {p:?}");
                }
            }
        }
    }
    assert!(inside > 500 && outside > 2000, "{inside} {outside}");
}

#[test]
fn projected_area_of_a_sphere_matches_analytic_value() {
    // Black sphere (rho = 0) under a white sky: 1 - pixel = coverage.
    // A sphere of radius r at distance D subtends a cone of half-angle
    // asin(r/D); centred in view, its image is a disk of radius tan(asin(r/D))
    // on the unit-distance film plane.
    let src = SPHERE_SCENE
        .replace("REFL", "0.0")
        .replace("center = [0.3, -0.2, 0.0]", "center = [0.0, 0.0, 0.0]")
        .replace("spp = 4", "spp = 64")
        .replace("width = 96", "width = 128")
        .replace("height = 64", "height = 128");
    let img = render_with(&scene(&src), 2);
    let covered: f64 = img.rgb.iter().map(|p| 1.0 - p[1] as f64).sum();
    let alpha = (0.8f64 / 4.0).asin();
    let radius_px = alpha.tan() / (15f64.to_radians().tan()) * 64.0;
    let area = std::f64::consts::PI * radius_px * radius_px;
    let rel = (covered - area).abs() / area;
    assert!(rel < 2e-3, "covered {covered} vs analytic {area} ({rel})");
}

const FURNACE: &str = r#"
[camera]
position = [0.3, 0.5, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_y = 35.0
[film]
width = 64
height = 48
spp = 8
[integrator]
max_depth = 256
seed = 3
ENV
[[material]]
name = "white"
type = "diffuse"
reflectance = [1.0, 1.0, 1.0]
[[object]]
material = "white"
base = { type = "sphere", center = [0.0, 0.0, 0.0], radius = 0.6 }
[[object.perturbation]]
quadric = { type = "sphere", center = [0.0, 0.0, 0.6], radius = 0.35 }
factor = -600.0
[[object.perturbation]]
quadric = { type = "sphere", center = [0.45, 0.3, 0.3], radius = 0.3 }
factor = 2500.0
[[object.perturbation]]
quadric = { type = "ellipsoid", center = [-0.4, 0.1, 0.4], radii = [0.5, 0.1, 0.1], rotate = [0.0, 30.0, 20.0] }
factor = 400000.0
[[object.perturbation]]
quadric = { type = "sphere", center = [0.0, 0.6, 0.0], radius = 0.3 }
factor = -800.0
"#;

#[test]
fn white_furnace_on_a_non_convex_perturbed_object_stays_at_one() {
    // Reflectance 1 under radiance 1: every path that escapes carries
    // exactly 1; Russian roulette never cuts throughput 1. Only paths that
    // exhaust max_depth (deep inside concavities) can lose energy.
    let s = scene(&FURNACE.replace(
        "ENV",
        "[environment]\ntype = \"constant\"\nradiance = [1.0, 1.0, 1.0]",
    ));
    let img = render_with(&s, 2);
    let mut sum = 0.0;
    for p in &img.rgb {
        for &v in p {
            assert!(v <= 1.0 + 1e-6 && v > 0.99, "{p:?}");
            sum += v as f64;
        }
    }
    let mean = sum / (3 * img.rgb.len()) as f64;
    assert!(mean > 0.9999, "{mean}");
}

#[test]
fn white_furnace_under_an_environment_map_exercises_mis() {
    // A constant-valued *map* goes through light sampling + MIS: the
    // estimator is noisy but unbiased, so the image mean stays at 1.
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("white.exr");
    let img = Image {
        width: 32,
        height: 16,
        rgb: vec![[1.0; 3]; 32 * 16],
        aov: None,
    };
    isolux_io::write_exr(&map, &img).unwrap();
    let env = "[environment]\ntype = \"map\"\nfile = \"white.exr\"\nscale = 1.0";
    let src = FURNACE.replace("ENV", env).replace("spp = 8", "spp = 16");
    let s = isolux_scene::parse_str(&src, Path::new("t.toml"), dir.path()).unwrap();
    let out = render_with(&s, 2);
    let n = (3 * out.rgb.len()) as f64;
    let mean: f64 = out
        .rgb
        .iter()
        .flat_map(|p| p.iter())
        .map(|&v| v as f64)
        .sum::<f64>()
        / n;
    let var: f64 = out
        .rgb
        .iter()
        .flat_map(|p| p.iter())
        .map(|&v| (v as f64 - mean).powi(2))
        .sum::<f64>()
        / n;
    // Standard error of the mean over pixels (channels are correlated:
    // count pixels, not channels).
    let se = (var / out.rgb.len() as f64).sqrt();
    assert!((mean - 1.0).abs() < 4.0 * se + 1e-3, "mean {mean} se {se}");
    assert!(var > 0.0, "light sampling should add some noise");
}

#[test]
fn point_light_on_a_plane_matches_closed_form() {
    // Direct light only: L = rho/pi * I cos(theta) / r^2, noise-free.
    let src = r#"
[camera]
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_y = 40.0
[film]
width = 40
height = 30
spp = 1
[integrator]
max_depth = 1
[[light]]
type = "point"
position = [0.5, 0.7, 1.0]
intensity = [2.0, 3.0, 4.0]
[[material]]
name = "m"
type = "diffuse"
reflectance = [0.25, 0.5, 0.75]
[[object]]
material = "m"
base = { type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
"#;
    // Hold the sub-pixel position fixed: with spp = 1 the sample is jittered
    // inside the pixel, so compare against the closed form at the jittered
    // point's neighbourhood bound instead: the value varies smoothly, so
    // the pixel must lie between the minimum and maximum over its corners.
    let img = render_with(&scene(src), 1);
    let eye = DVec3::new(0.0, 0.0, 3.0);
    let light = DVec3::new(0.5, 0.7, 1.0);
    let radiance = |fx: f64, fy: f64| -> f64 {
        let d = pinhole_dir(fx, fy, 40, 30, 40.0);
        let t = -eye.z / d.z;
        let p = eye + t * d;
        let l = light - p;
        let r2 = l.length_squared();
        0.5 / std::f64::consts::PI * 3.0 * (l.z / r2.sqrt()) / r2
    };
    for y in 0..30 {
        for x in 0..40 {
            let v = img.pixel(x, y)[1] as f64;
            let vals: Vec<f64> = (0..=4)
                .flat_map(|i| (0..=4).map(move |j| (i, j)))
                .map(|(i, j)| radiance(x as f64 + i as f64 / 4.0, y as f64 + j as f64 / 4.0))
                .collect();
            let lo = vals.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = vals.iter().cloned().fold(0.0, f64::max);
            assert!(
                v >= lo * (1.0 - 1e-4) && v <= hi * (1.0 + 1e-4),
                "({x},{y}) {v} not in [{lo}, {hi}]"
            );
        }
    }
    // Colour ratio follows rho * I exactly.
    let p = img.pixel(20, 15);
    assert!(((p[0] / p[1]) as f64 - (0.25 * 2.0) / (0.5 * 3.0)).abs() < 1e-5);
    assert!(((p[2] / p[1]) as f64 - (0.75 * 4.0) / (0.5 * 3.0)).abs() < 1e-5);
}

#[test]
fn image_is_bit_identical_whatever_the_thread_count() {
    let src = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/scenes/perturbed-sphere.toml"
    ))
    .unwrap();
    let mut s = isolux_scene::parse_str(&src, Path::new("p.toml"), Path::new(".")).unwrap();
    s.film.width = 64;
    s.film.height = 48;
    s.film.spp = 5;
    let a = render_with(&s, 1);
    let b = render_with(&s, 3);
    let c = render_with(&s, 2);
    assert_eq!(a.rgb, b.rgb);
    assert_eq!(a.rgb, c.rgb);
    s.integrator.seed += 1;
    let d = render_with(&s, 2);
    assert_ne!(a.rgb, d.rgb, "the seed must matter");
}

#[test]
fn no_nan_or_inf_reaches_the_image() {
    // Extreme but valid inputs: huge light, grazing camera, tiny bumps.
    let src = FURNACE
        .replace("ENV", "[[light]]\ntype = \"point\"\nposition = [0.0, 0.0, 0.6000001]\nintensity = [1e30, 1e30, 1e30]")
        .replace("spp = 8", "spp = 2");
    let img = render_with(&scene(&src), 2);
    assert!(img.rgb.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
}

#[test]
fn every_model_under_a_white_sky_stays_below_the_sky() {
    // Sphere of each model under constant radiance 1. On a convex object a
    // reflected ray escapes at once, and each model's sample weight
    // f cos / pdf is at most 1 (F G2 / G1 for visible-normal sampling), so
    // no pixel may exceed the sky; a perfect F = 1 mirror is exactly 1.
    let models = [
        ("ggx", "type = \"ggx\"\nroughness = 0.3"),
        (
            "ggx-aniso",
            "type = \"ggx\"\nroughness_u = 0.05\nroughness_v = 0.5\ntangent = [0.0, 1.0, 0.0]",
        ),
        ("beckmann", "type = \"beckmann\"\nroughness = 0.5"),
        ("gold", "type = \"ggx\"\nroughness = 0.2\nmetal = \"Au\""),
        ("mirror", "type = \"conductor\""),
        ("silver-mirror", "type = \"conductor\"\nmetal = \"Ag\""),
    ];
    for (name, params) in models {
        let src = SPHERE_SCENE
            .replace(
                "type = \"diffuse\"\nreflectance = [REFL, REFL, REFL]",
                params,
            )
            .replace("spp = 4", "spp = 16");
        let img = render_with(&scene(&src), 2);
        let mut sphere_sum = 0.0;
        let mut n = 0;
        for p in &img.rgb {
            for &v in p {
                assert!(v <= 1.0 + 1e-6, "{name}: pixel {p:?} above the sky");
            }
            if p[0] < 0.999 || p[2] < 0.999 {
                sphere_sum += p[1] as f64;
                n += 1;
            }
        }
        if name == "mirror" {
            assert!(
                img.rgb.iter().flatten().all(|&v| (v - 1.0).abs() < 1e-6),
                "F = 1 mirror reflects the sky exactly"
            );
        } else {
            // Something visibly darker than the sky, but not black.
            assert!(n > 100, "{name}: the sphere must show");
            let mean = sphere_sum / n as f64;
            assert!(mean > 0.3 && mean < 1.0, "{name}: mean {mean}");
        }
    }
}

#[test]
fn clear_glass_sphere_under_a_white_sky_renders_the_sky() {
    // Every path reflects or refracts with weight 1 (radiance compressed
    // by 1/eta^2 on the way in, expanded on the way out) and escapes.
    let src = SPHERE_SCENE
        .replace(
            "type = \"diffuse\"\nreflectance = [REFL, REFL, REFL]",
            "type = \"dielectric\"\nior = 1.5",
        )
        .replace("max_depth = 16", "max_depth = 64");
    let img = render_with(&scene(&src), 2);
    for p in &img.rgb {
        for &v in p {
            assert!((v - 1.0).abs() < 1e-6, "{p:?}");
        }
    }
}

#[test]
fn lobe_models_under_a_white_sky_do_not_create_energy() {
    // Phong-type sample weights can exceed 1 individually ((n+2)/(n+1) cos
    // for a pure Phong lobe), so the bound is statistical: the mean over
    // the sphere stays at or below the sky within 4 standard errors.
    let models = [
        ("phong", "type = \"phong\"\nexponent = 30\nspecular = [1.0, 1.0, 1.0]"),
        ("phong+diffuse", "type = \"phong\"\nexponent = 5\nspecular = [0.5, 0.5, 0.5]\nreflectance = [0.5, 0.5, 0.5]"),
        ("blinn_phong", "type = \"blinn_phong\"\nexponent = 80\nspecular = [1.0, 1.0, 1.0]"),
        ("plastic", "type = \"plastic\"\nreflectance = [1.0, 1.0, 1.0]"),
        ("rough plastic", "type = \"plastic\"\nreflectance = [1.0, 1.0, 1.0]\nroughness = 0.3"),
        ("ward", "type = \"ward\"\nalpha_u = 0.1\nalpha_v = 0.4\nspecular = [0.7, 0.7, 0.7]\nreflectance = [0.3, 0.3, 0.3]\ntangent = [0.0, 1.0, 0.0]"),
        ("heidrich_seidel", "type = \"heidrich_seidel\"\nexponent = 30\nspecular = [0.6, 0.6, 0.6]\nisotropic = [0.2, 0.2, 0.2]\nreflectance = [0.2, 0.2, 0.2]\ntangent = [0.0, 1.0, 0.0]"),
        ("mix", "type = \"mix\"\ncomponents = [{ material = \"white\", weight = 0.5 }, { material = \"shiny\", weight = 0.5 }]"),
        ("gaussian", "type = \"gaussian\"\nm = 0.3\nspecular = [0.6, 0.6, 0.6]\nreflectance = [0.4, 0.4, 0.4]"),
        ("cook_torrance", "type = \"cook_torrance\"\nroughness = 0.3\nreflectance = [1.0, 1.0, 1.0]\nior = 1.5"),
        ("cook_torrance_smith", "type = \"cook_torrance\"\nroughness = 0.4\ndistribution = \"ggx\"\nmasking = \"smith\"\nschlick = [1.0, 1.0, 1.0]"),
    ];
    for (name, params) in models {
        // The mix refers to materials defined before it.
        let src = SPHERE_SCENE
            .replace(
                "type = \"diffuse\"\nreflectance = [REFL, REFL, REFL]",
                params,
            )
            .replace("spp = 4", "spp = 64")
            .replace(
                "[[material]]\nname = \"grey\"",
                "[[material]]\nname = \"white\"\ntype = \"diffuse\"\nreflectance = [1.0, 1.0, 1.0]\n\n[[material]]\nname = \"shiny\"\ntype = \"ggx\"\nroughness = 0.2\n\n[[material]]\nname = \"grey\"",
            );
        let img = render_with(&scene(&src), 2);
        let vals: Vec<f64> = img
            .rgb
            .iter()
            .filter(|p| p[1] < 0.999 || p[1] > 1.001)
            .map(|p| p[1] as f64)
            .collect();
        let n = vals.len() as f64;
        let mean = vals.iter().sum::<f64>() / n;
        let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        assert!(n > 100.0, "{name}");
        assert!(
            mean <= 1.0 + 4.0 * (var / n).sqrt(),
            "{name}: sphere mean {mean}"
        );
        assert!(img.rgb.iter().flatten().all(|v| v.is_finite()));
    }
}

fn channel_means(img: &Image) -> ([f64; 3], [f64; 3]) {
    // Sphere pixels differ from the white background.
    let px: Vec<&[f32; 3]> = img
        .rgb
        .iter()
        .filter(|p| p.iter().any(|v| (v - 1.0).abs() > 1e-6))
        .collect();
    let n = px.len() as f64;
    let mut mean = [0.0; 3];
    let mut se = [0.0; 3];
    for c in 0..3 {
        let m = px.iter().map(|p| p[c] as f64).sum::<f64>() / n;
        let v = px.iter().map(|p| (p[c] as f64 - m).powi(2)).sum::<f64>() / n;
        mean[c] = m;
        se[c] = (v / n).sqrt();
    }
    (mean, se)
}

#[test]
fn random_walk_medium_conserves_energy_under_a_white_sky() {
    // A non-absorbing medium behind a glass boundary: every photon that
    // enters leaves again, so the expected radiance is exactly the sky's,
    // per channel (spectral MIS over the channels adds noise only).
    let src = SPHERE_SCENE
        .replace(
            "type = \"diffuse\"\nreflectance = [REFL, REFL, REFL]",
            "type = \"subsurface\"\nsigma_s = [2.0, 1.0, 0.5]\nsigma_a = [0.0, 0.0, 0.0]\ng = 0.3\nscale = 1.0\nmode = \"random_walk\"",
        )
        .replace("spp = 4", "spp = 64");
    let img = render_with(&scene(&src), 2);
    let (mean, se) = channel_means(&img);
    eprintln!("non-absorbing: {mean:?} +- {se:?}");
    for c in 0..3 {
        assert!(
            (mean[c] - 1.0).abs() < 4.0 * se[c] + 1e-3,
            "channel {c}: {} +- {}",
            mean[c],
            se[c]
        );
    }
    assert!(img.rgb.iter().flatten().all(|v| v.is_finite()));

    // With absorption every channel loses energy, most where it absorbs most.
    let src = src.replace("sigma_a = [0.0, 0.0, 0.0]", "sigma_a = [0.05, 0.5, 2.0]");
    let img = render_with(&scene(&src), 2);
    let (mean, se) = channel_means(&img);
    eprintln!("absorbing: {mean:?} +- {se:?}");
    for c in 0..3 {
        assert!(mean[c] < 1.0 - 4.0 * se[c], "channel {c}: {}", mean[c]);
    }
    assert!(mean[0] > mean[1] && mean[1] > mean[2], "{mean:?}");
}

#[test]
fn random_walk_medium_on_a_non_convex_object_conserves_energy() {
    // The perturbed furnace object in a non-absorbing medium: the mirror
    // reflection of its boundary often meets the object itself, so this
    // checks that the environment seen in the mirror (added with its
    // Fresnel weight at every hit) is neither lost nor counted twice when
    // the sampled reflection continues. Every photon leaves: mean 1.
    let src = FURNACE
        .replace(
            "ENV",
            "[environment]\ntype = \"constant\"\nradiance = [1.0, 1.0, 1.0]",
        )
        .replace(
            "type = \"diffuse\"\nreflectance = [1.0, 1.0, 1.0]",
            "type = \"subsurface\"\nsigma_s = [3.0, 3.0, 3.0]\nsigma_a = [0.0, 0.0, 0.0]\nscale = 1.0\nmode = \"random_walk\"",
        )
        .replace("spp = 8", "spp = 32");
    let img = render_with(&scene(&src), 2);
    let (mean, se) = channel_means(&img);
    eprintln!("non-convex, non-absorbing: {mean:?} +- {se:?}");
    for c in 0..3 {
        assert!(
            (mean[c] - 1.0).abs() < 4.0 * se[c] + 2e-3,
            "channel {c}: {} +- {}",
            mean[c],
            se[c]
        );
    }
}

fn medium_scene(params: &str, spp: u32) -> Image {
    let src = SPHERE_SCENE
        .replace(
            "type = \"diffuse\"\nreflectance = [REFL, REFL, REFL]",
            params,
        )
        .replace("spp = 4", &format!("spp = {spp}"))
        .replace("max_depth = 16", "max_depth = 32");
    render_with(&scene(&src), 2)
}

/// The camera inside a non-absorbing random-walk medium (a sphere of
/// index `n` around it) under a white sky of radiance 1: the radiance of
/// equilibrium inside a medium of index `n` is `n^2` times that outside,
/// so every channel averages `n^2` (closed form). More: the medium loses
/// nothing and every path leaves the convex sphere to the sky, so each
/// path's spectral MIS weights equal its channels' density ratios, which
/// sum to 3: every path brings `3 n^2` over its channels, and every
/// pixel's channels sum to `3 n^2` to rounding. With absorption, every
/// channel loses energy, most where it absorbs most. Paths used to start
/// outside every medium and saw the sky through empty space (mean 1 per
/// channel at any `n`).
#[test]
fn a_camera_inside_a_random_walk_medium_sees_it() {
    let src = |ior: f64, sigma_a: &str| {
        test_scene(
            "medium-around-camera.toml",
            &[
                ("ior = 1.5", &format!("ior = {ior}")),
                ("sigma_a = [0.0, 0.0, 0.0]", &format!("sigma_a = {sigma_a}")),
            ],
        )
    };
    for ior in [1.0, 1.5] {
        let s = scene(&src(ior, "[0.0, 0.0, 0.0]"));
        assert!(s.medium_at(s.camera.position).is_some());
        let img = render_with(&s, 2);
        let want = ior * ior;
        for p in &img.rgb {
            let sum = p.iter().map(|&v| v as f64).sum::<f64>();
            assert!((sum - 3.0 * want).abs() < 1e-5 * want, "n = {ior}: {p:?}");
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
            eprintln!("n = {ior}, channel {c}: {m} +- {se}");
            assert!(
                (m - want).abs() < 4.0 * se,
                "n = {ior}, channel {c}: {m} +- {se}"
            );
        }
    }
    let img = render_with(&scene(&src(1.5, "[0.05, 0.5, 2.0]")), 2);
    let n = img.rgb.len() as f64;
    let mean: Vec<f64> = (0..3)
        .map(|c| img.rgb.iter().map(|p| p[c] as f64).sum::<f64>() / n)
        .collect();
    eprintln!("absorbing: {mean:?}");
    assert!(
        mean[0] < 2.2 && mean[0] > mean[1] && mean[1] > mean[2],
        "{mean:?}"
    );
    // Outside the sphere the camera starts in no medium.
    let outside =
        scene(&src(1.5, "[0.0, 0.0, 0.0]").replace("[0.1, -0.2, 0.3]", "[0.1, -0.2, 3.0]"));
    assert!(outside.medium_at(outside.camera.position).is_none());
}

/// Media nest: the camera inside the sphere of index 1.5 of
/// `medium-around-camera.toml`, itself inside a scattering sphere of
/// water (index 1.33, radius 3, listed first), under a white sky, starts
/// in both (`Scene::media_at`, outermost first: the water's box is the
/// larger) and sees the equilibrium radiance of the inner medium, `1.5^2`:
/// each path brings exactly `3 n^2` over its channels, as without the water
/// (closed form; the eta scalings of the two boundaries telescope). A
/// camera outside the inner sphere, in the water, sees `1.33^2`.
#[test]
fn media_nest() {
    let nested = test_scene("nested-media.toml", &[]);
    for (camera, n) in [("[0.1, -0.2, 0.3]", 1.5), ("[0.1, -0.2, 2.0]", 1.33)] {
        let s = scene(&nested.replace("[0.1, -0.2, 0.3]", camera));
        let media = s.media_at(s.camera.position);
        let ids: Vec<usize> = media.iter().map(|(i, _)| *i).collect();
        assert_eq!(ids, if n == 1.5 { vec![0, 1] } else { vec![0] });
        let img = render_with(&s, 2);
        let want = 3.0 * n * n;
        for p in &img.rgb {
            let sum = p.iter().map(|&v| v as f64).sum::<f64>();
            assert!(
                (sum - want).abs() < 1e-5 * want,
                "camera at {camera}: {p:?}"
            );
        }
    }
}

/// Media nest four deep (examples/tests/deep-media.toml: spheres of index
/// 1.9 in 1.7 in 1.5 in water of 1.33, all scattering without absorption,
/// under a white sky): the camera in the innermost sees `1.9^2`, every
/// path bringing exactly `3 n^2` over its channels, and from the sphere
/// of 1.7, `1.7^2` (closed form, as [`media_nest`]). And eight deep, as
/// deep as a path follows ([`MAX_NESTED_MEDIA`]; deeper-media.toml
/// appended: four more, of 1.6, 1.4, 1.2 and 1.1 inward): `1.1^2`, and
/// from the seventh, `1.2^2`.
#[test]
fn media_nest_four_and_eight_deep() {
    let deep = test_scene("deep-media.toml", &[]);
    let deeper = deep.clone() + &test_scene("deeper-media.toml", &[]);
    for (text, camera, n, depth) in [
        (&deep, "[0.5, 0.0, 0.3]", 1.9, 4),
        (&deep, "[0.1, 0.0, 0.3]", 1.7, 3),
        (&deeper, "[0.5, 0.0, 0.3]", 1.1, MAX_NESTED_MEDIA),
        (&deeper, "[0.5, 0.0, 0.25]", 1.2, 7),
    ] {
        let s = scene(&text.replacen("[0.5, 0.0, 0.3]", camera, 1));
        assert_eq!(s.media_at(s.camera.position).len(), depth);
        let want = 3.0 * n * n;
        for p in &render_with(&s, 2).rgb {
            let sum = p.iter().map(|&v| v as f64).sum::<f64>();
            assert!(
                (sum - want).abs() < 1e-5 * want,
                "camera at {camera}, {depth} deep: {p:?}"
            );
        }
    }
}

/// A grey medium (fog: the same coefficients in every channel) carries
/// all three channels on every path instead of choosing one: with the
/// camera inside a non-absorbing grey sphere of index 1.5 under a white
/// sky, every pixel shows exactly `1.5^2` in each channel (closed form;
/// choosing a channel, a pixel's three values only summed to `3 n^2`).
#[test]
fn grey_media_carry_every_channel() {
    let s = scene(&test_scene(
        "medium-around-camera.toml",
        &[("sigma_s = [2.0, 1.0, 0.5]", "sigma_s = [1.0, 1.0, 1.0]")],
    ));
    for p in &render_with(&s, 2).rgb {
        for &v in p {
            assert!((v as f64 - 2.25).abs() < 1e-5, "{p:?}");
        }
    }
}

/// The text of `examples/tests/<name>` with each `(from, to)` replaced.
fn test_scene(name: &str, edits: &[(&str, &str)]) -> String {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/tests/");
    let mut src = std::fs::read_to_string(format!("{dir}{name}")).unwrap();
    for (from, to) in edits {
        assert!(src.contains(from), "{name}: no {from}");
        src = src.replace(from, to);
    }
    src
}

/// `examples/tests/lamp-in-medium.toml`: a point light inside a large
/// sphere of medium (index 1: its boundary is invisible; radius 50) under
/// a black sky, `sigma_s`, `sigma_a` per unit in every channel, with or
/// without its diffuse floor (reflectance 0.8).
fn lamp_in_medium(sigma_s: f64, sigma_a: f64, floor: bool) -> Scene {
    let mut src = test_scene(
        "lamp-in-medium.toml",
        &[
            (
                "sigma_s = [0.3, 0.3, 0.3]",
                &format!("sigma_s = [{sigma_s}, {sigma_s}, {sigma_s}]"),
            ),
            (
                "sigma_a = [0.2, 0.2, 0.2]",
                &format!("sigma_a = [{sigma_a}, {sigma_a}, {sigma_a}]"),
            ),
        ],
    );
    if !floor {
        src.truncate(src.find("\n# floor\n").unwrap());
    }
    scene(&src)
}

/// `f(ray)` per pixel, the mean at 4 x 4 stratified points (the renderer
/// jitters its samples over the pixel likewise).
fn film_of(s: &Scene, f: impl Fn(&isolux_core::Ray) -> f64) -> Vec<f64> {
    let rig = s.camera.rig(s.film.width, s.film.height).unwrap();
    let mut out = Vec::new();
    for y in 0..s.film.height {
        for x in 0..s.film.width {
            let mut sum = 0.0;
            for k in 0..16 {
                let fx = x as f64 + (k % 4) as f64 / 4.0 + 0.125;
                let fy = y as f64 + (k / 4) as f64 / 4.0 + 0.125;
                sum += f(&rig.ray(fx, fy));
            }
            out.push(sum / 16.0);
        }
    }
    out
}

/// The means of a grey render and of a reference per pixel, and the
/// standard error of the mean of their difference (the render's noise).
fn against(img: &Image, want: &[f64]) -> (f64, f64, f64) {
    let d: Vec<f64> = img
        .rgb
        .iter()
        .zip(want)
        .map(|(p, w)| p.iter().map(|&c| c as f64).sum::<f64>() / 3.0 - w)
        .collect();
    let n = d.len() as f64;
    let md = d.iter().sum::<f64>() / n;
    let se = (d.iter().map(|x| (x - md).powi(2)).sum::<f64>() / n / n).sqrt();
    let mw = want.iter().sum::<f64>() / n;
    (mw + md, mw, se)
}

/// Unpolarized Fresnel reflectance of a dielectric interface, light
/// arriving at cosine `c` from the side of index `n1` onto index `n2`
/// (written out here again, independently of `isolux_materials`).
fn fresnel(c: f64, n1: f64, n2: f64) -> f64 {
    let s2 = (n1 / n2).powi(2) * (1.0 - c * c);
    if s2 >= 1.0 {
        return 1.0;
    }
    let ct = (1.0 - s2).sqrt();
    let rs = (n1 * c - n2 * ct) / (n1 * c + n2 * ct);
    let rp = (n2 * c - n1 * ct) / (n2 * c + n1 * ct);
    0.5 * (rs * rs + rp * rp)
}

/// A surface under water meets water, not vacuum: the camera in a
/// half-space of water (index 1.33) sees a black plastic wall (coat 1.5)
/// face on, under a white sky (`examples/tests/plastic-under-water.toml`).
/// Along a camera ray at cosine `c`, light from the sky enters the water
/// (transmittance `T` of the surface, radiance times `n^2`), bounces
/// between the coat (`R_p`, Fresnel of 1.5 against 1.33) and the surface
/// (`R_w`, from inside), the two planes parallel: `R_p T n^2 e^(-5 a / c)
/// / (1 - R_w R_p e^(-6 a / c))` for the water's absorption `a`. The film
/// agrees within four standard errors; with the coat against vacuum (as
/// before 2026-12-04) the film was 11 times brighter.
#[test]
fn a_surface_under_water_reflects_as_against_water() {
    let s = scene(&test_scene("plastic-under-water.toml", &[]));
    let (n, coat, a) = (1.33, 1.5, 1e-4);
    let want = film_of(&s, |ray| {
        let c = -ray.dir.x;
        let rp = fresnel(c, n, coat);
        let rw = fresnel(c, n, 1.0);
        rp * (1.0 - rw) * n * n * (-5.0 * a / c).exp() / (1.0 - rw * rp * (-6.0 * a / c).exp())
    });
    let (got, want, se) = against(&render_with(&s, 2), &want);
    eprintln!("plastic under water: render {got} +- {se}, closed form {want}");
    let in_air = fresnel(1.0, 1.0, coat) * (1.0 - fresnel(1.0, n, 1.0)) * n * n;
    assert!(
        want > 0.005 && want < in_air / 8.0,
        "{want} against {in_air}"
    );
    assert!(
        (got - want).abs() < 4.0 * se + 1e-3 * want,
        "render {got} +- {se}, closed form {want}"
    );
}

/// A point light inside an absorbing medium lights a diffuse floor in it
/// through the medium: each pixel's expected value is `exp(-sigma t) rho /
/// pi I cos / r^2 exp(-sigma r)` (closed form; `t` the camera ray's length
/// to the floor, `r` the light's distance, `max_depth` 1, no scattering).
/// The film's mean agrees within four standard errors; without the
/// light's attenuation it came out `exp(sigma r)` brighter.
#[test]
fn a_lamp_in_an_absorbing_medium_lights_a_floor_through_it() {
    // The file's floor reflectance.
    let (sigma, rho) = (0.6, 0.8);
    let s = lamp_in_medium(0.0, sigma, true);
    let light = s.lights[0].position;
    let want = film_of(&s, |ray| {
        if ray.dir.y >= 0.0 {
            return 0.0;
        }
        let t = (-1.0 - ray.origin.y) / ray.dir.y;
        let p = ray.at(t);
        if p.x.abs() > 30.0 || p.z.abs() > 30.0 {
            return 0.0;
        }
        let d = light - p;
        let r = d.length();
        let cos = (d.y / r).max(0.0);
        (-sigma * t).exp() * rho / std::f64::consts::PI * 20.0 * cos / (r * r) * (-sigma * r).exp()
    });
    let (got, want, se) = against(&render_with(&s, 2), &want);
    eprintln!("lamp in absorbing medium: render {got} +- {se}, closed form {want}");
    assert!(want > 0.02, "{want}");
    assert!(
        (got - want).abs() < 4.0 * se + 1e-3 * want,
        "render {got} +- {se}, closed form {want}"
    );
}

/// A point light above a half-space of absorbing water lights a diffuse
/// floor under it through the flat surface, by refraction
/// (`examples/tests/sun-above-water.toml`, the camera under water, black
/// sky, `max_depth` 1): each pixel's expected value is `exp(-sigma t) rho
/// / pi E`, with the floor's irradiance `E = I T(theta_1) G cos theta_2
/// exp(-sigma l_2)` for the path from the light that crosses the surface
/// at the point Fermat's principle picks (least optical length `n_1 l_1 +
/// n_2 l_2`, found here by golden-section search) and `G` the spreading
/// of the light's cone, `sin theta_1 / (R cos theta_2 dR/dtheta_1)`,
/// with the landing radius `R(theta_1)` traced through Snell's law and
/// differentiated numerically. The film's mean agrees within four
/// standard errors; before 2026-12-04 a point light outside a medium
/// reached nothing inside it, and the film was black.
#[test]
fn a_lamp_above_water_lights_the_floor_through_the_surface() {
    let (n1, n2, sigma, rho, depth) = (1.0f64, 1.33f64, 0.3, 0.8, 2.0);
    let s = scene(&test_scene("sun-above-water.toml", &[]));
    let light = s.lights[0].position;
    let want = film_of(&s, |ray| {
        let t = (-depth - ray.origin.y) / ray.dir.y;
        let q = ray.at(t);
        if !(t > 0.0) || q.x.abs() > 30.0 || q.z.abs() > 30.0 {
            return 0.0;
        }
        let (e, cos2) = refracted_reference(light, q, n1, n2, sigma);
        (-sigma * t).exp() * rho / std::f64::consts::PI * e * cos2
    });
    let (got, want, se) = against(&render_with(&s, 2), &want);
    eprintln!("lamp above water: render {got} +- {se}, closed form {want}");
    assert!(want > 0.01, "{want}");
    assert!(
        (got - want).abs() < 4.0 * se + 2e-3 * want,
        "render {got} +- {se}, closed form {want}"
    );
}

/// The irradiance at `q` under the water of `sun-above-water.toml` (the
/// half-space `y < 0` of index `n2` and extinction `sigma`) from its
/// light of intensity 20 at `light` above it (index `n1`), normal to the
/// refracted ray, and that ray's cosine with the vertical: `I T(theta_1)
/// G exp(-sigma l_2)`, with the crossing point Fermat's principle picks
/// (least optical length `n_1 l_1 + n_2 l_2`, by golden-section search)
/// and `G = sin theta_1 / (R cos theta_2 dR/dtheta_1)`, the landing radius
/// `R(theta_1)` traced through Snell's law and differentiated
/// numerically.
fn refracted_reference(light: DVec3, q: DVec3, n1: f64, n2: f64, sigma: f64) -> (f64, f64) {
    let (h1, depth) = (light.y, -q.y);
    let d = DVec3::new(light.x - q.x, 0.0, light.z - q.z).length();
    let optical =
        |x: f64| n1 * (x * x + h1 * h1).sqrt() + n2 * ((d - x).powi(2) + depth * depth).sqrt();
    let (mut a, mut b) = (0.0, d);
    let r = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..100 {
        let (c1, c2) = (b - r * (b - a), a + r * (b - a));
        if optical(c1) < optical(c2) {
            b = c2;
        } else {
            a = c1;
        }
    }
    let x = 0.5 * (a + b);
    let (l1, l2) = (
        (x * x + h1 * h1).sqrt(),
        ((d - x).powi(2) + depth * depth).sqrt(),
    );
    let (th1, cos2) = ((x / l1).asin(), depth / l2);
    let landing = |a: f64| h1 * a.tan() + depth * (n1 * a.sin() / n2).asin().tan();
    let g = if d < 1e-9 {
        1.0 / (h1 + depth * n1 / n2).powi(2)
    } else {
        let e = 1e-6;
        let dr = (landing(th1 + e) - landing(th1 - e)) / (2.0 * e);
        th1.sin() / (landing(th1) * cos2 * dr)
    };
    let tr = 1.0 - fresnel(th1.cos(), n1, n2);
    (20.0 * tr * g * (-sigma * l2).exp(), cos2)
}

/// The lamp above water lights the water itself at its scattering events
/// through the surface: with the floor cut from
/// `examples/tests/sun-above-water.toml` and a little isotropic
/// scattering (albedo 1/30), along each camera ray single scattering
/// gives `int sigma_s exp(-sigma_t t) p I T G exp(-sigma_t l_2) dt` (the
/// crossing found by Fermat's principle, `G` by the traced landing radius,
/// as for the floor above; Simpson's rule in `t`). The film's mean lies
/// between the single scattering and 4% above it for the higher orders.
#[test]
fn a_lamp_above_water_lights_the_water_through_the_surface() {
    let (n1, n2, ss, sa) = (1.0f64, 1.33f64, 0.01, 0.29);
    let st = ss + sa;
    let mut src = test_scene(
        "sun-above-water.toml",
        &[
            ("sigma_s = [0.0, 0.0, 0.0]", "sigma_s = [0.01, 0.01, 0.01]"),
            ("sigma_a = [0.3, 0.3, 0.3]", "sigma_a = [0.29, 0.29, 0.29]"),
            (
                "width = 48\nheight = 36\nspp = 16",
                "width = 16\nheight = 12\nspp = 256",
            ),
        ],
    );
    src.truncate(src.find("\n# floor\n").unwrap());
    let s = scene(&src);
    let light = s.lights[0].position;
    let want = film_of(&s, |ray| {
        let irradiance = |q: DVec3| refracted_reference(light, q, n1, n2, st).0;
        let (n, t_end) = (600, 60.0);
        let h = t_end / n as f64;
        let f =
            |t: f64| ss * (-st * t).exp() / (4.0 * std::f64::consts::PI) * irradiance(ray.at(t));
        let mut sum = f(0.0) + f(t_end);
        for k in 1..n {
            sum += f(k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        sum * h / 3.0
    });
    let (got, want, se) = against(&render_with(&s, 2), &want);
    eprintln!("lamp above scattering water: render {got} +- {se}, single scattering {want}");
    assert!(want > 1e-3, "{want}");
    assert!(
        got > want - 4.0 * se && got < 1.04 * want + 4.0 * se,
        "render {got} +- {se}, single scattering {want}"
    );
}

/// Only relative indices of refraction matter: a scene wholly inside
/// clear water of index `n` (camera, lamp and objects in a sphere of
/// radius 50 under a black sky) renders as the same scene in vacuum with
/// every index divided by `n` (the water's surface too, a glass shell of
/// index `1 / n`): glass, a plastic coat, a gold GGX (`eta`,
/// `k`), a dipole marble floor and a random-walk jelly, which under water
/// is a medium inside a medium. Image means agree within four standard
/// errors of their difference (separate seeds). With the surfaces'
/// indices taken against vacuum (before 2026-12-04, without the jelly)
/// the image in water came out 15% darker (0.1072 against 0.1266), and
/// 17% with the marble's alone (0.1051).
#[test]
fn only_relative_indices_of_refraction_matter() {
    let scene_in = |n: f64, seed: u64| {
        let mut src = format!(
            r#"
[camera]
position = [0.0, 0.4, 2.5]
look_at = [0.0, -0.3, 0.0]
fov_y = 50.0
[film]
width = 48
height = 36
spp = 256
[integrator]
max_depth = 6
seed = {seed}
[environment]
type = "constant"
radiance = [0.0, 0.0, 0.0]
[[light]]
type = "point"
position = [0.8, 1.2, 0.9]
intensity = [12.0, 12.0, 12.0]
[[material]]
name = "glass"
type = "dielectric"
ior = {glass}
[[material]]
name = "coat"
type = "plastic"
ior = {coat}
roughness = 0.2
reflectance = [0.2, 0.5, 0.3]
[[material]]
name = "gold"
type = "ggx"
roughness = 0.25
eta = [{er}, {eg}, {eb}]
k = [{kr}, {kg}, {kb}]
[[material]]
name = "marble"
type = "subsurface"
sigma_s = [60.0, 70.0, 80.0]
sigma_a = [0.5, 1.0, 3.0]
ior = {marble}
scale = 1.0
[[material]]
name = "jelly"
type = "subsurface"
sigma_s = [3.0, 4.0, 5.0]
sigma_a = [0.5, 0.3, 0.2]
g = 0.3
ior = {jelly}
scale = 1.0
mode = "random_walk"
[[object]]
material = "jelly"
base = {{ type = "sphere", center = [0.15, 0.0, 0.3], radius = 0.3 }}
[[object]]
material = "marble"
base = {{ type = "plane", point = [0.0, -1.0, 0.0], normal = [0.0, 1.0, 0.0] }}
bounds = {{ min = [-30.0, -2.0, -30.0], max = [30.0, 0.0, 30.0] }}
[[object]]
material = "glass"
base = {{ type = "sphere", center = [-0.6, -0.6, 0.0], radius = 0.4 }}
[[object]]
material = "coat"
base = {{ type = "sphere", center = [0.1, -0.65, -0.6], radius = 0.35 }}
[[object]]
material = "gold"
base = {{ type = "sphere", center = [0.7, -0.7, 0.1], radius = 0.3 }}
"#,
            glass = 1.5 * n,
            coat = 1.6 * n,
            marble = 1.3 * n,
            jelly = 1.4 * n,
            er = 0.18 * n,
            eg = 0.42 * n,
            eb = 1.37 * n,
            kr = 3.42 * n,
            kg = 2.35 * n,
            kb = 1.77 * n,
        );
        if n == 1.0 {
            // The water's surface seen from vacuum scaled by 1 / 1.33: a
            // shell of index 1 / 1.33 against the sky (its internal
            // reflection sends about 2% of the light back).
            src += &format!(
                r#"
[[material]]
name = "shell"
type = "dielectric"
ior = {}
[[object]]
material = "shell"
base = {{ type = "sphere", center = [0.0, 0.0, 0.0], radius = 50.0 }}
"#,
                1.0 / 1.33
            );
        } else {
            // Clear water around it all (a medium must absorb or scatter:
            // 1e-6 per unit, 1e-5 along the longest paths).
            src += &format!(
                r#"
[[material]]
name = "water"
type = "subsurface"
sigma_s = [0.0, 0.0, 0.0]
sigma_a = [1e-6, 1e-6, 1e-6]
ior = {n}
scale = 1.0
mode = "random_walk"
[[object]]
material = "water"
base = {{ type = "sphere", center = [0.0, 0.0, 0.0], radius = 50.0 }}
"#
            );
        }
        scene(&src)
    };
    let a = render_with(&scene_in(1.0, 1), 2);
    let b = render_with(&scene_in(1.33, 2), 2);
    let grey = |p: &[f32; 3]| p.iter().map(|&c| c as f64).sum::<f64>() / 3.0;
    let want: Vec<f64> = a.rgb.iter().map(grey).collect();
    let (got, want, se) = against(&b, &want);
    eprintln!("in index 1: {want}; in index 1.33, indices times 1.33: {got} +- {se}");
    assert!(want > 0.05, "{want}");
    assert!(
        (got - want).abs() < 4.0 * se,
        "{want} against {got} +- {se}"
    );
}

/// A dipole medium inside a random-walk one (a marble floor under water)
/// sees the lamp in the water through the water, at its exit points
/// (single scattering) and at its entry points alike. The floor's
/// profile is short (mean free path 1/220, `sigma_tr` 115 per unit), so
/// each pixel's light is attenuated as a point's: the render in water of
/// absorption `sigma` equals the render in clear water times `exp(-sigma
/// (t + r))`, `t` the camera ray's length to the floor and `r` the
/// lamp's distance (to within 2%, the profile's spread). Before
/// 2026-12-04 the CPU left the lamp's light on a dipole unattenuated (the
/// image 3.8 times too bright); the GPU attenuated it already.
#[test]
fn a_dipole_floor_under_water_sees_the_lamp_through_the_water() {
    let sigma = 0.6;
    let floor = |sigma_a: f64| {
        test_scene(
            "lamp-in-medium.toml",
            &[
                ("sigma_s = [0.3, 0.3, 0.3]", "sigma_s = [0.0, 0.0, 0.0]"),
                (
                    "sigma_a = [0.2, 0.2, 0.2]",
                    &format!("sigma_a = [{sigma_a}, {sigma_a}, {sigma_a}]"),
                ),
                (
                    "type = \"diffuse\"\nreflectance = [0.8, 0.8, 0.8]",
                    "type = \"subsurface\"\nsigma_s = [200.0, 200.0, 200.0]\n\
                     sigma_a = [20.0, 20.0, 20.0]\ng = 0.0\nior = 1.3\nscale = 1.0",
                ),
                ("max_depth = 1", "max_depth = 2"),
            ],
        )
    };
    let clear = scene(&floor(1e-9));
    let absorbing = scene(&floor(sigma));
    let light = clear.lights[0].position;
    let w = film_of(&clear, |ray| {
        if ray.dir.y >= 0.0 {
            return 0.0;
        }
        let t = (-1.0 - ray.origin.y) / ray.dir.y;
        let r = (light - ray.at(t)).length();
        (-sigma * (t + r)).exp()
    });
    let img = render_with(&clear, 2);
    let want: Vec<f64> = img
        .rgb
        .iter()
        .zip(&w)
        .map(|(p, w)| p.iter().map(|&c| c as f64).sum::<f64>() / 3.0 * w)
        .collect();
    let (got, want, se) = against(&render_with(&absorbing, 2), &want);
    eprintln!("dipole floor under water: render {got} +- {se}, clear water attenuated {want}");
    assert!(want > 0.005, "{want}");
    assert!(
        (got - want).abs() < 4.0 * se + 0.02 * want,
        "render {got} +- {se}, clear water attenuated {want}"
    );
}

/// The length of the segment from `a` to `b` inside the sphere of centre
/// `c` and radius `r`.
fn chord(a: DVec3, b: DVec3, c: DVec3, r: f64) -> f64 {
    let d = b - a;
    let f = a - c;
    let (qa, qb, qc) = (d.dot(d), 2.0 * f.dot(d), f.dot(f) - r * r);
    let disc = qb * qb - 4.0 * qa * qc;
    if disc <= 0.0 {
        return 0.0;
    }
    let t0 = ((-qb - disc.sqrt()) / (2.0 * qa)).clamp(0.0, 1.0);
    let t1 = ((-qb + disc.sqrt()) / (2.0 * qa)).clamp(0.0, 1.0);
    (t1 - t0) * d.length()
}

/// A lamp outside a sphere of fog (index 1: its boundary bends no ray,
/// `examples/tests/fog-lamp-outside.toml`) lights the floor inside and
/// behind the fog through it: per pixel `exp(-sigma L_c) rho / pi I cos /
/// r^2 exp(-sigma L_l)`, `L_c` and `L_l` the lengths of the camera ray
/// and of the light's segment inside the fog (closed form, a pure
/// absorber, `max_depth` 1). Before 2026-12-04 the fog's boundary
/// occluded the lamp: the floor under and behind the fog was black.
#[test]
fn a_lamp_lights_through_fog_whose_boundary_bends_no_ray() {
    let s = scene(&test_scene("fog-lamp-outside.toml", &[]));
    let (sigma, rho, centre, radius) = (0.8, 0.8, DVec3::new(0.0, 0.4, 0.0), 1.2);
    let light = s.lights[0].position;
    let want = film_of(&s, |ray| {
        if ray.dir.y >= 0.0 {
            return 0.0;
        }
        let t = -ray.origin.y / ray.dir.y;
        let p = ray.at(t);
        if p.x.abs() > 8.0 || p.z.abs() > 8.0 {
            return 0.0;
        }
        let d = light - p;
        let r = d.length();
        let cos = (d.y / r).max(0.0);
        let lc = chord(ray.origin, p, centre, radius);
        let ll = chord(p, light, centre, radius);
        (-sigma * (lc + ll)).exp() * rho / std::f64::consts::PI * 20.0 * cos / (r * r)
    });
    let (got, want, se) = against(&render_with(&s, 2), &want);
    eprintln!("lamp through fog: render {got} +- {se}, closed form {want}");
    assert!(want > 0.05, "{want}");
    assert!(
        (got - want).abs() < 4.0 * se + 1e-3 * want,
        "render {got} +- {se}, closed form {want}"
    );
}

/// A lamp outside scattering fog (index 1) makes it glow: along a camera
/// ray, single scattering gives `int sigma_s exp(-sigma_t s) p(cos) I
/// exp(-sigma_t L_l) / r^2 dt` over the ray's stretch in the fog (`s` the
/// depth reached into it, `L_l` the light's path inside it; Simpson's
/// rule). At albedo 0.05 the higher orders add a little, so the film's
/// mean lies between the single scattering and 5% above it (measured
/// 0.0010363 +- 0.0000032 against 0.0010028, +3.3%). Before 2026-12-04
/// the fog was black: its boundary occluded the lamp.
#[test]
fn a_lamp_outside_fog_makes_it_glow() {
    let (ss, sa, g) = (0.05, 0.95, 0.4);
    let mut src = test_scene(
        "fog-lamp-outside.toml",
        &[
            ("sigma_s = [0.0, 0.0, 0.0]", "sigma_s = [0.05, 0.05, 0.05]"),
            ("sigma_a = [0.8, 0.8, 0.8]", "sigma_a = [0.95, 0.95, 0.95]"),
            ("g = 0.0", "g = 0.4"),
            ("max_depth = 1", "max_depth = 8"),
            ("spp = 64", "spp = 256"),
        ],
    );
    src.truncate(src.find("\n# floor\n").unwrap());
    let s = scene(&src);
    let (centre, radius, st) = (DVec3::new(0.0, 0.4, 0.0), 1.2, ss + sa);
    let light = s.lights[0].position;
    let want = film_of(&s, |ray| {
        // The ray's stretch inside the sphere.
        let f = ray.origin - centre;
        let b = f.dot(ray.dir);
        let disc = b * b - (f.dot(f) - radius * radius);
        if disc <= 0.0 {
            return 0.0;
        }
        let (t0, t1) = (-b - disc.sqrt(), -b + disc.sqrt());
        let n = 200;
        let h = (t1 - t0) / n as f64;
        let fx = |t: f64| {
            let x = ray.at(t);
            let d = light - x;
            let r = d.length();
            let cos = (d / r).dot(ray.dir);
            let phase = (1.0 - g * g)
                / (4.0 * std::f64::consts::PI * (1.0 + g * g - 2.0 * g * cos).powf(1.5));
            ss * (-st * (t - t0)).exp()
                * phase
                * 20.0
                * (-st * chord(x, light, centre, radius)).exp()
                / (r * r)
        };
        let mut sum = fx(t0) + fx(t1);
        for k in 1..n {
            sum += fx(t0 + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        sum * h / 3.0
    });
    let (got, want, se) = against(&render_with(&s, 2), &want);
    eprintln!("fog glow: render {got} +- {se}, single scattering {want}");
    assert!(want > 5e-4, "{want}");
    assert!(
        got > want - 4.0 * se && got < want * 1.05 + 4.0 * se,
        "render {got} +- {se}, single scattering {want}"
    );
}

/// A point light inside a scattering medium glows: along a camera ray,
/// single scattering gives `int sigma_s exp(-sigma_t t) p(cos) I
/// exp(-sigma_t r) / r^2 dt` (Henyey-Greenstein `p`, integrated here by
/// Simpson's rule). At albedo 0.02 the higher orders add a few percent
/// (the scattering events per photon, `a / (1 - a)`, against `a` for
/// single scattering; measured at 1024 spp: +3.2%), so the film's mean
/// lies between the single scattering and 5% above it. Without
/// next-event estimation at the scattering events the image was black.
#[test]
fn a_lamp_in_a_scattering_medium_glows_by_single_scattering() {
    let (ss, sa, g) = (0.02, 0.98, 0.5);
    let s = lamp_in_medium(ss, sa, false);
    let want = single_scattered_glow(&s, ss, ss + sa, g);
    let (got, want, se) = against(&render_with(&s, 2), &want);
    eprintln!("lamp in scattering medium: render {got} +- {se}, single scattering {want}");
    assert!(want > 1e-3, "{want}");
    assert!(
        got > want - 4.0 * se && got < 1.03 * want + 4.0 * se,
        "render {got} +- {se}, single scattering {want}"
    );
}

/// Per pixel of `s` (a lamp of intensity 20 in a medium around the camera,
/// `lamp_in_medium` without floor), the lamp's light scattered once into
/// the camera: `int sigma_s exp(-sigma_t t) p(cos) I exp(-sigma_t r) / r^2
/// dt` along each camera ray to the medium's boundary (Henyey-Greenstein
/// `p`). Simpson's rule in the angle `theta` under which the lamp sees
/// the ray's point (`t = delta + D tan theta`, `dt / r^2 = dtheta / D`),
/// where the integrand is smooth however close the ray passes the lamp.
fn single_scattered_glow(s: &Scene, ss: f64, st: f64, g: f64) -> Vec<f64> {
    let light = s.lights[0].position;
    let hg = |c: f64| {
        let d = 1.0 + g * g - 2.0 * g * c;
        (1.0 - g * g) / (4.0 * std::f64::consts::PI * d * d.sqrt())
    };
    film_of(s, |ray| {
        let to = light - ray.origin;
        let delta = to.dot(ray.dir);
        let dd = (to - delta * ray.dir).length();
        // The sphere of radius 50 about the origin holds the camera.
        let (o, d) = (ray.origin, ray.dir);
        let b = o.dot(d);
        let t_end = -b + (b * b - o.length_squared() + 2500.0).sqrt();
        let (a, e) = ((-delta / dd).atan(), ((t_end - delta) / dd).atan());
        let n = 4000;
        let h = (e - a) / n as f64;
        let f = |theta: f64| {
            let t = delta + dd * theta.tan();
            let r = dd / theta.cos();
            let cos = (light - ray.at(t)).dot(ray.dir) / r;
            ss * (-st * t).exp() * hg(cos) * 20.0 * (-st * r).exp() / dd
        };
        let mut sum = f(a) + f(e);
        for k in 1..n {
            sum += f(a + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        sum * h / 3.0
    })
}

/// Equiangular sampling of a lamp's light along the flights through a
/// medium (`medium_light_sampling = "equiangular"`, the default) against
/// next-event estimation at the free flights' scattering points alone
/// (`"distance"`), on the lamp of `lamp-in-medium.toml` at albedo 0.02,
/// turned into view: both agree with the single-scattering integral (plus
/// at most 5% of higher orders), and the equiangular film's noise (the
/// standard error of its mean against the reference, over pixels) is at
/// least 2 times smaller at the same samples (measured: 3.5 times). The
/// distance strategy's `1 / d^2` at scattering points near the lamp gives
/// its estimate unbounded variance.
#[test]
fn equiangular_sampling_quiets_a_lamps_glow() {
    // The file's phase function; albedo 0.02.
    let (ss, sa, g) = (0.02, 0.98, 0.5);
    let mut src = test_scene(
        "lamp-in-medium.toml",
        &[
            (
                "sigma_s = [0.3, 0.3, 0.3]",
                &format!("sigma_s = [{ss}, {ss}, {ss}]"),
            ),
            (
                "sigma_a = [0.2, 0.2, 0.2]",
                &format!("sigma_a = [{sa}, {sa}, {sa}]"),
            ),
            ("look_at = [0.0, -0.6, 0.0]", "look_at = [0.6, 0.8, -0.4]"),
        ],
    );
    src.truncate(src.find("\n# floor\n").unwrap());
    let mut s = scene(&src);
    s.film.spp = 16;
    let want = single_scattered_glow(&s, ss, ss + sa, g);
    // The pixels whose rays pass within 0.05 of the lamp are left out: the
    // reference's 16 points per pixel do not resolve its `1 / D` there.
    let light = s.lights[0].position;
    let near = film_of(&s, |ray| {
        let to = light - ray.origin;
        (to - to.dot(ray.dir) * ray.dir).length()
    });
    let keep: Vec<usize> = (0..want.len()).filter(|&i| near[i] > 0.05).collect();
    assert!(keep.len() < want.len() && keep.len() + 10 > want.len());

    let mut noise = Vec::new();
    for strategy in [
        MediumLightSampling::Distance,
        MediumLightSampling::Equiangular,
    ] {
        s.integrator.medium_lights = strategy;
        let img = render_with(&s, 2);
        let d: Vec<f64> = keep
            .iter()
            .map(|&i| img.rgb[i].iter().map(|&c| c as f64).sum::<f64>() / 3.0 - want[i])
            .collect();
        let n = d.len() as f64;
        let md = d.iter().sum::<f64>() / n;
        let se = (d.iter().map(|x| (x - md).powi(2)).sum::<f64>() / n / n).sqrt();
        let want = keep.iter().map(|&i| want[i]).sum::<f64>() / n;
        let got = want + md;
        eprintln!("{strategy:?}: render {got} +- {se}, single scattering {want}");
        assert!(
            got > want - 4.0 * se && got < 1.05 * want + 4.0 * se,
            "{strategy:?}: render {got} +- {se}, single scattering {want}"
        );
        noise.push(se);
    }
    assert!(noise[1] * 2.0 < noise[0], "standard errors {noise:?}");
}

#[test]
fn dipole_mode_conserves_energy_and_agrees_with_the_random_walk() {
    // Non-absorbing medium, optically large (radius 0.8 = 16 mean free
    // paths): the dipole's total reflectance is 1, so under a white sky
    // the sphere renders 1 less the profile's power-law tail that lies
    // beyond the object: int_{r > 1.6} R_d 2 pi r dr ~ (z_r + z_v)/3.2 = 8%
    // (measured: 0.929).
    let white = |single: bool| {
        medium_scene(
            &format!("type = \"subsurface\"\nsigma_s_reduced = [20.0, 20.0, 20.0]\nsigma_a = [0.0, 0.0, 0.0]\nmode = \"dipole\"\nsingle_scattering = {single}"),
            16,
        )
    };
    let (mean, se) = channel_means(&white(false));
    eprintln!("dipole, no absorption: {mean:?} +- {se:?}");
    for c in 0..3 {
        assert!(
            mean[c] > 0.9 && mean[c] < 1.0 + 4.0 * se[c] + 1e-3,
            "channel {c}: {}",
            mean[c]
        );
    }
    // Jensen's S^(1) + S_d double-counts low orders: published, it
    // rendered 1.054. The single-scattering term is now scaled per channel
    // to keep the half-space's directional albedo within 1 at every angle
    // (subsurface::energy); without absorption that leaves none of it, so
    // the sphere renders as the dipole alone: measured 0.927 (0.929
    // without the term, a different random stream).
    let (mean1, se1) = channel_means(&white(true));
    eprintln!("dipole + single scattering, no absorption: {mean1:?} +- {se1:?}");
    for c in 0..3 {
        assert!(
            mean1[c] > 0.85 && mean1[c] < 1.0 + 4.0 * se1[c] + 1e-3,
            "channel {c}: {}",
            mean1[c]
        );
    }
    // Dipole (diffusion term alone: its known error is the diffusion
    // approximation's) against the exact random walk where the dipole's
    // assumptions hold: a half-space (a plane, the medium below, bounds far away) under
    // the white sky, reduced albedo 0.99 / 0.9 / 0.7 per channel; the
    // centre region seen from above.
    let half_space_with = |mode: &str, spp: u32, sigma_a: &str, single: bool| {
        let src = format!(
            r#"
[camera]
position = [0.0, 3.0, 0.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, -1.0]
fov_y = 20.0
[film]
width = 24
height = 24
spp = {spp}
[integrator]
max_depth = 32
[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]
[[material]]
name = "m"
type = "subsurface"
sigma_s_reduced = [20.0, 20.0, 20.0]
sigma_a = {sigma_a}
mode = "{mode}"
single_scattering = {single}
[[object]]
material = "m"
base = {{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }}
bounds = {{ min = [-40.0, -40.0, -40.0], max = [40.0, 1.0, 40.0] }}
"#
        );
        render_with(&scene(&src), 2)
    };
    let half_space =
        |mode: &str, spp: u32| half_space_with(mode, spp, "[0.202, 2.222, 8.571]", false);
    let means = |img: &Image| -> [f64; 3] {
        let n = img.rgb.len() as f64;
        [0, 1, 2].map(|c| img.rgb.iter().map(|p| p[c] as f64).sum::<f64>() / n)
    };
    let md = means(&half_space("dipole", 64));
    let mw = means(&half_space("random_walk", 256));
    eprintln!("half-space: dipole {md:?}, random walk {mw:?}");
    // Measured: -1.8%, +2.3%, +11.9%: the dipole's known error (it
    // overestimates more as the albedo falls; compare the half-space
    // random walk of the materials crate: -1.8% at 0.99, +2.8% at 0.9).
    let bounds = [(-0.06, 0.03), (-0.02, 0.08), (0.05, 0.20)];
    for c in 0..3 {
        let rel = md[c] / mw[c] - 1.0;
        eprintln!("channel {c}: dipole / walk - 1 = {:+.1}%", rel * 100.0);
        assert!(md[c] <= 1.0 && mw[c] <= 1.0);
        assert!(rel > bounds[c].0 && rel < bounds[c].1, "channel {c}: {rel}");
    }
    // The white furnace of the published sum in its own geometry: a
    // non-absorbing half-space under the white sky reflects everything
    // (the random walk's 1), so with single scattering on it must not
    // exceed 1. The published S^(1) + S_d rendered 1.108 here; with both
    // terms scaled (this code's first fix), 0.953; with the single
    // scattering alone scaled, 0.981 (the dipole alone: 0.987, its
    // profile beyond r_max ignored).
    let white_plane = means(&half_space_with("dipole", 16, "[0.0, 0.0, 0.0]", true));
    eprintln!("non-absorbing half-space, dipole + single scattering: {white_plane:?}");
    for (c, v) in white_plane.iter().enumerate() {
        assert!(*v > 0.9 && *v <= 1.005, "channel {c}: {v}");
    }
}

/// A sphere of radius 1 with a bump, resting in contact with a sphere of
/// radius 100, under a point light and a sky, everything moved `shift`
/// units along x (camera included).
fn moved_scene(shift: f64) -> Scene {
    let x = |v: f64| shift + v;
    let mut s = scene(&format!(
        r#"
[camera]
position = [{}, 1.0, 5.0]
look_at = [{}, 0.0, 0.0]
fov_y = 40.0
[film]
width = 64
height = 48
spp = 8
[[material]]
name = "m"
type = "diffuse"
reflectance = [0.7, 0.7, 0.7]
[[object]]
material = "m"
base = {{ type = "sphere", center = [{}, 0.0, 0.0], radius = 1.0 }}
[[object.perturbation]]
quadric = {{ type = "sphere", center = [{}, 0.3, 0.9], radius = 0.3 }}
factor = 300.0
[[object]]
material = "m"
base = {{ type = "sphere", center = [{}, -101.0, 0.0], radius = 100.0 }}
[environment]
type = "constant"
radiance = [0.2, 0.3, 0.4]
[[light]]
type = "point"
position = [{}, 4.0, 3.0]
intensity = [20.0, 20.0, 20.0]
"#,
        x(0.0),
        x(0.0),
        x(0.0),
        x(0.0),
        x(0.0),
        x(2.0)
    ));
    s.integrator.seed = 1;
    s
}

/// Mean absolute difference of two images, over every channel.
fn mean_difference(a: &Image, b: &Image) -> f64 {
    let sum: f64 = a
        .rgb
        .iter()
        .zip(&b.rgb)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs() as f64))
        .sum();
    sum / (3 * a.rgb.len()) as f64
}

/// Each object is intersected in its own frame, built about its base's
/// centre by the scene loader, and rays leave surfaces an offset that
/// does not grow with the distance from the world origin (`Hit::offset`;
/// docs/geometry.md, "Scene scale"). So a scene moved a million or a
/// billion units renders, with the same seed, as it does at the origin:
/// the same paths, up to rounding (measured: identical 8-bit blocks). The
/// bound is 2% of the difference between two seeds. With the offset
/// `1e-7 (1 + |p|)` of before, the contact shadow under the small sphere
/// turned black a million units out (40% of that difference); with world
/// quadrics, a billion units out the spheres were lost altogether.
#[test]
fn a_scene_far_from_the_origin_renders_as_at_the_origin() {
    let at_origin = render_with(&moved_scene(0.0), 2);
    let mut other = moved_scene(0.0);
    other.integrator.seed = 2;
    let noise = mean_difference(&at_origin, &render_with(&other, 2));
    assert!(noise > 0.0);
    for shift in [1e6, 1e9] {
        let moved = render_with(&moved_scene(shift), 2);
        let d = mean_difference(&at_origin, &moved);
        eprintln!("moved {shift:e}: {:.4} of the seeds' difference", d / noise);
        assert!(d <= 0.02 * noise, "moved {shift:e}: {d} vs {noise}");
    }
}

/// The test scene `examples/tests/NAME` with its lengths multiplied by
/// `10^exponent`, and its lights' intensities by `10^(2 exponent)`: the
/// file writes them, and nothing else, with the exponents `e+0` and `E+0`
/// (`small-units.toml` says how).
fn scaled_scene(name: &str, exponent: i32) -> Scene {
    let file = format!("{}/../../examples/tests/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(file).unwrap();
    assert!(text.matches("e+0").count() >= 4 && text.contains("E+0"));
    let text = text.replace("E+0", &format!("e{}", 2 * exponent));
    scene(&text.replace("e+0", &format!("e{exponent}")))
}

/// A scene renders the same in any unit: rays leave surfaces an offset
/// scaled by the length of the object's box, at most 1 (`Hit::offset`,
/// `Object::length`). Until 2026-12-06 its first term was `1e-7 (1 +
/// ..)`, a tenth of a unit's millionth whatever the scene's size: this
/// scene at 1e-8 differed from itself at 1 by 1.7 times the difference
/// between two seeds (the perturbed-sphere example scaled by 1e-8
/// rendered 11% darker), its contact shadows and the bump's shading lost;
/// now by 0.05 of it at 1e-4 to 1e-12 (the rounding of the glass's paths
/// sends a few of them another way).
#[test]
fn a_scene_in_small_units_renders_as_in_large_ones() {
    let unit = render_with(&scaled_scene("small-units.toml", 0), 2);
    let mut other = scaled_scene("small-units.toml", 0);
    other.integrator.seed = 2;
    let noise = mean_difference(&unit, &render_with(&other, 2));
    assert!(noise > 0.0);
    for exponent in [-4, -8, -12] {
        let small = render_with(&scaled_scene("small-units.toml", exponent), 2);
        let d = mean_difference(&unit, &small);
        eprintln!(
            "scaled 1e{exponent}: {:.4} of the seeds' difference",
            d / noise
        );
        assert!(d <= 0.25 * noise, "scaled 1e{exponent}: {d} vs {noise}");
    }
}

/// Light through glass to a point (`caustic`, `RefractedLights::Manifold`)
/// renders the same in any unit: the marble's caustic at 1, 0.1 and 1e-6.
/// Until 2026-12-06 the legs of a solved path were traced from the point
/// spawned off the surface along the direction from the unspawned one,
/// parallel to the leg and the spawn offset off it, so a grazing exit (the
/// caustic's rim) was met that offset over the cosine from the solved
/// crossing, beyond the check's tolerance: at 0.1, where the floor's
/// offset is relatively eight times larger than at 1 (its length is
/// capped at 1, `Object::length`), the rim lost 12% of its light: here
/// 0.57 of the difference between two seeds at 1e-1, now 1e-4 of it.
#[test]
fn caustics_render_the_same_in_any_unit() {
    let name = "marble-caustic.toml";
    let mut unit = scaled_scene(name, 0);
    unit.film.spp = 16;
    let unit_image = render_with(&unit, 2);
    let mut other = unit.clone();
    other.integrator.seed = 2;
    let noise = mean_difference(&unit_image, &render_with(&other, 2));
    assert!(noise > 0.0);
    for exponent in [-1, -6] {
        let mut small = scaled_scene(name, exponent);
        small.film.spp = 16;
        let d = mean_difference(&unit_image, &render_with(&small, 2));
        eprintln!(
            "caustic at 1e{exponent}: {:.4} of the seeds' difference",
            d / noise
        );
        assert!(d <= 0.25 * noise, "1e{exponent}: {d} vs {noise}");
    }
}

/// An unbounded base (a plane, a cylinder) is the same surface written
/// about any of its points along the directions that leave it unchanged,
/// so it renders the same, bit for bit: `shallows.toml`'s water plane
/// through `[1e7, 0, 0]` instead of the origin, and a pillar (an infinite
/// cylinder) about a point `1e7` up its axis. Until 2026-12-06 the object's
/// frame stayed at the written point, where the CPU's ray offset is a
/// whole unit, so walks into the water started too deep (the water
/// rendered 0.55 of its brightness, `gpu-diff-fuzz.py --seed 31`).
#[test]
fn unbounded_objects_written_about_far_points_render_as_about_near_ones() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/scenes/");
    let shallows = std::fs::read_to_string(format!("{dir}shallows.toml"))
        .unwrap()
        .replace("width = 480", "width = 32")
        .replace("height = 270", "height = 24")
        .replace("spp = 64", "spp = 4");
    let water = r#"base = { type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }"#;
    assert!(shallows.contains(water));
    let pillar = |y: f64| {
        format!(
            r#"
[camera]
position = [0.0, 0.5, 4.0]
look_at = [0.0, 0.0, 0.0]
[film]
width = 32
height = 24
spp = 4
[[material]]
name = "m"
type = "diffuse"
reflectance = [0.7, 0.6, 0.5]
[[object]]
material = "m"
base = {{ type = "cylinder", center = [0.3, {y}, 0.0], axis = [0.0, 1.0, 0.0], radius = 0.5 }}
[[object]]
material = "m"
base = {{ type = "plane", point = [0.0, -1.0, 0.0], normal = [0.0, 1.0, 0.0] }}
[environment]
type = "constant"
radiance = [0.2, 0.3, 0.4]
[[light]]
type = "point"
position = [2.0, 3.0, 3.0]
intensity = [20.0, 20.0, 20.0]
"#
        )
    };
    let cases = [
        (
            "water plane",
            shallows.clone(),
            shallows.replace(water, &water.replace("[0.0, 0.0, 0.0]", "[1e7, 0.0, 0.0]")),
        ),
        ("pillar", pillar(0.0), pillar(1e7)),
    ];
    for (what, near, far) in cases {
        let near = render_with(&scene(&near), 2);
        let far = render_with(&scene(&far), 2);
        let sum = |img: &Image| img.rgb.iter().flatten().map(|&v| v as f64).sum::<f64>();
        eprintln!("{what}: sums {} and {}", sum(&near), sum(&far));
        assert!(sum(&near) > 0.0, "{what}");
        assert!(
            near.rgb == far.rgb,
            "{what}: {} against {}",
            sum(&near),
            sum(&far)
        );
    }
}

/// `examples/tests/lamp-above-drop.toml`: a point light of intensity 20 at
/// `[0, 5, 0]` above a sphere of absorbing water (radius 2 about the
/// origin, index 1.33, `sigma_a` 0.1) holding a diffuse floor (0.8) at
/// `y = -0.5`, the camera inside the water, black sky, `max_depth` 1. The
/// light reaches the floor only through the curved surface, by
/// refraction (manifold next-event estimation): each pixel's expected
/// value is `exp(-sigma t) rho / pi E cos`, `E = I T G exp(-sigma l)` for
/// the path through the crossing point that Fermat's principle picks, in
/// the plane of the light, the centre and the floor point (golden-section
/// search of the optical length over the great circle), and the
/// spreading `G = (d theta_L / ds) (sin theta_L / rho_q)` from the
/// symmetry about the light's axis (`theta_L` the light's ray's angle
/// with the axis, `rho_q` the floor point's distance from it, `s` across
/// the ray in that plane, differentiated numerically). With
/// `refracted_lights = "flat"` (the behaviour before) the floor is black.
#[test]
fn a_lamp_above_a_drop_lights_the_floor_inside_through_the_curved_surface() {
    let (n1, n2, sigma, rho, radius) = (1.0f64, 1.33f64, 0.1, 0.8, 2.0);
    let s = scene(&test_scene("lamp-above-drop.toml", &[]));
    let light = s.lights[0].position;
    let want = film_of(&s, |ray| {
        let t = (-0.5 - ray.origin.y) / ray.dir.y;
        let q = ray.at(t);
        if !(t > 0.0) || q.x.abs() > 1.0 || q.z.abs() > 1.0 {
            return 0.0;
        }
        let (e, cos_floor) = drop_reference(light, q, radius, n1, n2, sigma);
        (-sigma * t).exp() * rho / std::f64::consts::PI * e * cos_floor
    });
    let (got, want, se) = against(&render_with(&s, 2), &want);
    eprintln!("lamp above a drop: render {got} +- {se}, closed form {want}");
    assert!(want > 0.01, "{want}");
    assert!(
        (got - want).abs() < 4.0 * se + 3e-3 * want,
        "render {got} +- {se}, closed form {want}"
    );
    let flat = scene(&test_scene(
        "lamp-above-drop.toml",
        &[(
            "[integrator]\n",
            "[integrator]\nrefracted_lights = \"flat\"\n",
        )],
    ));
    let img = render_with(&flat, 2);
    assert!(img.rgb.iter().flatten().all(|&v| v == 0.0));
}

/// `examples/tests/lamp-above-glass.toml`: a point light of intensity 20
/// at `[0.3, 3, 0.2]` above a slab of glass (index 1.5, `y` from 1 to
/// 1.5) over a diffuse floor (0.8) at `y = 0`, the camera under the
/// slab, black sky, `max_depth` 1, `caustics = "manifold"`. The light
/// reaches the floor only through both faces of the slab: each pixel's
/// expected value is `rho / pi E cos theta_1` with `E = I T^2 G`, the
/// light's ray at `theta_1` from the vertical landing at `R = (h_1 +
/// h_2) tan theta_1 + d tan theta_2` from its foot (`n sin theta_1 = 1.5
/// sin theta_2`, bisection), `G = sin theta_1 / (R cos theta_1
/// dR/dtheta_1)` and `T = 1 - F(theta_1)` at either face. Then the same
/// under water: everything inside a sphere of absorbing water (index
/// 1.33, `sigma_a` 0.1), so the glass refracts by `1.5 / 1.33` and the
/// water attenuates the camera ray and both legs outside the glass. With
/// `caustics = "none"` (the default) the floor is black.
#[test]
fn a_lamp_above_a_glass_slab_lights_the_floor_through_both_faces() {
    let (rho, d, h1, h2) = (0.8, 0.5, 1.5, 1.0);
    let water = "[[material]]\nname = \"water\"\ntype = \"subsurface\"\n\
                 sigma_s = [0.0, 0.0, 0.0]\nsigma_a = [0.1, 0.1, 0.1]\nior = 1.33\n\
                 mode = \"random_walk\"\n[[object]]\nmaterial = \"water\"\n\
                 base = { type = \"sphere\", center = [0.0, 0.0, 0.0], radius = 10.0 }\n";
    for (n_out, sigma, extra) in [(1.0f64, 0.0, ""), (1.33, 0.1, water)] {
        let n = 1.5 / n_out;
        let s = scene(&(test_scene("lamp-above-glass.toml", &[]) + extra));
        let light = s.lights[0].position;
        let want = film_of(&s, |ray| {
            let t = -ray.origin.y / ray.dir.y;
            let q = ray.at(t);
            if !(t > 0.0) || q.x.abs() > 1.5 || q.z.abs() > 1.5 {
                return 0.0;
            }
            let foot = DVec3::new(light.x - q.x, 0.0, light.z - q.z).length();
            let radius = |t1: f64| {
                let s2 = t1.sin() / n;
                (h1 + h2) * t1.tan() + d * s2 / (1.0 - s2 * s2).sqrt()
            };
            let (mut lo, mut hi) = (0.0, std::f64::consts::FRAC_PI_2 - 1e-9);
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                if radius(mid) < foot {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let t1 = 0.5 * (lo + hi);
            let e = 1e-6;
            let dr = (radius(t1 + e) - radius(t1 - e)) / (2.0 * e);
            let g = t1.sin() / (foot * t1.cos() * dr);
            let tr = 1.0 - fresnel(t1.cos(), n_out, 1.5);
            let outside = t + (h1 + h2) / t1.cos();
            (-sigma * outside).exp() * rho / std::f64::consts::PI * 20.0 * tr * tr * g * t1.cos()
        });
        let (got, want, se) = against(&render_with(&s, 2), &want);
        eprintln!(
            "lamp above a glass slab (n_out {n_out}): render {got} +- {se}, closed form {want}"
        );
        assert!(want > 0.1, "{want}");
        assert!(
            (got - want).abs() < 4.0 * se + 3e-3 * want,
            "n_out {n_out}: render {got} +- {se}, closed form {want}"
        );
        let none = scene(
            &(test_scene(
                "lamp-above-glass.toml",
                &[("caustics = \"manifold\"", "caustics = \"none\"")],
            ) + extra),
        );
        let img = render_with(&none, 2);
        assert!(img.rgb.iter().flatten().all(|&v| v == 0.0));
    }
}

/// The irradiance at `q`, inside a sphere of radius `radius` about the
/// origin (index `n2`, extinction `sigma`), from a light of intensity 20
/// at `light` outside (index `n1`), normal to the refracted ray, and that
/// ray's cosine with the vertical (Fermat's principle in the plane of
/// the light, the centre and `q`; the spreading from the symmetry about
/// the light's axis).
fn drop_reference(light: DVec3, q: DVec3, radius: f64, n1: f64, n2: f64, sigma: f64) -> (f64, f64) {
    let e1 = light.normalize();
    // The crossing for a point qq in the plane of e1 and e2.
    let solve = |qq: DVec3| {
        let off = qq - qq.dot(e1) * e1;
        let e2 = off.normalize();
        let at = |psi: f64| radius * (psi.cos() * e1 + psi.sin() * e2);
        let optical = |psi: f64| n1 * (light - at(psi)).length() + n2 * (at(psi) - qq).length();
        let (mut a, mut b) = (0.0, (radius / light.length()).acos());
        let r = (5f64.sqrt() - 1.0) / 2.0;
        for _ in 0..200 {
            let (c1, c2) = (b - r * (b - a), a + r * (b - a));
            if optical(c1) < optical(c2) {
                b = c2;
            } else {
                a = c1;
            }
        }
        at(0.5 * (a + b))
    };
    let x = solve(q);
    let theta = |xx: DVec3| (xx - light).normalize().dot(-e1).acos();
    let ray = (q - x).normalize();
    // Across the ray, in the plane.
    let normal_of_plane = e1.cross(q - x).normalize();
    let across = normal_of_plane.cross(ray);
    let ds = 1e-5;
    let dtheta = (theta(solve(q + ds * across)) - theta(solve(q - ds * across))).abs() / (2.0 * ds);
    let rho_q = (q - q.dot(e1) * e1).length();
    let g = dtheta * theta(x).sin() / rho_q;
    let cos_out = (light - x).normalize().dot(x / radius);
    let tr = 1.0 - fresnel(cos_out, n1, n2);
    (
        20.0 * tr * g * (-sigma * (q - x).length()).exp(),
        ray.dot(-DVec3::Y),
    )
}
