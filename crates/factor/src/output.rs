//! Writing a factorization: `p.exr`, `q.exr` (linear float RGB,
//! `res x res`, row 0 at the top), `r.exr` (`hd_res x hd_res`, row `k` is
//! `theta_h` texel `k`, column `l` is `theta_d` texel `l`; only when
//! `hd_res > 0`) and `factors.toml`. The reader is
//! `isolux_scene::load_factored`.

use crate::fit::Factorization;
use crate::{FactorError, Report};
use isolux_core::{Image, Rgb};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

fn image(res: usize, texels: &[Rgb]) -> Image {
    debug_assert_eq!(texels.len(), res * res);
    Image {
        width: res as u32,
        height: res as u32,
        rgb: texels
            .iter()
            .map(|c| [c.r as f32, c.g as f32, c.b as f32])
            .collect(),
        aov: None,
    }
}

fn toml_str(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

/// The text of `factors.toml`.
pub fn factors_toml(f: &Factorization, report: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Homomorphic factorization written by isolux factor.");
    let _ = writeln!(
        s,
        "# f(wo, wi) = scale * p(wo) * q(h) * p(wi) * r(theta_h, theta_d), per channel;"
    );
    let _ = writeln!(
        s,
        "# p.exr and q.exr are parabolic maps, r.exr (hd_res > 0) a table over"
    );
    let _ = writeln!(
        s,
        "# (theta_h rows, theta_d columns); all looked up bilinearly in the logarithm."
    );
    let _ = writeln!(s, "res = {}", f.res);
    let _ = writeln!(s, "hd_res = {}", f.hd_res);
    let _ = writeln!(s, "theta_max_deg = {:?}", f.theta_max_deg);
    let _ = writeln!(
        s,
        "scale = [{:e}, {:e}, {:e}]",
        f.scale.r, f.scale.g, f.scale.b
    );
    let _ = writeln!(s, "source = {}", toml_str(&report.source));
    let _ = writeln!(s, "interpolation = \"log-bilinear\"");
    let _ = writeln!(s);
    let _ = writeln!(s, "[fit]");
    let _ = writeln!(s, "smoothness = {:e}", report.smoothness);
    let _ = writeln!(s, "samples = {}", f.stats.samples);
    let _ = writeln!(s, "used = {:?}", f.stats.used);
    let _ = writeln!(s, "excluded = {:?}", f.stats.excluded);
    let _ = writeln!(s, "dynamic_range = {:e}", report.dynamic_range);
    let _ = writeln!(
        s,
        "floor = [{:e}, {:e}, {:e}]",
        f.floor.r, f.floor.g, f.floor.b
    );
    let _ = writeln!(s, "floored = {:?}", f.stats.floored);
    let _ = writeln!(s, "held_out = {}", report.held_out);
    let _ = writeln!(s, "unknowns = {}", f.stats.unknowns);
    let _ = writeln!(s, "cholesky_factorizations = {}", f.stats.factorizations);
    let _ = writeln!(s, "assemble_seconds = {:.4}", f.stats.assemble_s);
    let _ = writeln!(s, "solve_seconds = {:.4}", f.stats.solve_s);
    let _ = writeln!(s);
    let _ = writeln!(s, "[error]");
    let _ = writeln!(s, "relative_rms = {:.6}", report.factored.relative_rms);
    let _ = writeln!(s, "cosine_abs_rms = {:.6}", report.factored.cosine_abs_rms);
    for b in &report.baselines {
        let _ = writeln!(s);
        let _ = writeln!(s, "[[baseline]]");
        let _ = writeln!(s, "method = \"svd\"");
        let _ = writeln!(s, "rank = {}", b.rank);
        let _ = writeln!(s, "storage_texels = {}", b.storage_texels);
        let _ = writeln!(s, "relative_rms = {:.6}", b.metrics.relative_rms);
        let _ = writeln!(s, "cosine_abs_rms = {:.6}", b.metrics.cosine_abs_rms);
    }
    s
}

/// Writes the three files into `dir` (created if needed). Each file is
/// written atomically.
pub fn write_dir(dir: &Path, f: &Factorization, report: &Report) -> Result<(), FactorError> {
    std::fs::create_dir_all(dir).map_err(|e| FactorError::Input {
        what: dir.display().to_string(),
        message: format!("cannot create the directory: {e}"),
    })?;
    isolux_io::write_exr(&dir.join("p.exr"), &image(f.res, &f.p))?;
    isolux_io::write_exr(&dir.join("q.exr"), &image(f.res, &f.q))?;
    let r_path = dir.join("r.exr");
    if f.hd_res > 0 {
        isolux_io::write_exr(&r_path, &image(f.hd_res, &f.r))?;
    } else if r_path.exists() {
        // A stale table from an earlier run must not outlive hd_res = 0.
        std::fs::remove_file(&r_path).map_err(|e| FactorError::Input {
            what: r_path.display().to_string(),
            message: format!("cannot remove the stale file: {e}"),
        })?;
    }
    let text = factors_toml(f, report);
    let path = dir.join("factors.toml");
    isolux_io::atomic_write(&path, |file| {
        file.write_all(text.as_bytes())
            .map_err(|source| isolux_io::IoError::Io {
                path: path.clone(),
                source,
            })
    })?;
    Ok(())
}
