//! `isolux render --gpu` end to end: a furnace scene renders to a PNG on
//! whatever adapter exists (lavapipe in CI), and a flag the GPU path does
//! not support is refused before any work. Without an adapter (outside CI)
//! the render test only checks that the error says so.

use std::process::Command;

fn run(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_isolux"))
        .args(args)
        .output()
        .unwrap()
}

const FURNACE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../examples/scenes/furnace.toml"
);

/// Whether a run failed for want of an adapter (stderr `err`) outside CI,
/// where the test is skipped; in CI (lavapipe) an adapter must exist.
fn no_adapter(err: &str) -> bool {
    err.contains("no GPU adapter found") && std::env::var_os("CI").is_none()
}

/// `render SCENE --gpu -o OUT` at 32 x 24, 2 spp, with `extra` flags:
/// its stderr, once it succeeded; `None` without an adapter outside CI
/// (after checking that it then exits 1).
fn render_small(scene: &str, extra: &[&str], out: &std::path::Path) -> Option<String> {
    let mut args = vec![
        "render",
        scene,
        "--gpu",
        "--spp",
        "2",
        "--width",
        "32",
        "--height",
        "24",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = run(&args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    if no_adapter(&err) {
        assert_eq!(o.status.code(), Some(1));
        return None;
    }
    assert!(o.status.success(), "{extra:?}: {err}");
    Some(err)
}

#[test]
fn render_gpu_writes_an_image_of_the_furnace() {
    // The default, the wavefront with the f64 intersection, the sorted
    // wavefront.
    // The summary names the kernel that ran.
    for (extra, kernel) in [
        (&[][..], None),
        (&["--wavefront", "--f64"], Some(", wavefront)")),
        (&["--sorted"], Some(", sorted wavefront)")),
        (&["--megakernel"], Some(", megakernel)")),
    ] {
        render_furnace(extra, kernel);
    }
}

/// The furnace through `render --gpu` with `extra` flags: 1 in every
/// pixel; the summary line names `kernel`.
fn render_furnace(extra: &[&str], kernel: Option<&str>) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.exr");
    let Some(err) = render_small(FURNACE, extra, &out) else {
        return;
    };
    assert!(err.contains("rendered 32x24 at 2 spp"), "{err}");
    let named = ["megakernel)", "wavefront)"]
        .iter()
        .any(|k| err.contains(k));
    assert!(named, "{extra:?}: no kernel named: {err}");
    if let Some(kernel) = kernel {
        assert!(err.contains(kernel), "{extra:?}: {err}");
    }
    // The white furnace is 1 everywhere: check the mean of the EXR.
    let img = isolux_io::read_rgb_image(&out).unwrap();
    let mean: f64 = img.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / img.pixels.len() as f64;
    assert!((mean - 1.0).abs() < 0.01, "{extra:?}: {mean}");
}

/// `--sorted` on a scene with a `subsurface` material renders as
/// `--wavefront` and says so.
#[test]
fn sorted_says_when_it_renders_as_the_wavefront() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.png");
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/scenes/translucent.toml"
    );
    let Some(err) = render_small(scene, &["--sorted"], &out) else {
        return;
    };
    assert!(err.contains("renders as --wavefront"), "{err}");
    assert!(err.contains(", wavefront)"), "{err}");
    assert!(out.exists());
}

/// On a driver that miscompiles long loops (Mesa 22's lavapipe, the CI's;
/// `Gpu::miscompiles_loops`), `render --gpu` warns of a scene with a
/// random-walk medium, saying what each path tracer gets wrong there; on
/// other drivers, and for a scene without one, it does not.
#[test]
fn render_gpu_warns_of_random_walks_where_loops_are_miscompiled() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.png");
    let scenes = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/scenes/");
    let walk = format!("{scenes}translucent-random-walk.toml");
    let dipoles = format!("{scenes}translucent.toml");
    let Some(err) = render_small(&dipoles, &[], &out) else {
        return;
    };
    assert!(!err.contains("random walks"), "{err}");
    let miscompiles = isolux_gpu::Gpu::new().unwrap().miscompiles_loops();
    for (extra, what) in [
        (&[][..], "a few pixels differ from run to run"),
        (&["--megakernel"][..], "by the megakernel shorter walks too"),
    ] {
        let err = render_small(&walk, extra, &out).unwrap();
        let warned = err.contains("miscompiles the long loops of random walks in media: ");
        assert_eq!(warned, miscompiles, "{extra:?}: {err}");
        assert_eq!(err.contains(what), miscompiles, "{extra:?}: {err}");
    }
}

/// `--wavefront`, `--sorted` and `--megakernel` choose the GPU's path
/// tracer: refused without `--gpu`, with `--realtime` and together,
/// before any work; `--f64` (the GPU's intersection in f64) without
/// `--gpu` too.
#[test]
fn wavefront_needs_the_gpu_path_tracer() {
    for (flag, extra) in [
        ("--wavefront", &[][..]),
        ("--megakernel", &[][..]),
        ("--wavefront", &["--gpu", "--realtime"][..]),
        ("--megakernel", &["--gpu", "--realtime"][..]),
        ("--wavefront", &["--gpu", "--megakernel"][..]),
        ("--sorted", &[][..]),
        ("--sorted", &["--gpu", "--realtime"][..]),
        ("--sorted", &["--gpu", "--wavefront"][..]),
        ("--sorted", &["--gpu", "--megakernel"][..]),
        ("--f64", &[][..]),
    ] {
        let mut args = vec!["render", FURNACE, flag, "-o", "never.png"];
        args.extend_from_slice(extra);
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flag} {extra:?}: {err}");
        assert!(err.contains(flag), "{err}");
        assert!(!std::path::Path::new("never.png").exists());
    }
}

/// `--bounds-probe clamp` and `zero` (the kernels with every index out of
/// bounds clamped or read as zero) render the furnace to the same EXR
/// file byte for byte, 1 in every pixel; without `--gpu` the flag is
/// refused before any work.
#[test]
fn bounds_probes_render_the_same_furnace() {
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for probe in ["clamp", "zero"] {
        let out = dir.path().join(format!("{probe}.exr"));
        if render_small(FURNACE, &["--bounds-probe", probe], &out).is_none() {
            return;
        }
        let img = isolux_io::read_rgb_image(&out).unwrap();
        assert!(
            img.pixels.iter().all(|p| (p[1] - 1.0).abs() < 0.05),
            "{probe}"
        );
        files.push(std::fs::read(&out).unwrap());
    }
    assert!(files[0] == files[1], "the clamped and zero kernels differ");
    let o = run(&[
        "render",
        FURNACE,
        "--bounds-probe",
        "zero",
        "-o",
        "never.png",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--gpu") && err.contains("--bounds-probe"),
        "{err}"
    );
    assert!(!std::path::Path::new("never.png").exists());
}

#[test]
fn render_gpu_writes_aov_layers() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.exr");
    if render_small(FURNACE, &["--aov"], &out).is_none() {
        return;
    }
    // The EXR header names the AOV channels (their values are compared
    // with the CPU's in crates/gpu/tests/aov.rs).
    let bytes = std::fs::read(&out).unwrap();
    for name in ["albedo.R", "normal.X", "depth.Z"] {
        let key = format!("{name}\0");
        assert!(
            bytes.windows(key.len()).any(|w| w == key.as_bytes()),
            "no {name} channel"
        );
    }
}

/// Whether a printed ratio can be the quotient of two printed times.
///
/// The table prints times and ratios to two decimals and computes each
/// ratio from the unrounded times, so at lavapipe's fraction-of-a-millisecond
/// times the quotient of the printed figures can be off by several percent
/// (0.56 / 0.36 = 1.56 printed as 1.53). The ratio must lie between the
/// quotients of the times' rounding intervals, widened by its own rounding.
fn ratio_agrees(ratio: f64, num: &str, den: &str) -> bool {
    let half = |cell: &str| {
        let digits = cell.split('.').nth(1).map_or(0, str::len);
        0.5 * 10f64.powi(-(digits as i32))
    };
    let (n, d): (f64, f64) = (num.parse().unwrap(), den.parse().unwrap());
    let (hn, hd) = (half(num), half(den));
    let low = (n - hn).max(0.0) / (d + hd);
    let high = if d - hd > 0.0 {
        (n + hn) / (d - hd)
    } else {
        f64::INFINITY
    };
    let slack = 0.005 + 1e-9;
    ratio >= low - slack && ratio <= high + slack
}

/// `isolux bench gpu` prints its table: the adapter, one row per mode, each
/// naming the kernel features of its frame (the diffuse model alone, and
/// no candidate list, for the furnace) and a positive, finite GPU time;
/// with `--kernels` a second table of each frame's time kernel by kernel
/// (`kernels_table_adds_up`).
#[test]
fn bench_gpu_prints_a_table_naming_the_kernel_features() {
    let o = run(&[
        "bench",
        "gpu",
        FURNACE,
        "--width",
        "16",
        "--height",
        "8",
        "--repeat",
        "1",
        "--skip-cpu",
        "--wavefront",
        "--per-sample",
        "--tiles",
        "--checked",
        "--kernels",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    if no_adapter(&err) {
        assert_eq!(o.status.code(), Some(1));
        return;
    }
    assert!(o.status.success(), "{err}");
    let all = String::from_utf8_lossy(&o.stdout);
    let (out, kernels) = all
        .split_once("\nGPU time per kernel")
        .expect("--kernels' table (lavapipe offers timestamps)");
    kernels_table_adds_up(kernels, &all);
    assert!(out.starts_with("adapter: "), "{out}");
    assert!(
        out.contains("| kernel features | GPU (ms/frame) |"),
        "{out}"
    );
    assert!(
        out.contains("| GPU wavefront (ms/frame) | wavefront / megakernel | GPU one sample per dispatch (ms/frame) | per sample / layered | GPU tile lists (ms/frame) | GPU per-ray walks (ms/frame) | lists / walks | GPU run-time checks (ms/frame) | checked / unchecked |"),
        "{out}"
    );
    let rows: Vec<&str> = out
        .lines()
        .filter(|l| l.starts_with("| furnace.toml |"))
        .collect();
    assert_eq!(rows.len(), 4, "{out}");
    for (row, mode) in rows
        .iter()
        .zip(["real-time", "path traced", "direct only", "first hit"])
    {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        assert_eq!(cells[2], mode, "{row}");
        assert_eq!(cells[4], "diffuse", "{row}");
        let ms: f64 = cells[5].parse().unwrap();
        assert!(ms.is_finite() && ms > 0.0, "{row}");
        // The first frame, its kernel's compile included where no earlier
        // row compiled it.
        let first: f64 = cells[cells.len() - 2].parse().unwrap();
        assert!(first.is_finite() && first > 0.0, "{row}");
        // `--wavefront`: its time and its ratio to the megakernel's, for
        // the path tracer's modes.
        if mode == "real-time" || mode == "first hit" {
            assert_eq!((cells[7], cells[8]), ("-", "-"), "{row}");
        } else {
            let wf: f64 = cells[7].parse().unwrap();
            let ratio: f64 = cells[8].parse().unwrap();
            assert!(wf.is_finite() && wf > 0.0, "{row}");
            assert!(ratio_agrees(ratio, cells[7], cells[5]), "{row}");
        }
        // `--per-sample`: in every mode that shades (first hits take a
        // dispatch per sample anyway).
        if mode == "first hit" {
            assert_eq!((cells[9], cells[10]), ("-", "-"), "{row}");
        } else {
            let one: f64 = cells[9].parse().unwrap();
            let ratio: f64 = cells[10].parse().unwrap();
            assert!(one.is_finite() && one > 0.0, "{row}");
            assert!(ratio_agrees(ratio, cells[9], cells[5]), "{row}");
        }
        // `--tiles`: in every mode.
        let lists: f64 = cells[11].parse().unwrap();
        let walks: f64 = cells[12].parse().unwrap();
        let ratio: f64 = cells[13].parse().unwrap();
        assert!(lists.is_finite() && lists > 0.0, "{row}");
        assert!(walks.is_finite() && walks > 0.0, "{row}");
        assert!(ratio_agrees(ratio, cells[11], cells[12]), "{row}");
        // `--checked`: in every mode.
        let checked: f64 = cells[14].parse().unwrap();
        let ratio: f64 = cells[15].parse().unwrap();
        assert!(checked.is_finite() && checked > 0.0, "{row}");
        assert!(ratio_agrees(ratio, cells[14], cells[5]), "{row}");
    }
}

/// `bench gpu --kernels`' table for the furnace with `--wavefront`: per
/// mode and path kernel the kernels each kernel queues (the megakernel's
/// `main` and `resolve`, the wavefront's `trace` over its steps,
/// `trace_last` and `resolve`, real time's and first hits' own), and the kernels' times
/// and the time between them adding up to the frame's span, the shares
/// to 100%, within the table's rounding.
fn kernels_table_adds_up(table: &str, all: &str) {
    let rows: Vec<Vec<&str>> = table
        .lines()
        .filter(|l| l.starts_with("| furnace.toml |"))
        .map(|l| l.split('|').map(str::trim).collect())
        .collect();
    let mut groups: Vec<(String, Vec<&Vec<&str>>)> = Vec::new();
    for r in &rows {
        let key = format!("{} / {}", r[2], r[3]);
        match groups.last_mut() {
            Some((k, g)) if *k == key => g.push(r),
            _ => groups.push((key, vec![r])),
        }
    }
    let names = |g: &[&Vec<&str>]| g.iter().map(|r| r[4].to_string()).collect::<Vec<_>>();
    let expect: [(&str, &[&str]); 6] = [
        ("real-time / -", &["realtime", "resolve"]),
        ("path traced / megakernel", &["main", "resolve"]),
        (
            "path traced / wavefront",
            &["trace", "trace_last", "resolve"],
        ),
        ("direct only / megakernel", &["main", "resolve"]),
        (
            "direct only / wavefront",
            &["trace", "trace_last", "resolve"],
        ),
        ("first hit / -", &["aov_main"]),
    ];
    assert_eq!(groups.len(), 6, "{all}");
    for ((key, g), (want, kernels)) in groups.iter().zip(expect) {
        assert_eq!(key, want, "{all}");
        let n = g.len();
        let names = names(g);
        assert_eq!(&names[..n - 2], kernels, "{all}");
        assert_eq!(
            &names[n - 2..],
            ["(between dispatches)", "(frame)"],
            "{all}"
        );
        let num = |s: &str| -> f64 { s.trim_end_matches('%').parse().unwrap() };
        let frame = num(g[n - 1][9]);
        let parts: f64 = g[..n - 1].iter().map(|r| num(r[9])).sum();
        let shares: f64 = g[..n - 1].iter().map(|r| num(r[10])).sum();
        assert!(frame > 0.0, "{key}: {all}");
        assert!(
            (parts - frame).abs() <= 0.0005 * n as f64 + 1e-9,
            "{key}: {parts} against {frame}\n{all}"
        );
        assert!(
            (shares - 100.0).abs() <= 0.05 * n as f64,
            "{key}: shares {shares}\n{all}"
        );
        // Dispatches: the frame's count is the kernels' sum; the
        // wavefront's steps add up to each kernel's total.
        let count: usize = g[..n - 2]
            .iter()
            .map(|r| r[5].parse::<usize>().unwrap())
            .sum();
        assert_eq!(count, g[n - 1][5].parse::<usize>().unwrap(), "{key}: {all}");
        for r in &g[..n - 2] {
            if r[6] == "-" {
                assert!(
                    !key.contains("wavefront") || r[4] == "resolve",
                    "{key}: {all}"
                );
                continue;
            }
            let steps: f64 = (6..9).map(|c| num(r[c])).sum();
            assert!((steps - num(r[9])).abs() <= 0.0015 + 1e-9, "{key}: {r:?}");
        }
    }
}

/// An object too far from the camera for its size in the GPU's f32
/// (`isolux_gpu::f32_shortfall`) is refused by `--gpu` with the reason
/// and no image, and renders on the CPU.
#[test]
fn render_gpu_refuses_a_scene_beyond_f32() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("far.toml");
    std::fs::write(
        &scene,
        r#"
[camera]
position = [0, 1, 5]
look_at = [500000, 0, 0]
fov_y = 40

[film]
width = 16
height = 12
spp = 1

[[material]]
name = "m"
type = "diffuse"
reflectance = [0.7, 0.7, 0.7]

[[object]]
material = "m"
base = { type = "sphere", center = [500000, 0, 0], radius = 1 }
"#,
    )
    .unwrap();
    refused_on_the_gpu_rendered_on_the_cpu(
        &scene,
        "object[0] is 2.0000e0 units across and reaches 5.0000e5 from the camera",
    );
}

/// Values that f64 holds and the GPU's f32 arithmetic does not (a light's
/// intensity of 1e300 is infinite in f32, and every sample it reached was
/// dropped as non-finite: a darker image with only a warning) are refused
/// by `--gpu`, naming what (`isolux_gpu::F32_VALUE_LIMIT`, and any
/// material parameter that is not finite in f32), with no image; the CPU
/// renders each of them. So is a bump whose `f Q^3` inside its object
/// goes beyond that limit, although its coefficients stay inside it.
#[test]
fn render_gpu_refuses_values_beyond_f32() {
    let dir = tempfile::tempdir().unwrap();
    let base = |light: &str, env: &str, ior: &str, factor: &str| {
        format!(
            r#"
[camera]
position = [0, 1, 5]
look_at = [0, 0, 0]
fov_y = 40

[film]
width = 12
height = 8
spp = 1

[environment]
type = "constant"
radiance = [{env}, 0.5, 0.5]

[[light]]
type = "point"
position = [2, 4, 3]
intensity = [{light}, 20, 20]

[[material]]
name = "glass"
type = "dielectric"
ior = {ior}

[[object]]
material = "glass"
base = {{ type = "sphere", center = [0, 0, 0], radius = 1 }}
[[object.perturbation]]
quadric = {{ type = "sphere", center = [0, 1, 0], radius = 0.3 }}
factor = {factor}
"#
        )
    };
    let cases = [
        (
            base("1e300", "0.5", "1.5", "100"),
            "light[0] has intensity [1e300, 20, 20], beyond the 1e30",
        ),
        (
            base("20", "2e30", "1.5", "100"),
            "the environment's radiance [2e30, 0.5, 0.5] exceeds the 1e30",
        ),
        (
            base("20", "0.5", "1.5", "1e31"),
            "object[0]: perturbation 0 has a factor or quadric coefficient beyond the 1e30",
        ),
        (
            base("20", "0.5", "1e300", "100"),
            "material \"glass\" has a parameter beyond the range of the GPU's f32",
        ),
        (
            // A support of radius 1e5: Q up to 1e10, 100 Q^3 up to 1e32.
            base("20", "0.5", "1.5", "100").replace("radius = 0.3 ", "radius = 1e5 "),
            "object[0]: perturbation 0 adds f Q^3 = 1e32 inside the object, beyond the 1e30",
        ),
    ];
    for (k, (text, want)) in cases.iter().enumerate() {
        let scene = dir.path().join(format!("big{k}.toml"));
        std::fs::write(&scene, text).unwrap();
        if !refused_on_the_gpu_rendered_on_the_cpu(&scene, want) {
            return;
        }
    }
}

/// `render --gpu` refuses `scene` with `--gpu: SCENE: {want} ... render
/// without --gpu`, exit 1 and no image, and the CPU renders it. False
/// when there is no adapter (outside CI: skipped).
fn refused_on_the_gpu_rendered_on_the_cpu(scene: &std::path::Path, want: &str) -> bool {
    let out = scene.with_extension("png");
    let s = scene.to_str().unwrap();
    let o = out.to_str().unwrap();
    let r = run(&["render", s, "--gpu", "-o", o]);
    let err = String::from_utf8_lossy(&r.stderr);
    if no_adapter(&err) {
        return false;
    }
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!("--gpu: {s}: {want}")) && err.contains("render without --gpu"),
        "{err}"
    );
    assert!(!out.exists());
    let r = run(&["render", s, "--quiet", "-o", o]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(out.exists());
    true
}

/// The gallery's copper bump (support radius 0.2, factor 3000) grown to
/// `radius` beside a white sphere, rendered at 40 x 24 and 16 spp on the
/// CPU and with `--gpu`: the GPU's image agrees with the CPU's within 5%
/// per channel. Returns the scene's path and the GPU run's stderr; `None`
/// where no adapter exists or it lacks f64 when the scene needs it.
fn grown_bump_on_both(radius: f64) -> Option<(String, String)> {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("shell.toml");
    let text = r#"
[camera]
position = [0.0, 3.4, 7.2]
look_at = [0.0, -0.15, 0.0]
fov_y = 42.0

[film]
width = 40
height = 24
spp = 16

[[light]]
type = "point"
position = [-3.0, 6.0, 5.0]
intensity = [45.0, 45.0, 45.0]

[[material]]
name = "copper"
type = "beckmann"
roughness = 0.25
metal = "Cu"

[[material]]
name = "white"
type = "diffuse"
reflectance = [0.7, 0.7, 0.7]

[[object]]
material = "white"
base = { type = "sphere", center = [0.0, 0.0, 0.0], radius = 1.0 }

[[object]]
material = "copper"
base = { type = "sphere", center = [-2.5, 0.0, 0.0], radius = 0.45 }
[[object.perturbation]]
quadric = { type = "sphere", center = [-2.5, 0.45, 0.0], radius = RADIUS }
factor = 3000.0
"#;
    std::fs::write(&scene, text.replace("RADIUS", &radius.to_string())).unwrap();
    let s = scene.to_str().unwrap();
    let means = |gpu: bool| {
        let out = dir.path().join(format!("shell-{gpu}.exr"));
        let mut args = vec!["render", s, "-o", out.to_str().unwrap()];
        if gpu {
            args.push("--gpu");
        }
        let r = run(&args);
        let err = String::from_utf8_lossy(&r.stderr).to_string();
        if no_adapter(&err) {
            return None;
        }
        if gpu && err.contains("does not offer f64 in shaders") {
            // An adapter without SHADER_F64 refuses the scene instead.
            assert!(
                err.contains("render without --gpu") && !out.exists(),
                "{err}"
            );
            return None;
        }
        assert!(r.status.success(), "{err}");
        let img = isolux_io::read_rgb_image(&out).unwrap();
        let n = img.pixels.len() as f64;
        let m = [0, 1, 2].map(|c| img.pixels.iter().map(|p| p[c] as f64).sum::<f64>() / n);
        Some((m, err))
    };
    let (gpu, err) = means(true)?;
    let (cpu, _) = means(false).unwrap();
    eprintln!("support radius {radius}: GPU {gpu:?}, CPU {cpu:?}");
    for c in 0..3 {
        assert!(
            (gpu[c] / cpu[c] - 1.0).abs() < 0.05,
            "support radius {radius}, channel {c}: GPU {} against CPU {}",
            gpu[c],
            cpu[c]
        );
    }
    Some((s.to_string(), err))
}

/// A bump that dwarfs its base grows a copper shell around the camera (a
/// fuzzed gallery: support radius 0.2 -> 50, `f Q^3` 6.2e9 times the
/// base's `|F|`; here grown on to radius 200, 1.6e12 times). The f32
/// intersection of the power basis placed the hits of the shell of radius
/// 50 up to 0.2 units short or missed them, and the image came out twice
/// as bright or half as bright as the CPU's. `--gpu` names the object and
/// intersects in f64 above `F32_CONDITION_LIMIT` (lavapipe has it), and
/// the image agrees with the CPU's.
#[test]
fn render_gpu_intersects_ill_conditioned_bumps_in_f64() {
    let Some((s, err)) = grown_bump_on_both(200.0) else {
        return;
    };
    let want = format!(
        "isolux: note: --gpu: {s}: object[1]: perturbation 0 adds f Q^3 up to 1.920e17 inside \
         the object, 1.60e12 times its base quadric's largest |F| there"
    );
    assert!(
        err.contains(&want) && err.contains("intersecting in f64"),
        "{err}"
    );
}

/// A floor (diffuse, 0.5) under a white sky, its plane `gap` units above
/// the top face of its box, seen from above: on the CPU (f64) the box
/// clips a plane above it away and the sky shows (1 everywhere); the
/// GPU's f32 cannot tell a plane 1e-6 units beyond its box's face from
/// one on it (a fuzzed gallery drew its floor on the GPU alone), so
/// `--gpu` notes the plane and intersects in f64 there (lavapipe has
/// it), and the image agrees with the CPU's; at 1e-2 it stays in f32 and
/// says nothing, and agrees too; with the plane on the face both draw the
/// floor (0.5). `Gpu::precision_for`, `f32_plane_at_box_face`.
#[test]
fn render_gpu_clips_a_plane_just_beyond_its_box_as_the_cpu() {
    let dir = tempfile::tempdir().unwrap();
    for (gap, note, want) in [
        ("1e-6", true, 1.0),
        ("1e-2", false, 1.0),
        ("0.0", false, 0.5),
    ] {
        let scene = dir.path().join(format!("floor-{gap}.toml"));
        std::fs::write(
            &scene,
            format!(
                "[camera]\nposition = [0.0, 6.0, 0.5]\nlook_at = [0.0, 0.0, 0.0]\nfov_y = 30.0\n\n\
                 [environment]\ntype = \"constant\"\nradiance = [1.0, 1.0, 1.0]\n\n\
                 [[material]]\nname = \"floor\"\ntype = \"diffuse\"\nreflectance = [0.5, 0.5, 0.5]\n\n\
                 [[object]]\nmaterial = \"floor\"\n\
                 base = {{ type = \"plane\", point = [0.0, {gap}, 0.0], normal = [0.0, 1.0, 0.0] }}\n\
                 bounds = {{ min = [-30.0, -2.0, -30.0], max = [30.0, 0.0, 30.0] }}\n"
            ),
        )
        .unwrap();
        let s = scene.to_str().unwrap();
        let mut means = Vec::new();
        for gpu in [true, false] {
            let out = dir.path().join(format!("floor-{gap}-{gpu}.exr"));
            let o = out.to_str().unwrap();
            let mut args = vec![
                "render", s, "-o", o, "--width", "16", "--height", "12", "--spp", "4",
            ];
            if gpu {
                args.push("--gpu");
            }
            let r = run(&args);
            let err = String::from_utf8_lossy(&r.stderr);
            if gpu && no_adapter(&err) {
                return;
            }
            assert!(r.status.success(), "{gap}: {err}");
            if gpu {
                let noted = err.contains("its plane misses its box (bounds) by 1.00e-6 units")
                    && err.contains("intersecting in f64");
                assert_eq!(noted, note, "{gap}: {err}");
                assert_eq!(err.contains("note"), note, "{gap}: {err}");
            }
            let img = isolux_io::read_rgb_image(&out).unwrap();
            let n = img.pixels.len() as f64;
            means.push(img.pixels.iter().map(|p| p[1] as f64).sum::<f64>() / n);
        }
        eprintln!(
            "plane {gap} above the box: GPU {}, CPU {}",
            means[0], means[1]
        );
        for m in means {
            assert!((m - want).abs() < 0.02, "{gap}: {m} against {want}");
        }
    }
}

/// The same bump at radius 50 (`f Q^3` 6.2e9 times the base's `|F|`):
/// the power basis' f32 walk missed or misplaced 200 of 400 rays at such
/// a shell, so it went to f64 until 2026-12-05; the Bernstein basis, its
/// quadratics taken about points near where they are used, holds it
/// (docs/gpu.md, "Precision"), so `--gpu` stays in f32, says nothing, and
/// agrees with the CPU.
#[test]
fn render_gpu_keeps_f32_below_the_condition_limit() {
    let Some((_, err)) = grown_bump_on_both(50.0) else {
        return;
    };
    assert!(!err.contains("f64") && !err.contains("note"), "{err}");
}
