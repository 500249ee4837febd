//! Every numeric flag of the CLI at its extremes: the guide's promises for
//! bad input, checked on a fixed table (`scripts/cli-fuzz.py` draws the
//! same kind of values at random, and found the bounds of docs/limits.md).
//!
//! For each command, each flag in turn takes 0, -1, 1e-30, 1e30, 2^32 - 1,
//! NaN and infinity while the others keep small valid values. Whatever the
//! value, the command must end within a minute (a request of hours is
//! refused up front), never panic or die on a signal, fail with a message
//! and no output file, and accept no NaN or infinity.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const EXTREMES: [&str; 7] = ["0", "-1", "1e-30", "1e30", "4294967295", "nan", "inf"];

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples")
}

/// A command: its fixed arguments, its numeric flags with valid values,
/// and the output it writes.
struct Case {
    name: &'static str,
    fixed: Vec<String>,
    flags: Vec<(&'static str, &'static str)>,
    output: PathBuf,
}

fn cases(dir: &Path) -> Vec<Case> {
    let ex = examples();
    let s = |p: PathBuf| p.to_str().unwrap().to_string();
    let sphere = s(ex.join("scenes/perturbed-sphere.toml"));
    let gallery = s(ex.join("scenes/gallery.toml"));
    let grating = s(ex.join("heightfields/grating.exr"));
    let out = |name: &str| dir.join(name);
    let owned = |v: &[&str]| v.iter().map(|a| a.to_string()).collect::<Vec<_>>();
    vec![
        Case {
            name: "render",
            fixed: owned(&["render", &sphere, "--quiet", "-o", &s(out("r.png"))]),
            flags: vec![
                ("--spp", "1"),
                ("--width", "12"),
                ("--height", "8"),
                ("--seed", "3"),
                ("--max-depth", "3"),
                ("--exposure", "0"),
                ("--threads", "2"),
            ],
            output: out("r.png"),
        },
        Case {
            name: "brdf plot",
            fixed: owned(&[
                "brdf",
                "plot",
                &gallery,
                "--material",
                "ggx",
                "-o",
                &s(out("p.svg")),
            ]),
            flags: vec![("--theta-i", "30"), ("--phi-i", "0")],
            output: out("p.svg"),
        },
        Case {
            name: "brdf sphere",
            fixed: owned(&[
                "brdf",
                "sphere",
                &gallery,
                "--material",
                "ward",
                "-o",
                &s(out("s.png")),
            ]),
            flags: vec![("--size", "8")],
            output: out("s.png"),
        },
        Case {
            name: "sss profile",
            fixed: owned(&[
                "sss",
                "profile",
                "--medium",
                "skin1",
                "-o",
                &s(out("sss.svg")),
            ]),
            flags: vec![("--scale", "1"), ("--photons", "500")],
            output: out("sss.svg"),
        },
        Case {
            name: "factor",
            fixed: owned(&[
                "factor",
                &gallery,
                "--material",
                "phong",
                "--no-preview",
                "-o",
                &s(out("f")),
            ]),
            flags: vec![
                ("--res", "4"),
                ("--hd-res", "0"),
                ("--smoothness", "0.001"),
                ("--theta-max", "80"),
                ("--fit-samples", "500"),
                ("--held-out", "100"),
                ("--svd-rank", "1"),
                ("--refine", "1"),
            ],
            output: out("f"),
        },
        Case {
            name: "heightfield gen noise",
            fixed: owned(&[
                "heightfield",
                "gen",
                "--kind",
                "noise",
                "-o",
                &s(out("n.exr")),
            ]),
            flags: vec![
                ("--width", "16"),
                ("--height", "16"),
                ("--texel-um", "0.5"),
                ("--rms-um", "0.1"),
                ("--corr-um", "2"),
            ],
            output: out("n.exr"),
        },
        Case {
            name: "heightfield gen brushed",
            fixed: owned(&[
                "heightfield",
                "gen",
                "--kind",
                "brushed",
                "--width",
                "16",
                "-o",
                &s(out("b.exr")),
            ]),
            flags: vec![
                ("--along-um", "20"),
                ("--across-um", "1"),
                ("--direction-deg", "10"),
            ],
            output: out("b.exr"),
        },
        Case {
            name: "heightfield gen scratches",
            fixed: owned(&[
                "heightfield",
                "gen",
                "--kind",
                "scratches",
                "--width",
                "16",
                "-o",
                &s(out("c.exr")),
            ]),
            flags: vec![
                ("--count", "3"),
                ("--depth-um", "0.2"),
                ("--width-um", "1"),
                ("--length-um", "10"),
            ],
            output: out("c.exr"),
        },
        Case {
            name: "heightfield gen grating",
            fixed: owned(&[
                "heightfield",
                "gen",
                "--kind",
                "grating",
                "--width",
                "16",
                "-o",
                &s(out("g.exr")),
            ]),
            flags: vec![
                ("--period-um", "2"),
                ("--amplitude-um", "0.1"),
                ("--direction-deg", "0"),
            ],
            output: out("g.exr"),
        },
        Case {
            name: "wave brdf",
            fixed: owned(&[
                "wave",
                "brdf",
                "--heightfield",
                &grating,
                "-o",
                &s(out("w.exr")),
            ]),
            flags: vec![
                ("--texel-um", "0.25"),
                ("--vertical-scale", "1"),
                ("--sigma-um", "3"),
                ("--lambda-um", "0.5"),
                ("--res", "8"),
                ("--center-um", "10,10"),
                ("--incident", "0,0.3,1"),
            ],
            output: out("w.exr"),
        },
        Case {
            name: "bench geometry",
            fixed: owned(&["bench", "geometry"]),
            flags: vec![("--size", "4"), ("--bumps", "0,2"), ("--repeat", "1")],
            output: out("none"),
        },
    ]
}

/// Runs `isolux args` for at most `limit`: (exit code, `None` when it died
/// on a signal or was stopped; stderr; whether it was stopped at `limit`).
fn run(args: &[String], limit: Duration) -> (Option<i32>, String, bool) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_isolux"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let timed_out = loop {
        if child.try_wait().unwrap().is_some() {
            break false;
        }
        if start.elapsed() > limit {
            child.kill().unwrap();
            break true;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        timed_out,
    )
}

#[test]
fn every_numeric_flag_at_its_extremes_is_refused_or_done_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let mut problems = Vec::new();
    let mut runs = 0;
    for case in cases(dir.path()) {
        for (flag, _) in &case.flags {
            for v in EXTREMES {
                // The flag at `v` (in one element of a list), the rest valid.
                let mut args = case.fixed.clone();
                for (f, valid) in &case.flags {
                    let value = if f != flag {
                        valid.to_string()
                    } else if valid.contains(',') {
                        let mut parts: Vec<&str> = valid.split(',').collect();
                        parts[0] = v;
                        parts.join(",")
                    } else {
                        v.to_string()
                    };
                    args.push(format!("{f}={value}"));
                }
                let _ = std::fs::remove_file(&case.output);
                let _ = std::fs::remove_dir_all(&case.output);
                let (code, err, timed_out) = run(&args, Duration::from_secs(60));
                runs += 1;
                let what = format!("{} {flag}={v}", case.name);
                let last = err.trim().lines().last().unwrap_or("").to_string();
                if timed_out {
                    problems.push(format!("{what}: still running after 60 s"));
                } else if err.contains("panicked") || code.is_none() || code == Some(101) {
                    problems.push(format!("{what}: crashed ({code:?}): {last}"));
                } else if code != Some(0) {
                    if err.trim().is_empty() {
                        problems.push(format!("{what}: exit {code:?} with no message"));
                    }
                    if case.output.exists() {
                        problems.push(format!("{what}: failed and left its output"));
                    }
                } else if v == "nan" || v == "inf" {
                    problems.push(format!("{what}: accepted"));
                }
            }
        }
    }
    assert!(runs > 250, "{runs}");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
