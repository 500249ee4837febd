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
                ("--dynamic-range", "1e-4"),
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
        // As given, each command succeeds: else its extremes test nothing.
        let mut args = case.fixed.clone();
        args.extend(case.flags.iter().map(|(f, v)| format!("{f}={v}")));
        let (code, err, _) = run(&args, Duration::from_secs(60));
        assert_eq!(code, Some(0), "{} with valid values: {err}", case.name);
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

/// The byte ranges of the numbers of a TOML text outside strings and
/// comments.
fn numbers(src: &str) -> Vec<std::ops::Range<usize>> {
    let b = src.as_bytes();
    let mut out = Vec::new();
    let (mut i, mut in_string, mut in_comment) = (0, false, false);
    while i < b.len() {
        let c = b[i];
        if c == b'\n' {
            in_comment = false;
        } else if in_comment {
        } else if c == b'"' {
            in_string = !in_string;
        } else if !in_string && c == b'#' {
            in_comment = true;
        } else if !in_string {
            let starts =
                c.is_ascii_digit() || (c == b'-' && b.get(i + 1).is_some_and(u8::is_ascii_digit));
            let after_word =
                i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_' || b[i - 1] == b'.');
            if starts && !after_word {
                let mut j = i + 1;
                while j < b.len()
                    && (b[j].is_ascii_digit()
                        || b[j] == b'.'
                        || b[j] == b'e'
                        || b[j] == b'E'
                        || ((b[j] == b'-' || b[j] == b'+') && matches!(b[j - 1], b'e' | b'E')))
                {
                    j += 1;
                }
                if src[i..j].parse::<f64>().is_ok() {
                    out.push(i..j);
                }
                i = j;
                continue;
            }
        }
        i += 1;
    }
    out
}

/// Every number of five small example scenes (the furnace, the perturbed
/// sphere, the metals, the translucent marble, the wave grating) at each
/// extreme, rendered at 8 x 6, 1 spp: each variant renders with finite
/// samples, or is refused naming the scene file and line; none panics or
/// hangs, and none accepts NaN or infinity (`scripts/gpu-diff-fuzz.py
/// --cpu-only` draws such variants at random, over every example).
#[test]
fn every_number_of_the_small_examples_at_its_extremes_renders_or_is_refused_by_line() {
    let dir = tempfile::tempdir().unwrap();
    let ex = examples().canonicalize().unwrap();
    let variant = dir.path().join("variant.toml");
    let image = dir.path().join("v.png");
    let args: Vec<String> = [
        "render",
        variant.to_str().unwrap(),
        "-o",
        image.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "6",
        "--spp",
        "1",
        "--quiet",
    ]
    .iter()
    .map(|a| a.to_string())
    .collect();
    let mut problems = Vec::new();
    let mut runs = 0;
    for scene in [
        "furnace.toml",
        "perturbed-sphere.toml",
        "metals.toml",
        "translucent.toml",
        "wave-grating.toml",
    ] {
        let src = std::fs::read_to_string(ex.join("scenes").join(scene))
            .unwrap()
            .replace("\"../", &format!("\"{}/", ex.display()));
        // Unchanged, the scene renders from the temporary directory.
        std::fs::write(&variant, &src).unwrap();
        let (code, err, _) = run(&args, Duration::from_secs(60));
        assert_eq!(code, Some(0), "{scene} as it is: {err}");
        let spots = numbers(&src);
        assert!(spots.len() > 20, "{scene}: {} numbers", spots.len());
        for at in spots {
            let line = src[..at.start].matches('\n').count() + 1;
            for v in EXTREMES {
                let text = format!("{}{v}{}", &src[..at.start], &src[at.end..]);
                std::fs::write(&variant, text).unwrap();
                let _ = std::fs::remove_file(&image);
                let (code, err, timed_out) = run(&args, Duration::from_secs(60));
                runs += 1;
                let what = format!("{scene}:{line}: {} -> {v}", &src[at.clone()]);
                if timed_out {
                    problems.push(format!("{what}: still running after 60 s"));
                } else if err.contains("panicked") || !matches!(code, Some(0 | 1)) {
                    problems.push(format!("{what}: crashed ({code:?}): {err}"));
                } else if code == Some(1) && !err.contains("variant.toml:") {
                    problems.push(format!("{what}: refused without the file and line: {err}"));
                } else if code == Some(1) && image.exists() {
                    problems.push(format!("{what}: failed and left its image"));
                } else if code == Some(0) && err.contains("non-finite") {
                    problems.push(format!("{what}: non-finite samples: {err}"));
                } else if code == Some(0) && (v == "nan" || v == "inf") {
                    problems.push(format!("{what}: accepted"));
                }
            }
        }
    }
    assert!(runs > 1000, "{runs}");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
