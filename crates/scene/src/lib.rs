//! # isolux-scene
//!
//! Reads Isolux scene files (TOML) into a [`isolux_render::Scene`]. The
//! format is documented key by key in `docs/scene-format.md`. Errors name
//! the file, line, column and key path:
//!
//! ```
//! let src = "[film]\nwidth = -3\n";
//! let err = isolux_scene::parse_str(src, "demo.toml".as_ref(), ".".as_ref()).unwrap_err();
//! assert_eq!(err.to_string(), "demo.toml:2:9: film.width: must lie in 1..=65536, got -3");
//! ```
#![warn(missing_docs)]

mod factored_files;
mod reader;
mod schema;

pub use factored_files::load_factored;
pub use reader::SceneError;
pub use schema::{parse_material, parse_str, MATERIAL_CHOICES, MATERIAL_INTEGERS, MATERIAL_TYPES};

use std::path::{Path, PathBuf};

/// Errors loading a scene file.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file could not be read.
    #[error("{path}: cannot read scene file: {source}")]
    Read {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The file's content is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
}

/// Loads a scene file; relative paths inside it (environment maps) are
/// resolved against the file's directory.
pub fn load(path: &Path) -> Result<isolux_render::Scene, LoadError> {
    let src = std::fs::read_to_string(path).map_err(|source| LoadError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    Ok(parse_str(&src, path, dir)?)
}
