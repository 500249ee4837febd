//! End-to-end tests of the `isolux` binary.

use std::path::Path;
use std::process::Command;

fn isolux() -> Command {
    Command::new(env!("CARGO_BIN_EXE_isolux"))
}

const TINY: &str = r#"
[film]
width = 24
height = 16
spp = 2
[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]
[[material]]
name = "m"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]
[[object]]
material = "m"
base = { type = "sphere", center = [0.0, 0.0, 0.0], radius = 1.0 }
"#;

/// The file `path` under the repository's `examples/` (`scenes/...`,
/// `tests/...`).
fn example(path: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(path)
}

fn write_scene(dir: &Path, src: &str) -> std::path::PathBuf {
    let p = dir.join("scene.toml");
    std::fs::write(&p, src).unwrap();
    p
}

#[test]
fn renders_png_and_exr_with_overrides() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), TINY);
    let png = dir.path().join("out.png");
    let st = isolux()
        .args([
            "render",
            scene.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--width",
            "30",
            "--height",
            "20",
            "--spp",
            "3",
            "--threads",
            "1",
            "--seed",
            "5",
        ])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let stderr = String::from_utf8_lossy(&st.stderr);
    assert!(
        stderr.contains("rendered 30x20 at 3 spp") && stderr.contains("M samples/s"),
        "{stderr}"
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    // IHDR width and height (big-endian at offsets 16 and 20).
    assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().unwrap()), 30);
    assert_eq!(u32::from_be_bytes(bytes[20..24].try_into().unwrap()), 20);

    let exr = dir.path().join("out.exr");
    let st = isolux()
        .args([
            "render",
            scene.to_str().unwrap(),
            "-o",
            exr.to_str().unwrap(),
            "--aov",
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(st.status.success());
    assert!(st.stderr.is_empty(), "--quiet prints nothing");
    let img = isolux_io::read_rgb_image(&exr).unwrap();
    assert_eq!((img.width, img.height), (24, 16));
    // Centre pixel sees the sphere: exactly 0.5.
    assert!((img.pixels[8 * 24 + 12][0] - 0.5).abs() < 1e-6);
}

#[test]
fn bad_scene_exits_non_zero_with_one_line_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(
        dir.path(),
        &TINY.replace("radius = 1.0", "radius = \"one\""),
    );
    let png = dir.path().join("out.png");
    let st = isolux()
        .args([
            "render",
            scene.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(1));
    let err = String::from_utf8_lossy(&st.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("scene.toml:15:")
            && err.contains("object[0].base.radius: expected a number, found a string"),
        "{err}"
    );
    assert!(!png.exists());
    // Nothing half-written either.
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "{leftovers:?}");
}

#[test]
fn usage_errors_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), TINY);
    let s = scene.to_str().unwrap();
    for (args, want) in [
        (
            vec!["render", s, "-o", "x.jpg"],
            "x.jpg: unknown output format: use a .png or .exr file name",
        ),
        (
            vec!["render", s, "-o", "x.png", "--aov"],
            "--aov needs an .exr output",
        ),
        (
            vec!["render", s, "-o", "x.png", "--spp", "0"],
            "--spp must be at least 1",
        ),
        (
            vec!["render", s, "-o", "x.png", "--threads", "0"],
            "--threads must be at least 1",
        ),
        // Values that failed to allocate (an abort), overflowed the
        // stratification grid (a panic), or took minutes to start (found
        // by scripts/cli-fuzz.py): the scene file's bounds, by flag.
        (
            vec!["render", s, "-o", "x.png", "--width", "4294967295"],
            "--width: must lie in 1..=65536, got 4294967295",
        ),
        (
            vec![
                "render", s, "-o", "x.png", "--width", "60000", "--height", "60000",
            ],
            "--width x --height: 60000 x 60000 is 3600000000 pixels, more than the 268435456",
        ),
        (
            vec!["render", s, "-o", "x.png", "--spp", "4294967295"],
            "--spp: must lie in 1..=1048576, got 4294967295",
        ),
        (
            vec!["render", s, "-o", "x.png", "--threads", "100000"],
            "--threads 100000: at most 1024 worker threads",
        ),
        // The GPU's bounce bound, 2 max_depth + ..., wrapped in u32 from
        // 2^31 on and cut paths short where the CPU followed them.
        (
            vec!["render", s, "-o", "x.png", "--max-depth", "4294967295"],
            "--max-depth must be at most 1000000 scattering events, got 4294967295",
        ),
        // bench: 100 GB asked for, and a panic on zero repeats.
        (
            vec!["bench", "geometry", "--bumps", "0,4294967295"],
            "--bumps: at most 65536 bumps per sphere, got 4294967295",
        ),
        (
            vec!["bench", "factor", "--repeat", "0"],
            "--repeat must lie in 1..=1000, got 0",
        ),
        (
            vec![
                "sss",
                "profile",
                "--medium",
                "marble",
                "--photons",
                "18446744073709551615",
                "-o",
                "x.png",
            ],
            "at most 100000000 photons per channel",
        ),
        (
            vec!["render", "/missing.toml", "-o", "x.png"],
            "/missing.toml: cannot read scene file",
        ),
        // An output that cannot be written fails before the render.
        (
            vec!["render", s, "-o", "no/such/dir/x.png", "--spp", "100000"],
            "no/such/dir/x.png: cannot write here: the directory no/such/dir does not exist",
        ),
        (vec!["render", s, "-o", "."], "unknown output format"),
    ] {
        let st = isolux()
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert_eq!(st.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&st.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: one line: {err}");
        // No cause repeated (an error that prints its source, chained).
        let parts: Vec<&str> = err.trim().split(": ").collect();
        for w in parts.windows(2) {
            assert_ne!(w[0], w[1], "{args:?}: repeated cause: {err}");
        }
    }
    // Missing required flag: clap's usage error, exit 2.
    let st = isolux().args(["render", s]).output().unwrap();
    assert_eq!(st.status.code(), Some(2));
}

#[test]
fn help_documents_every_flag() {
    let out = isolux().args(["render", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    for flag in [
        "--output",
        "--spp",
        "--width",
        "--height",
        "--threads",
        "--seed",
        "--quiet",
        "--exposure",
        "--tonemap",
        "--aov",
        "--max-depth",
    ] {
        assert!(help.contains(flag), "missing {flag} in:\n{help}");
    }
    let out = isolux().arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(help.contains("render") && help.contains("bench") && help.contains("view"));
}

#[test]
fn exposure_and_tonemap_change_png() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), TINY);
    let s = scene.to_str().unwrap();
    let a = dir.path().join("a.png");
    let b = dir.path().join("b.png");
    assert!(isolux()
        .args(["render", s, "-o", a.to_str().unwrap(), "-q"])
        .status()
        .unwrap()
        .success());
    assert!(isolux()
        .args([
            "render",
            s,
            "-o",
            b.to_str().unwrap(),
            "-q",
            "--exposure",
            "-1",
            "--tonemap",
            "reinhard"
        ])
        .status()
        .unwrap()
        .success());
    assert_ne!(std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
}

const MATS: &str = r#"
[[material]]
name = "matte"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]
[[material]]
name = "glass"
type = "dielectric"
ior = 1.5
[[material]]
name = "gold"
type = "ggx"
roughness = 0.2
metal = "Au"
"#;

#[test]
fn brdf_plot_albedo_and_sphere_write_images() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), MATS);
    let s = scene.to_str().unwrap();
    let png = dir.path().join("lobe.png");
    let st = isolux()
        .args([
            "brdf",
            "plot",
            s,
            "--material",
            "matte",
            "--material",
            "gold",
            "--theta-i",
            "30",
            "-o",
            png.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    let svg = dir.path().join("lobe.svg");
    let st = isolux()
        .args([
            "brdf",
            "plot",
            s,
            "--material",
            "gold",
            "--theta-i",
            "60",
            "--plane",
            "out",
            "-o",
            svg.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(st.status.success());
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("<svg") && text.contains("gold"));

    // Albedo table: glass conserves energy (R + T = 1) at every angle, and
    // a Lambertian surface reflects exactly its reflectance.
    let out = dir.path().join("albedo.png");
    let st = isolux()
        .args([
            "brdf",
            "albedo",
            s,
            "--material",
            "matte",
            "--material",
            "glass",
            "-o",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let table = String::from_utf8_lossy(&st.stdout);
    let rows: Vec<Vec<f64>> = table
        .lines()
        .skip(2)
        .map(|l| l.split('|').filter_map(|c| c.trim().parse().ok()).collect())
        .collect();
    assert_eq!(rows.len(), 11, "{table}");
    for r in &rows {
        assert!((r[1] - 0.5).abs() < 1e-9, "{table}");
        assert!((r[2] - 1.0).abs() < 1e-9, "{table}");
    }

    // A `subsurface` medium has no BRDF of its own (its boundary's R + T
    // is 1 at every angle): the table shows its local approximation, the
    // `subsurface_brdf` of the same medium, within Monte Carlo noise of
    // that material's own column (measured: equal, 0.949 at normal
    // incidence rising to 0.998 at 89 degrees).
    let media = dir.path().join("media.toml");
    std::fs::write(
        &media,
        "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n\
         [[material]]\nname = \"milk\"\ntype = \"subsurface\"\nmedium = \"wholemilk\"\n\
         [[material]]\nname = \"local\"\ntype = \"subsurface_brdf\"\nmedium = \"wholemilk\"\n\
         [[object]]\nmaterial = \"milk\"\n\
         base = { type = \"sphere\", center = [0.0, 0.0, 0.0], radius = 1.0 }\n",
    )
    .unwrap();
    let st = isolux()
        .args([
            "brdf",
            "albedo",
            media.to_str().unwrap(),
            "--material",
            "milk",
            "--material",
            "local",
            "-o",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let table = String::from_utf8_lossy(&st.stdout);
    assert!(table.contains("milk (local approximation)"), "{table}");
    let rows: Vec<Vec<f64>> = table
        .lines()
        .skip(2)
        .map(|l| l.split('|').filter_map(|c| c.trim().parse().ok()).collect())
        .collect();
    assert!(rows[0][1] < 0.96, "{table}");
    for r in &rows {
        assert!(r[1] <= 1.0 && (r[1] - r[2]).abs() < 0.02, "{table}");
    }
    assert!(out.exists());

    let sphere = dir.path().join("sphere.png");
    let st = isolux()
        .args([
            "brdf",
            "sphere",
            s,
            "--material",
            "gold",
            "--size",
            "48",
            "-o",
            sphere.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    assert!(sphere.exists());
}

#[test]
fn brdf_errors_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), MATS);
    let s = scene.to_str().unwrap();
    for (args, want) in [
        (
            vec![
                "brdf",
                "plot",
                s,
                "--material",
                "velvet",
                "--theta-i",
                "30",
                "-o",
                "x.png",
            ],
            "no material named \"velvet\" (defined: matte, glass, gold)",
        ),
        (
            vec![
                "brdf",
                "plot",
                s,
                "--material",
                "gold",
                "--theta-i",
                "95",
                "-o",
                "x.png",
            ],
            "--theta-i must lie in [0, 90) degrees",
        ),
        // Found by scripts/cli-fuzz.py: a plot of NaN directions, written.
        (
            vec![
                "brdf",
                "plot",
                s,
                "--material",
                "gold",
                "--theta-i",
                "30",
                "--phi-i",
                "nan",
                "-o",
                "x.png",
            ],
            "--phi-i must be a finite number of degrees, got NaN",
        ),
        (
            vec!["brdf", "albedo", s, "--material", "gold", "-o", "x.gif"],
            "x.gif: unknown plot format: use a .png or .svg file name",
        ),
    ] {
        let st = isolux()
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert_eq!(st.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&st.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    }
    // Nothing but the scene was left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn sss_media_and_profile() {
    let out = isolux().args(["sss", "media"]).output().unwrap();
    assert!(out.status.success());
    let table = String::from_utf8_lossy(&out.stdout);
    for name in [
        "apple",
        "chicken1",
        "chicken2",
        "cream",
        "ketchup",
        "marble",
        "potato",
        "skimmilk",
        "skin1",
        "skin2",
        "spectralon",
        "wholemilk",
    ] {
        assert!(
            table.contains(&format!("| {name} |")),
            "{name} missing:\n{table}"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("profile.png");
    let st = isolux()
        .args([
            "sss",
            "profile",
            "--medium",
            "marble",
            "--photons",
            "5000",
            "-o",
            png.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    assert!(String::from_utf8_lossy(&st.stderr).contains("total diffuse reflectance dipole"));
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    let st = isolux()
        .args(["sss", "profile", "--medium", "jelly", "-o", "x.png"])
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&st.stderr).contains("unknown medium \"jelly\" (valid: apple,"));
}

/// A point light that cannot reach the random-walk medium around the
/// camera lights nothing the camera sees in the medium directly:
/// `render` warns, naming the light and the medium's object, and renders.
/// So for the sun above a camera in a bubble of another medium under
/// water (two boundaries: a point light is refracted through one), and
/// above a drop of water with `refracted_lights = "flat"` (curved
/// boundaries stop point lights then). A lamp in the water (the example
/// as it is) draws no warning, nor does the sun above water of index 1 (a
/// null boundary, which shadow rays pass), nor the sun above the
/// example's flat water (refracted through its surface, since
/// 2026-12-04) or above the drop (manifold next-event estimation, since
/// later that day).
#[test]
fn a_light_outside_the_cameras_medium_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string(example("scenes/underwater.toml")).unwrap();
    let lamp = "position = [0.3, -1.0, 1.2]";
    assert!(src.contains(lamp));
    let sun = "position = [0.3, 2.0, 1.2]";
    let index_1 = src.replace("ior = 1.33", "ior = 1.0");
    assert_ne!(index_1, src);
    let plane = "base = { type = \"plane\", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }";
    let drop = src.replace(
        plane,
        "base = { type = \"sphere\", center = [0.0, -50.0, 0.0], radius = 50.0 }",
    );
    assert_ne!(drop, src);
    let flat = drop.replace(
        "[integrator]\n",
        "[integrator]\nrefracted_lights = \"flat\"\n",
    );
    assert_ne!(flat, drop);
    // The camera in a bubble of another medium (listed first, so that it
    // is object 0) under the water.
    let bubble = format!(
        "{}\n[[material]]\nname = \"bubble\"\ntype = \"subsurface\"\nsigma_s = [0.1, 0.1, 0.1]\n\
         sigma_a = [0.0, 0.0, 0.0]\nior = 1.5\nmode = \"random_walk\"\n",
        src
    )
    .replacen(
        "[[object]]",
        "[[object]]\nmaterial = \"bubble\"\nbase = { type = \"sphere\", center = [0.0, -0.9, 4.0], radius = 0.2 }\n\n[[object]]",
        1,
    );
    for (src, light, warned) in [
        (&src, lamp, false),
        (&drop, sun, false),
        (&flat, sun, true),
        (&bubble, sun, true),
        (&src, sun, false),
        (&index_1, sun, false),
    ] {
        let scene = write_scene(dir.path(), &src.replace(lamp, light));
        let out = dir.path().join("out.png");
        let o = isolux()
            .args([
                "render", "--spp", "1", "--width", "16", "--height", "12", "-o",
            ])
            .arg(&out)
            .arg(&scene)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(out.exists());
        assert_eq!(
            err.contains("warning")
                && err.contains("light[0] lies outside the random-walk medium of object[0]"),
            warned,
            "{err}"
        );
    }
}

/// A camera deep inside a random-walk medium whose mean free path is a
/// ten-thousandth of its size: a walk would need some 10^8 events to
/// leave, so every path ends at `MAX_MEDIUM_EVENTS` (100,000), and the
/// render says so, with the count, instead of handing back a dark image
/// in silence (found by `gpu-diff-fuzz.py --cpu-only --seed 23`: fog's
/// `sigma_s` at 1e30 ran past the fuzzer's 300 s). The same sphere a
/// hundred times thinner (a walk of some 10^4 events) renders without the
/// warning, as does the first sphere's medium with the camera outside it.
#[test]
fn paths_ended_in_a_medium_too_thick_for_the_walk_are_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    // examples/tests/medium-too-thick.toml (shared with the GPU's
    // `paths_ended_at_the_cap_of_medium_events_are_counted`), its
    // `sigma_s` and the camera's z replaced.
    let text = std::fs::read_to_string(example("tests/medium-too-thick.toml")).unwrap();
    assert!(
        text.contains("sigma_s = [1e4, 1e4, 1e4]") && text.contains("position = [0.0, 0.0, 0.0]")
    );
    let scene = |sigma: f64, camera_z: f64| {
        text.replace(
            "sigma_s = [1e4, 1e4, 1e4]",
            &format!("sigma_s = [{sigma:e}, {sigma:e}, {sigma:e}]"),
        )
        .replace(
            "position = [0.0, 0.0, 0.0]",
            &format!("position = [0.0, 0.0, {camera_z:?}]"),
        )
    };
    for (sigma, camera_z, warned) in [(1e4, 0.0, true), (1e2, 0.0, false), (1e4, 5.0, false)] {
        let path = write_scene(dir.path(), &scene(sigma, camera_z));
        let out = dir.path().join("out.png");
        let o = isolux()
            .args([
                "render", "--spp", "1", "--width", "2", "--height", "2", "-o",
            ])
            .arg(&out)
            .arg(&path)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(out.exists());
        assert_eq!(
            err.contains("warning") && err.contains("4 of 4 paths reached 100000"),
            warned,
            "sigma_s {sigma}, camera at z = {camera_z}: {err}"
        );
        if !warned {
            assert!(!err.contains("paths reached"), "{err}");
        }
    }
}

/// `isolux render` of `scene` to `out` at 4 x 3 pixels and 4 spp,
/// real-time or path traced: it must succeed and write `out`; returns
/// its standard error.
fn render_small(scene: &Path, out: &Path, realtime: bool) -> String {
    let mut cmd = isolux();
    cmd.args([
        "render", "--spp", "4", "--width", "4", "--height", "3", "-o",
    ])
    .arg(out)
    .arg(scene);
    if realtime {
        cmd.arg("--realtime");
    }
    let o = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(out.exists());
    err
}

/// `isolux render` names a random-walk medium whose mean free path spans
/// fewer than ten of the CPU's ray offsets (`lamplit-milk.toml`'s milk
/// at `scale = 1e7`, 2% dark: docs/subsurface.md, "Media too thick for
/// the walk"), and not at the example's own scale, nor in the real-time
/// mode, which walks no medium.
#[test]
fn a_medium_finer_than_the_ray_offset_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string(example("scenes/lamplit-milk.toml")).unwrap();
    let line = "scale = 10.0          # 1 scene unit = 10 mm";
    assert!(src.contains(line));
    let thick = src.replacen(line, "scale = 1e7", 1);
    for (src, realtime, warned) in [
        (&thick, false, true),
        (&src, false, false),
        (&thick, true, false),
    ] {
        let scene = write_scene(dir.path(), src);
        let err = render_small(&scene, &dir.path().join("out.png"), realtime);
        let named = format!(
            "warning: {}: the random-walk medium of object[0] (material \"milk\") has a mean \
             free path of 5.22e-8 units",
            scene.display()
        );
        assert_eq!(
            err.contains(&named)
                && err.contains("at which the CPU starts rays off its surface")
                && err.contains("model it as `mode = \"dipole\"`"),
            warned,
            "realtime {realtime}: {err}"
        );
        if !warned {
            assert!(!err.contains("mean free path"), "{err}");
        }
    }
}

/// `render --realtime` warns where the real-time mode leaves out a
/// medium's volume (`isolux_render::realtime::volume_left_out`): the
/// stones under `shallows.toml`'s water, hidden by its opaque boundary;
/// the image is still written. The path tracer is not warned.
#[test]
fn realtime_warns_about_volumes_it_leaves_out() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("scenes/shallows.toml");
    let out = dir.path().join("s.png");
    for (realtime, warned) in [(true, true), (false, false)] {
        let err = render_small(&scene, &out, realtime);
        assert_eq!(
            err.contains("lies inside the random-walk medium of object[0]"),
            warned,
            "{err}"
        );
        std::fs::remove_file(&out).unwrap();
    }
}
