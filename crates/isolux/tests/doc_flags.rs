//! Every flag the README and `docs/` show with a command exists: each
//! `isolux CMD [SUB] ... --flag` (or `cargo run --release -- CMD ...`) is
//! checked against `isolux CMD [SUB] --help`. The command names and flags
//! are a contract with users and their scripts; a renamed flag must take
//! its documentation along.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Commands, and their subcommands where they have some.
const COMMANDS: &[(&str, &[&str])] = &[
    ("render", &[]),
    ("brdf", &["plot", "albedo", "sphere"]),
    ("sss", &["media", "profile"]),
    ("factor", &[]),
    ("heightfield", &["gen"]),
    ("wave", &["brdf"]),
    ("view", &[]),
    ("bench", &["geometry", "sss", "factor", "wave", "gpu"]),
];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Lines with their continuations joined: a trailing `\`, or a usage
/// line that goes on indented with `[--` or `(--`.
fn logical_lines(text: &str) -> Vec<(usize, String)> {
    let mut out: Vec<(usize, String)> = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let t = line.trim_start();
        let continues = line.len() > t.len() && (t.starts_with("[--") || t.starts_with("(--"));
        match out.last_mut() {
            Some((_, prev)) if prev.trim_end().ends_with('\\') || continues => {
                let p = prev.trim_end().trim_end_matches('\\').to_string();
                *prev = format!("{p} {t}");
            }
            _ => out.push((k + 1, line.to_string())),
        }
    }
    out
}

/// The flags (`--name`) of `text`: tokens that start with two dashes and a
/// letter, not inside a longer word.
fn flags(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let b = text.as_bytes();
    let mut i = 0;
    while i + 2 < b.len() {
        let starts = b[i] == b'-'
            && b[i + 1] == b'-'
            && b[i + 2].is_ascii_lowercase()
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'-'));
        if starts {
            let mut j = i + 2;
            while j < b.len() && (b[j].is_ascii_alphanumeric() || b[j] == b'-') {
                j += 1;
            }
            out.push(text[i..j].to_string());
            i = j;
        } else {
            i += 1;
        }
    }
    out
}

/// (command path, flag) -> where it is used, over one file's lines.
fn uses(name: &str, text: &str, found: &mut BTreeMap<(Vec<String>, String), Vec<String>>) {
    for (line_no, line) in logical_lines(text) {
        for prefix in ["isolux ", "cargo run --release -- "] {
            let mut from = 0;
            while let Some(at) = line[from..].find(prefix) {
                let start = from + at + prefix.len();
                from = start;
                let mut words = line[start..].split(' ');
                let Some(&(cmd, subs)) = words
                    .next()
                    .and_then(|w| COMMANDS.iter().find(|(c, _)| *c == w))
                else {
                    continue;
                };
                let mut path = vec![cmd.to_string()];
                let mut rest = start + cmd.len();
                if !subs.is_empty() {
                    match words.next().filter(|w| subs.contains(w)) {
                        Some(sub) => {
                            path.push(sub.to_string());
                            rest += 1 + sub.len();
                        }
                        None => continue,
                    }
                }
                // The command's own text ends at the code span, the table
                // cell, or the next command.
                let tail = &line[rest..];
                let end = ["`", "|", "isolux ", "cargo run"]
                    .iter()
                    .filter_map(|s| tail.find(s))
                    .min()
                    .unwrap_or(tail.len());
                for flag in flags(&tail[..end]) {
                    found
                        .entry((path.clone(), flag))
                        .or_default()
                        .push(format!("{name}:{line_no}"));
                }
            }
        }
    }
}

fn help(path: &[String]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_isolux"))
        .args(path)
        .arg("--help")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "isolux {} --help failed",
        path.join(" ")
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn every_documented_flag_exists() {
    let mut files = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    let mut found = BTreeMap::new();
    for f in &files {
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        uses(&name, &std::fs::read_to_string(f).unwrap(), &mut found);
    }
    let mut helps: BTreeMap<Vec<String>, BTreeSet<String>> = BTreeMap::new();
    let mut missing = Vec::new();
    for ((path, flag), where_) in &found {
        let known = helps
            .entry(path.clone())
            .or_insert_with(|| flags(&help(path)).into_iter().collect());
        if !known.contains(flag) {
            missing.push(format!(
                "isolux {} {flag} (used at {})",
                path.join(" "),
                where_.join(", ")
            ));
        }
    }
    assert!(
        missing.is_empty(),
        "flags not in --help:\n{}",
        missing.join("\n")
    );
    // 65 (command, flag) pairs when this test was written.
    assert!(found.len() >= 50, "only {} uses found", found.len());
}

#[test]
fn the_scanner_finds_flags_and_commands() {
    let mut found = BTreeMap::new();
    let text = "Run `isolux render s.toml --gpu -o x.png` or\n\
                ```\n\
                isolux bench gpu [--width 1920]\n    [--skip-cpu] \\\n  --f64\n\
                cargo run --release -- factor --res 8 | `isolux view --mode path`\n\
                isolux hits | not a command --no\n";
    uses("t.md", text, &mut found);
    let got: Vec<String> = found
        .keys()
        .map(|(p, f)| format!("{} {f}", p.join(" ")))
        .collect();
    assert_eq!(
        got,
        [
            "bench gpu --f64",
            "bench gpu --skip-cpu",
            "bench gpu --width",
            "factor --res",
            "render --gpu",
            "view --mode",
        ]
    );
    assert_eq!(flags("a--b --c-d x---e --9"), ["--c-d"]);
}
