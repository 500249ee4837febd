//! `isolux factor` end to end: files, the `factored` scene material
//! against its source in a render, and bad input.

use std::path::Path;
use std::process::Command;

fn isolux() -> Command {
    Command::new(env!("CARGO_BIN_EXE_isolux"))
}

const MATERIALS: &str = r#"
[[material]]
name = "ct"
type = "cook_torrance"
roughness = 0.3
distribution = "beckmann"
schlick = [0.05, 0.05, 0.05]
reflectance = [0.3, 0.3, 0.3]

[[material]]
name = "glass"
type = "dielectric"
"#;

/// A sphere lit by a point light only (direct light: one bounce is all a
/// BRDF comparison needs), with the material named `m`.
fn scene(material: &str) -> String {
    format!(
        r#"
[camera]
position = [0.0, 0.0, 3.6]
look_at = [0.0, 0.0, 0.0]
fov_y = 38.0
[film]
width = 48
height = 48
spp = 64
[integrator]
max_depth = 1
seed = 3
[[light]]
type = "point"
position = [2.0, 2.5, 4.0]
intensity = [20.0, 20.0, 20.0]
{material}
[[object]]
material = "m"
base = {{ type = "sphere", center = [0.0, 0.0, 0.0], radius = 1.0 }}
"#
    )
}

fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn render(dir: &Path, name: &str, src: &str) -> Vec<[f32; 3]> {
    let s = dir.join(format!("{name}.toml"));
    std::fs::write(&s, src).unwrap();
    let out = dir.join(format!("{name}.exr"));
    run_ok(isolux().args(["render", s.to_str().unwrap(), "-o", out.to_str().unwrap()]));
    isolux_io::read_rgb_image(&out).unwrap().pixels
}

#[test]
fn factored_material_renders_like_its_source() {
    let dir = tempfile::tempdir().unwrap();
    let mats = dir.path().join("materials.toml");
    std::fs::write(&mats, MATERIALS).unwrap();
    let fdir = dir.path().join("ct-factors");
    let table = run_ok(isolux().args([
        "factor",
        mats.to_str().unwrap(),
        "--material",
        "ct",
        "--fit-samples",
        "100000",
        "--held-out",
        "10000",
        "-o",
        fdir.to_str().unwrap(),
    ]));
    assert!(
        table.contains("homomorphic") && table.contains("SVD rank 1"),
        "{table}"
    );
    for f in ["p.exr", "q.exr", "r.exr", "factors.toml", "preview.png"] {
        assert!(fdir.join(f).is_file(), "{f} missing");
    }
    let direct = render(
        dir.path(),
        "direct",
        &scene(
            r#"[[material]]
name = "m"
type = "cook_torrance"
roughness = 0.3
distribution = "beckmann"
schlick = [0.05, 0.05, 0.05]
reflectance = [0.3, 0.3, 0.3]"#,
        ),
    );
    let factored = render(
        dir.path(),
        "factored",
        &scene(
            r#"[[material]]
name = "m"
type = "factored"
dir = "ct-factors""#,
        ),
    );
    // Over the lit pixels: the mean differs by under 1% and the mean
    // absolute per-pixel difference is under 3% of the mean (measured with
    // the default r(theta_h, theta_d) table: -0.15% and 0.78%, held-out
    // relative RMS 0.027; the paper's plain p q p gave -0.8% and 6.4%).
    let lum = |p: &[f32; 3]| (p[0] + p[1] + p[2]) as f64 / 3.0;
    let (mut sd, mut sf, mut sabs, mut n) = (0.0, 0.0, 0.0, 0);
    for (a, b) in direct.iter().zip(&factored) {
        let (x, y) = (lum(a), lum(b));
        assert!(y.is_finite());
        if x > 1e-3 {
            sd += x;
            sf += y;
            sabs += (x - y).abs();
            n += 1;
        }
    }
    assert!(n > 500, "{n} lit pixels");
    let mean_rel = (sf - sd) / sd;
    let abs_rel = sabs / sd;
    eprintln!("mean {mean_rel:+.4}, mean abs {abs_rel:.4}");
    assert!(mean_rel.abs() < 0.01, "mean differs by {mean_rel}");
    assert!(abs_rel < 0.03, "mean absolute difference {abs_rel}");
}

/// Materials with a delta lobe beside a finite BRDF: a smooth `plastic`
/// and a `subsurface` medium (whose local approximation, `subsurface_brdf`,
/// is factored). `factor` used to refuse both as "delta" materials; it now
/// factors the finite part and says what it leaves out: the coat's mirror
/// reflection, `((n - 1) / (n + 1))^2` at normal incidence (0.040 for
/// `ior = 1.5`, 0.017 for marble's 1.3), also in `factors.toml`'s `source`.
/// Under a point light (which no delta lobe reaches) the factored material
/// renders like its source: the finite part is all the light there is.
#[test]
fn coated_materials_factor_their_finite_part() {
    let dir = tempfile::tempdir().unwrap();
    let mats = dir.path().join("coated.toml");
    let plastic = r#"[[material]]
name = "m"
type = "plastic"
reflectance = [0.6, 0.3, 0.2]
ior = 1.5"#;
    let marble = r#"[[material]]
name = "m"
type = "subsurface"
medium = "marble"
scale = 20.0"#;
    // What the factors are compared with: the material itself, and for
    // the medium its local approximation (the path-traced BSSRDF spreads
    // light across the surface, which no BRDF does).
    let marble_brdf = marble.replace("\"subsurface\"", "\"subsurface_brdf\"");
    for (name, material, reference, delta) in [
        ("plastic", plastic, plastic, "0.040"),
        ("marble", marble, marble_brdf.as_str(), "0.017"),
    ] {
        std::fs::write(&mats, material).unwrap();
        let fdir = dir.path().join(format!("{name}-factors"));
        let out = isolux()
            .args(["factor", mats.to_str().unwrap(), "--material", "m"])
            .args([
                "--fit-samples",
                "60000",
                "--held-out",
                "5000",
                "--no-preview",
            ])
            .args(["-o", fdir.to_str().unwrap()])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {err}");
        assert!(
            err.contains(&format!(
                "a mirror reflection, {delta} of the light at normal incidence"
            )),
            "{name}: {err}"
        );
        let toml = std::fs::read_to_string(fdir.join("factors.toml")).unwrap();
        assert!(
            toml.contains("(finite part; its delta lobe left out)"),
            "{toml}"
        );
        if name == "marble" {
            assert!(toml.contains("m (local approximation)"), "{toml}");
        }
        let direct = render(dir.path(), &format!("{name}-direct"), &scene(reference));
        let factored = render(
            dir.path(),
            &format!("{name}-factored"),
            &scene(&format!(
                "[[material]]\nname = \"m\"\ntype = \"factored\"\ndir = \"{name}-factors\""
            )),
        );
        let lum = |p: &[f32; 3]| (p[0] + p[1] + p[2]) as f64 / 3.0;
        let (mut sd, mut sf, mut sabs) = (0.0, 0.0, 0.0);
        for (a, b) in direct.iter().zip(&factored) {
            assert!(lum(b).is_finite());
            sd += lum(a);
            sf += lum(b);
            sabs += (lum(a) - lum(b)).abs();
        }
        let (mean_rel, abs_rel) = ((sf - sd) / sd, sabs / sd);
        eprintln!("{name}: mean {mean_rel:+.4}, mean abs {abs_rel:.4}");
        assert!(mean_rel.abs() < 0.02, "{name}: mean differs by {mean_rel}");
        assert!(abs_rel < 0.04, "{name}: mean absolute difference {abs_rel}");
    }
}

#[test]
fn factor_bad_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let mats = dir.path().join("materials.toml");
    std::fs::write(&mats, MATERIALS).unwrap();
    let out = dir.path().join("o");
    let o = out.to_str().unwrap();
    let m = mats.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec![m, "--material", "ct", "--res", "3"],
            "--res: must lie in 4..=512, got 3",
        ),
        (
            vec![m, "--material", "ct", "--res", "513"],
            "--res: must lie in 4..=512",
        ),
        (
            vec![m, "--material", "ct", "--theta-max", "95"],
            "--theta-max: must lie in (0, 90]",
        ),
        // Found by scripts/cli-fuzz.py: 2^32 - 1 samples failed to
        // allocate (an abort); that many ranks or refinements ran on.
        (
            vec![m, "--material", "ct", "--fit-samples", "4294967295"],
            "--fit-samples: must be at most 10000000, got 4294967295",
        ),
        (
            vec![m, "--material", "ct", "--held-out", "4294967295"],
            "--held-out: must be at most 10000000",
        ),
        (
            vec![m, "--material", "ct", "--fit-samples", "8"],
            "--fit-samples: must be at least 16, got 8",
        ),
        (
            vec![m, "--material", "ct", "--held-out", "0"],
            "--held-out: must be at least 16, got 0",
        ),
        (
            vec![m, "--material", "ct", "--svd-rank", "4294967295"],
            "--svd-rank: must be at most 32, got 4294967295",
        ),
        (
            vec![m, "--material", "ct", "--refine", "4294967295"],
            "--refine: must be at most 100 iterations, got 4294967295",
        ),
        (vec![m, "--material", "nope"], "no material named \"nope\""),
        (
            vec![m, "--material", "glass"],
            "delta (dielectric) material",
        ),
        (vec!["--material", "ct"], "needs the scene file"),
        (
            vec!["--merl", "/nonexistent/x.binary"],
            "/nonexistent/x.binary: cannot read",
        ),
        (
            vec!["--samples", "/nonexistent/s.csv"],
            "/nonexistent/s.csv: cannot read",
        ),
    ];
    for (args, want) in cases {
        let st = isolux()
            .arg("factor")
            .args(&args)
            .args(["-o", o])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&st.stderr);
        assert_eq!(st.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} left output behind");
    }
    // A truncated MERL file.
    let merl = dir.path().join("short.binary");
    std::fs::write(&merl, [90u8, 0, 0, 0, 90, 0, 0, 0, 180, 0, 0, 0, 1, 2]).unwrap();
    let st = isolux()
        .args(["factor", "--merl", merl.to_str().unwrap(), "-o", o])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("short.binary: truncated MERL file"), "{err}");
    // A scene naming a factored directory that does not exist.
    let s = dir.path().join("bad.toml");
    std::fs::write(
        &s,
        scene("[[material]]\nname = \"m\"\ntype = \"factored\"\ndir = \"missing\""),
    )
    .unwrap();
    let st = isolux()
        .args([
            "render",
            s.to_str().unwrap(),
            "-o",
            dir.path().join("x.png").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(
        err.contains("bad.toml:") && err.contains("factors.toml: cannot read"),
        "{err}"
    );
}
