//! Reading the directory `isolux factor` writes (`p.exr`, `q.exr`,
//! `r.exr` when `hd_res > 0`, `factors.toml`) into a [`Factored`] material. The layout is documented
//! in `docs/factorization.md`; the writer lives in `isolux-factor`.

use isolux_core::Rgb;
use isolux_materials::Factored;
use std::path::Path;

/// Loads a factored BRDF directory. Errors name the file and the field.
pub fn load_factored(dir: &Path) -> Result<Factored, String> {
    let meta_path = dir.join("factors.toml");
    let text = std::fs::read_to_string(&meta_path)
        .map_err(|e| format!("{}: cannot read: {e}", meta_path.display()))?;
    let meta: toml::Table =
        toml::from_str(&text).map_err(|e| format!("{}: {e}", meta_path.display()))?;
    let field = |k: &str| {
        meta.get(k)
            .ok_or_else(|| format!("{}: missing field `{k}`", meta_path.display()))
    };
    let res = field("res")?
        .as_integer()
        .filter(|r| *r > 0)
        .ok_or_else(|| format!("{}: `res` must be a positive integer", meta_path.display()))?
        as usize;
    let scale = field("scale")?
        .as_array()
        .filter(|a| a.len() == 3)
        .and_then(|a| {
            let v: Option<Vec<f64>> = a
                .iter()
                .map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
                .collect();
            v
        })
        .ok_or_else(|| {
            format!(
                "{}: `scale` must be an array of three numbers",
                meta_path.display()
            )
        })?;
    // `hd_res` is absent in directories written before the r factor.
    let hd_res = match meta.get("hd_res") {
        None => 0,
        Some(v) => v.as_integer().filter(|r| *r >= 0).ok_or_else(|| {
            format!(
                "{}: `hd_res` must be a non-negative integer",
                meta_path.display()
            )
        })? as usize,
    };
    let read = |name: &str, res: usize| -> Result<Vec<Rgb>, String> {
        let path = dir.join(name);
        let img = isolux_io::read_rgb_image(&path).map_err(|e| e.to_string())?;
        if img.width != res || img.height != res {
            return Err(format!(
                "{}: {} x {} pixels, but factors.toml says {} = {res}",
                path.display(),
                img.width,
                img.height,
                if name == "r.exr" { "hd_res" } else { "res" }
            ));
        }
        Ok(img
            .pixels
            .iter()
            .map(|p| Rgb::new(p[0] as f64, p[1] as f64, p[2] as f64))
            .collect())
    };
    let (p, q) = (read("p.exr", res)?, read("q.exr", res)?);
    let m = Factored::new(res, &p, &q, Rgb::new(scale[0], scale[1], scale[2]))
        .map_err(|e| format!("{}: {e}", dir.display()))?;
    if hd_res == 0 {
        return Ok(m);
    }
    let r = read("r.exr", hd_res)?;
    m.with_hd(hd_res, &r)
        .map_err(|e| format!("{}: {e}", dir.join("r.exr").display()))
}
