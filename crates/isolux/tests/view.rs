//! `isolux view` end to end: the viewer starts under Xvfb (a virtual X
//! server) on whatever adapter exists (lavapipe in CI), draws a few frames
//! of an analytic scene and saves a screenshot, which is checked against
//! the closed form: a diffuse sphere of albedo 0.5 under a constant sky of
//! radiance 1 is 0.5 on every pixel it covers and the sky 1 elsewhere, and
//! it covers the projected disk of angular radius `asin(r / d)`.
//!
//! Outside CI, a machine without `xvfb-run` or without an adapter skips
//! the window test (saying so); under CI (`CI` set, as `.ci/run` installs
//! both) it fails instead.

use std::path::Path;
use std::process::Command;

const SPHERE: &str = r#"
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov_y = 40.0

[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]

[[material]]
name = "grey"
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]

[[object]]
material = "grey"
base = { type = "sphere", center = [0.0, 0.0, 0.0], radius = 1.0 }
"#;

fn isolux() -> Command {
    Command::new(env!("CARGO_BIN_EXE_isolux"))
}

fn have_xvfb() -> bool {
    Command::new("sh")
        .args(["-c", "command -v xvfb-run"])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Runs `isolux view SCENE` under Xvfb with `flags`, saving a screenshot
/// to `shot`; its output, or None (saying so) when this machine has no
/// adapter outside CI.
fn view_under_xvfb(scene: &Path, flags: &[&str], shot: &Path) -> Option<std::process::Output> {
    let o = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1024x768x24"])
        .arg(env!("CARGO_BIN_EXE_isolux"))
        .arg("view")
        .arg(scene)
        .args(flags)
        .arg("--screenshot")
        .arg(shot)
        .output()
        .expect("xvfb-run starts");
    let err = String::from_utf8_lossy(&o.stderr);
    if err.contains("no GPU adapter found") && std::env::var_os("CI").is_none() {
        eprintln!("skipped: no GPU adapter");
        return None;
    }
    Some(o)
}

/// Runs the viewer under Xvfb in `mode`; the screenshot's path, or None
/// when this machine cannot run it (outside CI).
fn view_screenshot(dir: &Path, mode: &str) -> Option<isolux_io::RgbImage> {
    let scene = dir.join(format!("sphere-{mode}.toml"));
    std::fs::write(&scene, SPHERE).unwrap();
    let shot = dir.join(format!("shot-{mode}.exr"));
    let flags = [
        "--width", "600", "--height", "200", "--frames", "3", "--mode", mode,
    ];
    let o = view_under_xvfb(&scene, &flags, &shot)?;
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success(),
        "isolux view --mode {mode} failed: {err}"
    );
    Some(isolux_io::read_rgb_image(&shot).unwrap())
}

fn check_sphere(img: &isolux_io::RgbImage, mode: &str) {
    let (w, h) = (img.width, img.height);
    // The window is 600 wide with a side panel: the image area is what
    // is left of it.
    assert!((160..600).contains(&w) && h == 200, "{mode}: {w} x {h}");
    let (mut sky, mut sphere, mut other) = (0usize, 0usize, 0usize);
    for p in &img.pixels {
        assert!(p.iter().all(|c| c.is_finite()), "{mode}: {p:?}");
        if p.iter().all(|&c| (c - 1.0).abs() < 1e-3) {
            sky += 1;
        } else if p.iter().all(|&c| (c - 0.5).abs() < 2e-3) {
            sphere += 1;
        } else {
            other += 1;
        }
    }
    // Projected disk: radius tan(asin(1/4)) / tan(20 deg) of half the height.
    let rad = (0.25f64.asin().tan() / 20f64.to_radians().tan()) * h as f64 / 2.0;
    let disk = std::f64::consts::PI * rad * rad;
    let covered = sphere as f64 + other as f64 / 2.0;
    assert!(
        (covered / disk - 1.0).abs() < 0.03,
        "{mode}: sphere covers {covered} pixels, the disk {disk} (sky {sky}, sphere {sphere}, other {other}, {w} x {h})"
    );
    // Only the silhouette's pixels mix sphere and sky.
    assert!(
        (other as f64) < 4.0 * 2.0 * std::f64::consts::PI * rad,
        "{mode}: {other} pixels are neither 0.5 nor 1 (sky {sky}, sphere {sphere})"
    );
    assert!(sky > 0 && sphere > 0, "{mode}: blank screenshot");
}

#[test]
fn viewer_under_xvfb_shows_the_analytic_sphere_in_both_modes() {
    if !have_xvfb() {
        assert!(
            std::env::var_os("CI").is_none(),
            "xvfb-run is missing (bash .ci/run installs it)"
        );
        eprintln!("skipped: no xvfb-run");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().to_path_buf();
    // The two runs in parallel: each spends most of its time compiling
    // its kernel on lavapipe.
    let realtime = std::thread::spawn({
        let path = path.clone();
        move || view_screenshot(&path, "realtime")
    });
    let traced = view_screenshot(&path, "path");
    let realtime = realtime.join().unwrap();
    for (img, mode) in [(realtime, "realtime"), (traced, "path")] {
        if let Some(img) = img {
            check_sphere(&img, mode);
        }
    }
}

#[test]
fn viewer_without_a_display_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(&scene, SPHERE).unwrap();
    let o = isolux()
        .arg("view")
        .arg(&scene)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("no display") && err.contains("xvfb-run"),
        "{err}"
    );
}

/// `isolux view` warns, as `isolux render --gpu` does, of a random-walk
/// medium finer than the GPU's ray offset (`lamplit-milk.toml`'s milk at
/// `scale = 1e4`: docs/subsurface.md, "Media too thick for the walk"),
/// before it looks for a display; not of the example as it is.
#[test]
fn viewer_warns_of_a_medium_finer_than_the_ray_offset() {
    let dir = tempfile::tempdir().unwrap();
    let example = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/scenes/lamplit-milk.toml"
    );
    let src = std::fs::read_to_string(example).unwrap();
    let line = "scale = 10.0          # 1 scene unit = 10 mm";
    assert!(src.contains(line));
    for (text, warned) in [
        (src.replacen(line, "scale = 1e4", 1), true),
        (src.clone(), false),
    ] {
        let scene = dir.path().join("milk.toml");
        std::fs::write(&scene, text).unwrap();
        let o = isolux()
            .arg("view")
            .arg(&scene)
            .env_remove("DISPLAY")
            .env_remove("WAYLAND_DISPLAY")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains("no display"), "{err}");
        assert_eq!(
            err.contains("warning")
                && err.contains("the random-walk medium of object[0] (material \"milk\")")
                && err.contains("at which the GPU starts rays"),
            warned,
            "{err}"
        );
    }
}

#[test]
fn viewer_refuses_bad_flags() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(&scene, SPHERE).unwrap();
    for (flags, want) in [
        (
            &["--realtime-spp", "30"][..],
            "--realtime-spp must lie in 4..=25",
        ),
        (
            &["--frames", "2", "--screenshot", "x.bmp"][..],
            "unknown screenshot format",
        ),
        (
            &["--max-spp", "0"][..],
            "--max-spp must lie in 1..=1048576, got 0",
        ),
        (
            &["--max-spp", "4294967295"][..],
            "--max-spp must lie in 1..=1048576, got 4294967295",
        ),
        (
            &["--width", "100000"][..],
            "--width must lie in 364..=16384 pixels, got 100000",
        ),
        // Narrower, the side panel left the image no room.
        (
            &["--width", "200"][..],
            "--width must lie in 364..=16384 pixels, got 200",
        ),
        (
            &["--height", "8"][..],
            "--height must lie in 64..=16384 pixels, got 8",
        ),
    ] {
        let o = isolux()
            .arg("view")
            .arg(&scene)
            .args(flags)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{flags:?}: {err}");
        assert!(err.contains(want), "{flags:?}: {err}");
    }
    // A missing scene names the file.
    let o = isolux().args(["view", "nope.toml"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("nope.toml") && o.status.code() == Some(1),
        "{err}"
    );
}

/// A bump that dwarfs its base quadric (a support of radius 200 and factor
/// 3000 around a sphere of radius 0.45: a shell around the camera) is
/// intersected in f64 by the viewer as by `render --gpu`, which says so,
/// naming the object (`Gpu::precision_for`; docs/gpu.md, "Precision").
#[test]
fn viewer_intersects_ill_conditioned_bumps_in_f64() {
    if !have_xvfb() {
        eprintln!("skipped: no xvfb-run");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("shell.toml");
    std::fs::write(
        &scene,
        r#"
[camera]
position = [0.0, 3.4, 7.2]
look_at = [0.0, -0.15, 0.0]
[[light]]
type = "point"
position = [-3.0, 6.0, 5.0]
intensity = [45.0, 45.0, 45.0]
[[material]]
name = "copper"
type = "beckmann"
roughness = 0.25
metal = "Cu"
[[object]]
material = "copper"
base = { type = "sphere", center = [-2.5, 0.0, 0.0], radius = 0.45 }
[[object.perturbation]]
quadric = { type = "sphere", center = [-2.5, 0.45, 0.0], radius = 200 }
factor = 3000.0
"#,
    )
    .unwrap();
    let shot = dir.path().join("shot.png");
    let flags = [
        "--width", "480", "--height", "120", "--frames", "2", "--mode", "realtime",
    ];
    let Some(o) = view_under_xvfb(&scene, &flags, &shot) else {
        return;
    };
    let err = String::from_utf8_lossy(&o.stderr);
    if err.contains("does not offer f64 in shaders") {
        // An adapter without SHADER_F64 refuses the scene instead.
        assert!(!o.status.success() && !shot.exists(), "{err}");
        return;
    }
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("object[0]: perturbation 0 adds f Q^3") && err.contains("intersecting in f64"),
        "{err}"
    );
    assert!(shot.exists());
}
