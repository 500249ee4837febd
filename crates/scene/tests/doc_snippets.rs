//! Every ` ```toml ` block of the README and `docs/` is a scene, or a part of
//! one, that the parser accepts as written: a user copying a snippet from
//! the documentation gets a scene that loads, not an "unknown key".
//!
//! A block with a `[camera]` is a whole scene; any other block is completed
//! with a camera and an object that uses its first material. Paths resolve
//! against `examples/scenes/`, as in the examples. A snippet that names a
//! file the reader supplies (`dir = "/tmp/ct-factors"`, a MERL file) may fail
//! only on reading that file, which means every key before it was accepted.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The ` ```toml ` blocks of a Markdown file: (first line number, text), each
/// line stripped of the block's common indentation (a block in a list).
fn toml_blocks(text: &str) -> Vec<(usize, String)> {
    let mut blocks = Vec::new();
    let mut current: Option<(usize, Vec<&str>, usize)> = None;
    for (k, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        match current.take() {
            None => {
                if trimmed.starts_with("```toml") {
                    let indent = line.len() - trimmed.len();
                    current = Some((k + 2, Vec::new(), indent));
                }
            }
            Some((start, lines, indent)) => {
                if trimmed.starts_with("```") {
                    let body: Vec<&str> = lines
                        .iter()
                        .map(|l| l.get(indent..).unwrap_or(l.trim_start()))
                        .collect();
                    blocks.push((start, body.join("\n") + "\n"));
                } else {
                    let mut lines = lines;
                    lines.push(line);
                    current = Some((start, lines, indent));
                }
            }
        }
    }
    assert!(current.is_none(), "a ```toml block is never closed");
    blocks
}

/// The block as a whole scene.
fn as_scene(block: &str) -> String {
    if block.contains("[camera]") {
        return block.to_string();
    }
    let name = block
        .lines()
        .find_map(|l| {
            let l = l.trim();
            let rest = l.strip_prefix("name")?.trim_start().strip_prefix('=')?;
            Some(rest.trim().trim_matches('"').to_string())
        })
        .expect("a part of a scene names a material");
    format!(
        "[camera]\nposition = [0.0, 1.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_y = 40.0\n\n{block}\n\
         [[object]]\nmaterial = \"{name}\"\nbase = {{ type = \"sphere\", center = [0.0, 0.0, 0.0], radius = 1.0 }}\n"
    )
}

#[test]
fn every_toml_block_of_the_docs_parses() {
    let mut files = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    let scenes = root().join("examples/scenes");
    let mut checked = 0;
    let mut failures = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        for (line, block) in toml_blocks(&text) {
            let name = format!("{}:{line}", file.file_name().unwrap().to_string_lossy());
            let scene = as_scene(&block);
            checked += 1;
            match isolux_scene::parse_str(&scene, Path::new("snippet"), &scenes) {
                Ok(_) => {}
                // Only the reading of a file the user supplies may fail.
                Err(e) if e.to_string().contains("cannot read: No such file") => {}
                Err(e) => failures.push(format!("{name}: {e}\n{block}")),
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // scene-format.md's example, the wave material, the factored and MERL
    // materials of factorization.md: 4 when this test was written.
    assert!(checked >= 4, "only {checked} blocks found");
}

#[test]
fn blocks_are_found_with_their_indentation_removed() {
    let md = "text\n\n  ```toml\n  [[material]]\n  name = \"a\"\n  ```\n\n```toml\nx = 1\n```\n";
    let blocks = toml_blocks(md);
    assert_eq!(blocks.len(), 2);
    assert_eq!(blocks[0], (4, "[[material]]\nname = \"a\"\n".to_string()));
    assert_eq!(blocks[1], (9, "x = 1\n".to_string()));
    // A block the parser would refuse fails the check.
    let bad = as_scene("[[material]]\nname = \"m\"\ntype = \"diffuse\"\nreflectanse = 0.5\n");
    let e = isolux_scene::parse_str(&bad, Path::new("x.md:1"), Path::new("."))
        .unwrap_err()
        .to_string();
    assert!(e.contains("reflectanse"), "{e}");
}
