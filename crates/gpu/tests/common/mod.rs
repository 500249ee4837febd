//! Shared by the GPU integration tests.

use isolux_gpu::{Gpu, GpuError};

/// The adapter, or `None` (with a message naming `what` was skipped) when
/// there is none outside CI. Under CI (`CI` set) `.ci/run` installs
/// lavapipe, and a missing adapter is a failure.
#[allow(dead_code)]
pub fn open(what: &str) -> Option<Gpu> {
    open_with(what, Gpu::new)
}

/// [`open`] by `how` (for example [`Gpu::for_bounds_probes`]).
#[allow(dead_code)]
pub fn open_with(what: &str, how: fn() -> Result<Gpu, GpuError>) -> Option<Gpu> {
    match how() {
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

// The helpers below serve the whole-image tests (`images.rs`, `realtime.rs`);
// the other test crates that include this module do not use them.

/// The example scene `name` from `examples/scenes/`.
#[allow(dead_code)]
pub fn example(name: &str) -> isolux_render::Scene {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/scenes")
        .join(name);
    isolux_scene::load(&p).unwrap()
}

/// The text of the test scene `examples/tests/<name>` (shared with the
/// CPU's tests).
#[allow(dead_code)]
pub fn test_scene_text(name: &str) -> String {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/tests")
        .join(name);
    std::fs::read_to_string(p).unwrap()
}

/// The scene of TOML `text`, as if read from `file` in the current folder
/// (errors name `file`); a test's own text, so it must parse.
#[allow(dead_code)]
pub fn parse(text: &str, file: &str) -> isolux_render::Scene {
    isolux_scene::parse_str(text, std::path::Path::new(file), std::path::Path::new(".")).unwrap()
}

/// The usual verdict on [`compare_with_cpu`]'s figures: the GPU's image
/// within 1.5 times the CPU's own seed-to-seed noise of the CPU's, their
/// means within 3%, and the CPU's mean above `floor` (not a blank image).
#[allow(dead_code)]
pub fn assert_within_noise((diff, noise, mg, mc): (f64, f64, f64, f64), name: &str, floor: f64) {
    assert!(mc > floor, "{name}: {mc}");
    assert!(diff <= 1.5 * noise, "{name}: {diff} vs noise {noise}");
    assert!((mg - mc).abs() <= 0.03 * mc, "{name}: {mg} vs {mc}");
}

/// Mean luminance of each 8 x 8 block of `img`.
#[allow(dead_code)]
pub fn blocks(img: &isolux_core::Image) -> Vec<f64> {
    let (w, h) = (img.width as usize, img.height as usize);
    let mut out = Vec::new();
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            let mut s = 0.0;
            for y in by * 8..by * 8 + 8 {
                for x in bx * 8..bx * 8 + 8 {
                    let p = img.rgb[y * w + x];
                    s += isolux_core::Rgb::new(p[0] as f64, p[1] as f64, p[2] as f64).luminance();
                }
            }
            out.push(s / 64.0);
        }
    }
    out
}

/// Mean absolute difference of two equally long lists.
#[allow(dead_code)]
pub fn mean_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f64>() / a.len() as f64
}

/// The GPU's image of `scene` against the CPU's, both from the same
/// renderer (path tracer or real-time mode, passed in): renders `scene`
/// with `gpu`, then with `cpu`, then with `cpu` again under the next seed.
/// Returns `(block |GPU - CPU|, block |CPU - CPU'|, mean GPU, mean CPU)`:
/// the mean absolute difference of 8 x 8 block means, GPU against CPU and
/// the CPU's own seed-to-seed one (the noise), and the two image means.
/// Prints them under `label`; a blank image fails.
#[allow(dead_code)]
pub fn compare_with_cpu(
    scene: &mut isolux_render::Scene,
    gpu: impl Fn(&isolux_render::Scene) -> isolux_core::Image,
    cpu: impl Fn(&isolux_render::Scene) -> isolux_core::Image,
    label: &str,
) -> (f64, f64, f64, f64) {
    let g = blocks(&gpu(scene));
    let c1 = blocks(&cpu(scene));
    scene.integrator.seed += 1;
    let c2 = blocks(&cpu(scene));
    let noise = mean_abs_diff(&c1, &c2);
    let diff = mean_abs_diff(&g, &c1);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (mg, mc) = (mean(&g), mean(&c1));
    eprintln!(
        "{label}: block |GPU - CPU| {diff:.5}, |CPU - CPU'| {noise:.5}; \
         means GPU {mg:.5} CPU {mc:.5} CPU' {:.5}",
        mean(&c2)
    );
    assert!(mc > 0.0 && noise > 0.0, "{label}: a blank image");
    (diff, noise, mg, mc)
}

/// The bits of `img`'s values, for comparisons bit for bit.
#[allow(dead_code)]
pub fn bits(img: &isolux_core::Image) -> Vec<u32> {
    img.rgb.iter().flatten().map(|c| c.to_bits()).collect()
}

/// Asserts that two renders' values agree bit for bit, saying how many do.
#[allow(dead_code)]
pub fn all_equal(a: &[u32], b: &[u32], what: &str) {
    let same = a.iter().zip(b).filter(|(x, y)| x == y).count();
    eprintln!(
        "{what}: {:.2}% of the values agree",
        100.0 * same as f64 / a.len() as f64
    );
    assert_eq!(same, a.len(), "{what}");
}

/// The example scene `file` at 40 x 24 pixels, 4 spp: the size of the
/// tests that render a scene with two compilations of the kernels.
#[allow(dead_code)]
pub fn small_example(file: &str) -> isolux_render::Scene {
    let mut scene = example(file);
    scene.film.width = 40;
    scene.film.height = 24;
    scene.film.spp = 4;
    scene
}

/// The bits of `scene` rendered by `mode`: `megakernel`, `wavefront`,
/// `sorted` (the three path tracers) or `real time`. Asserts that the
/// image is not black.
#[allow(dead_code)]
pub fn render_bits(gpu: &Gpu, scene: &isolux_render::Scene, mode: &str) -> Vec<u32> {
    let mut frame = match mode {
        "real time" => gpu.prepare_realtime(scene).unwrap(),
        _ => gpu.prepare(scene).unwrap(),
    };
    match mode {
        "megakernel" => frame.set_wavefront(false),
        "wavefront" | "sorted" => {
            frame.set_wavefront(true);
            frame.set_sorted(mode == "sorted");
        }
        "real time" => {}
        _ => panic!("no mode {mode}"),
    }
    frame.run(gpu, scene.film.spp);
    let (img, _) = frame.image(gpu).unwrap();
    assert!(img.rgb.iter().flatten().any(|&c| c > 0.0), "{mode}: black");
    bits(&img)
}
