//! Every ` ```toml ` block of the README and `docs/` is a scene, or a part of
//! one, that the parser accepts as written: a user copying a snippet from
//! the documentation gets a scene that loads, not an "unknown key".
//!
//! A block with a `[camera]` is a whole scene; any other block is completed
//! with a camera and an object that uses its first material. Paths resolve
//! against `examples/scenes/`, as in the examples. A snippet that names a
//! file the reader supplies (`dir = "/tmp/ct-factors"`, a MERL file) may fail
//! only on reading that file, which means every key before it was accepted.
//!
//! The same holds for the scene snippet and the parameter table that open
//! each material model's file in `isolux-materials`: the snippet parses, and
//! the table names exactly the keys the parser accepts for that type; and
//! for the tables of docs/scene-format.md, one per section of a scene.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The files of `dir` with extension `ext`, sorted.
fn files_ending(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    files.sort();
    files
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
    files.extend(files_ending(&root().join("docs"), "md"));
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

/// The module doc of a Rust file (`//!` lines, the marker removed).
fn module_doc(src: &str) -> Vec<String> {
    src.lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .map(|l| l.strip_prefix(' ').unwrap_or(l).to_string())
        .collect()
}

/// The keys a parameter table names: the backquoted identifiers of each
/// row's first cell, or of its second where the first is `Fresnel` (whose
/// keys are listed there).
fn table_keys(doc: &[String]) -> BTreeSet<String> {
    let mut keys = BTreeSet::new();
    for row in doc.iter().filter(|l| l.starts_with("| ")) {
        let cells: Vec<&str> = row.trim_matches('|').split('|').map(str::trim).collect();
        if cells[0] == "name" {
            continue;
        }
        let cell = if cells[0] == "Fresnel" {
            cells[1]
        } else {
            cells[0]
        };
        for (k, part) in cell.split('`').enumerate() {
            let ident = !part.is_empty()
                && part
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
            if k % 2 == 1 && ident {
                keys.insert(part.to_string());
            }
        }
    }
    keys
}

/// The key the probes add, which no table accepts.
const NOT_A_KEY: &str = "zzz_not_a_key = 1\n";

/// The keys the parser accepts in the table where `probe` puts
/// [`NOT_A_KEY`], read from its error for that key.
fn valid_keys(probe: &str, dir: &Path) -> BTreeSet<String> {
    let e = isolux_scene::parse_str(probe, Path::new("probe"), dir)
        .unwrap_err()
        .to_string();
    let list = e
        .split("valid keys here: ")
        .nth(1)
        .and_then(|rest| rest.split(')').next())
        .unwrap_or_else(|| panic!("no list of valid keys in: {e}"));
    list.split(',').map(|k| k.trim().to_string()).collect()
}

/// The keys the parser accepts in the last `[[material]]` of `block`,
/// `name` and `type` aside.
fn accepted_keys(block: &str, dir: &Path) -> BTreeSet<String> {
    let probe = as_scene(&format!("{}\n{NOT_A_KEY}", block.trim_end()));
    let mut keys = valid_keys(&probe, dir);
    keys.retain(|k| k != "name" && k != "type");
    keys
}

#[test]
fn every_material_doc_parses_and_its_table_names_the_accepted_keys() {
    let src_dir = root().join("crates/materials/src");
    let scenes = root().join("examples/scenes");
    let files = files_ending(&src_dir, "rs");
    let mut checked = Vec::new();
    let mut failures = Vec::new();
    for file in &files {
        let name = file.file_name().unwrap().to_string_lossy().to_string();
        let doc = module_doc(&std::fs::read_to_string(file).unwrap());
        // A model's file has a parameter table; lib.rs's table lists the
        // models, microfacet.rs has none.
        if !doc
            .iter()
            .any(|l| l.starts_with("| name | type | default |"))
        {
            continue;
        }
        let keys = table_keys(&doc);
        let text = doc.join("\n");
        let Some(block) = text
            .split("r#\"")
            .nth(1)
            .and_then(|rest| rest.split("\"#").next())
        else {
            failures.push(format!("{name}: a parameter table but no scene snippet"));
            continue;
        };
        match isolux_scene::parse_str(&as_scene(block), Path::new("snippet"), &scenes) {
            Ok(_) => {}
            Err(e) if e.to_string().contains("cannot read: No such file") => {}
            Err(e) => failures.push(format!("{name}: its snippet: {e}")),
        }
        let accepted = accepted_keys(block, &scenes);
        let undocumented: Vec<_> = accepted.difference(&keys).collect();
        let unknown: Vec<_> = keys.difference(&accepted).collect();
        if !undocumented.is_empty() || !unknown.is_empty() {
            failures.push(format!(
                "{name}: accepted but not in the table: {undocumented:?}; in the table but not accepted: {unknown:?}"
            ));
        }
        checked.push(name);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // The 18 model files when this test was written.
    assert!(checked.len() >= 18, "only {checked:?}");
}

#[test]
fn table_keys_reads_names_and_fresnel_rows() {
    let doc: Vec<String> = [
        "| name | type | default | meaning |",
        "|---|---|---|---|",
        "| `roughness_u`, `roughness_v` | numbers > 0 | | `alpha_x` |",
        "| Fresnel | `metal`, `eta` + `k` | none (`F = 1`) | see [`crate::fresnel`] |",
        "| `metal` / `ior` | string | none | `\"Au\"` |",
    ]
    .map(String::from)
    .to_vec();
    let keys: Vec<String> = table_keys(&doc).into_iter().collect();
    assert_eq!(
        keys,
        ["eta", "ior", "k", "metal", "roughness_u", "roughness_v"]
    );
}

/// The keys of the first `| key | type | default | meaning |` table under
/// the heading `heading` of `doc`.
fn section_keys(doc: &str, heading: &str) -> BTreeSet<String> {
    let lines: Vec<String> = doc
        .lines()
        .skip_while(|l| l.trim_start_matches('#').trim() != heading)
        .skip(1)
        .take_while(|l| !l.starts_with('#'))
        .map(String::from)
        .collect();
    assert!(!lines.is_empty(), "no section {heading}");
    let table: Vec<String> = lines
        .into_iter()
        .skip_while(|l| !l.starts_with("| key |"))
        .skip(1)
        .take_while(|l| l.starts_with('|'))
        .collect();
    table_keys(&table)
}

/// The keys the parser accepts in the table that `scene` ends with.
fn accepted_in(scene: &str) -> BTreeSet<String> {
    valid_keys(&format!("{scene}{NOT_A_KEY}"), Path::new("."))
}

/// docs/scene-format.md's tables of the scene's sections name exactly the
/// keys the parser accepts there.
#[test]
fn scene_format_tables_name_the_accepted_keys() {
    let doc = std::fs::read_to_string(root().join("docs/scene-format.md")).unwrap();
    let camera = "[camera]\nposition = [0.0, 1.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n";
    let object = "[[material]]\nname = \"m\"\ntype = \"diffuse\"\n\n[[object]]\nmaterial = \"m\"\n\
                  base = { type = \"sphere\", center = [0.0, 0.0, 0.0], radius = 1.0 }\n";
    let sections: [(&str, Vec<String>); 8] = [
        ("`[camera]`", vec![camera.to_string()]),
        ("`[film]`", vec![format!("{camera}[film]\n")]),
        ("`[integrator]`", vec![format!("{camera}[integrator]\n")]),
        (
            "`[[light]]`",
            vec![format!(
                "{camera}[[light]]\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = [1.0, 1.0, 1.0]\n"
            )],
        ),
        // The union over both types: `file` and `scale` belong to maps.
        (
            "`[environment]`",
            vec![
                format!("{camera}[environment]\ntype = \"constant\"\nradiance = [1.0, 1.0, 1.0]\n"),
                format!("{camera}[environment]\ntype = \"map\"\n"),
            ],
        ),
        ("`[[object]]`", vec![format!("{camera}{object}")]),
        (
            "`[[object.perturbation]]`",
            vec![format!(
                "{camera}{object}[[object.perturbation]]\nfactor = 1.0\n"
            )],
        ),
        (
            "Transform tables",
            vec![format!("{camera}{object}[object.transform]\n")],
        ),
    ];
    let mut failures = Vec::new();
    for (heading, probes) in sections {
        let documented = section_keys(&doc, heading);
        let accepted: BTreeSet<String> = probes.iter().flat_map(|p| accepted_in(p)).collect();
        if documented != accepted {
            failures.push(format!(
                "{heading}: accepted but not in the table: {:?}; in the table but not accepted: {:?}",
                accepted.difference(&documented).collect::<Vec<_>>(),
                documented.difference(&accepted).collect::<Vec<_>>()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
