//! The environment map's tables on the GPU: the texels with their
//! sampling density and CDFs for the path tracer ([`env_tables`]), and the
//! prefiltered pyramid of the real-time mode ([`env_levels`]).

use crate::GpuError;
use isolux_core::{Rgb, PI};
use isolux_render::Environment;

/// Texels with their density in `(u, v)` (`w`), and the CDFs: the marginal
/// over rows (`h + 1` values), then each row's conditional (`w + 1`),
/// from the weights `luminance sin(theta)` of the CPU's sampler.
pub(super) fn env_tables(width: usize, height: usize, texels: &[Rgb]) -> (Vec<[f32; 4]>, Vec<f32>) {
    let mut w = vec![0.0f64; width * height];
    for y in 0..height {
        let sin_t = (PI * (y as f64 + 0.5) / height as f64).sin();
        for x in 0..width {
            w[y * width + x] = texels[y * width + x].luminance().max(0.0) * sin_t;
        }
    }
    let total: f64 = w.iter().sum();
    let avg = total / (width * height) as f64;
    let tex = texels
        .iter()
        .zip(&w)
        .map(|(t, &wi)| {
            let pdf = if avg > 0.0 { wi / avg } else { 0.0 };
            [t.r as f32, t.g as f32, t.b as f32, pdf as f32]
        })
        .collect();
    let mut cdf = Vec::with_capacity(height + 1 + height * (width + 1));
    let rows: Vec<f64> = (0..height)
        .map(|y| w[y * width..(y + 1) * width].iter().sum())
        .collect();
    let mut acc = 0.0;
    cdf.push(0.0);
    for (y, r) in rows.iter().enumerate() {
        acc += r;
        cdf.push(if total > 0.0 {
            (acc / total) as f32
        } else {
            (y + 1) as f32 / height as f32
        });
    }
    *cdf.last_mut().unwrap() = 1.0;
    for (y, &r) in rows.iter().enumerate() {
        let mut acc = 0.0;
        cdf.push(0.0);
        for x in 0..width {
            acc += w[y * width + x];
            cdf.push(if r > 0.0 {
                (acc / r) as f32
            } else {
                (x + 1) as f32 / width as f32
            });
        }
        *cdf.last_mut().unwrap() = 1.0;
    }
    (tex, cdf)
}

/// Level headers in the pyramid buffer (`realtime.wgsl`): maps up to
/// 2^15 texels wide.
const ENV_LEVEL_HEADERS: usize = 16;

/// The prefiltered environment pyramid of the real-time mode, built by the
/// CPU's [`isolux_render::realtime::PrefilteredEnv`]: headers `(offset,
/// width, height, 0)`, then the levels' texels as f32 bits.
/// Returns the buffer and the number of levels.
pub(super) fn env_levels(env: &Environment) -> Result<(Vec<[u32; 4]>, u32), GpuError> {
    let Environment::Map(m) = env else {
        return Ok((Vec::new(), 0));
    };
    let p = isolux_render::realtime::PrefilteredEnv::new(m);
    if p.levels().len() > ENV_LEVEL_HEADERS {
        return Err(GpuError::Setup(format!(
            "environment map of {} x {} texels is too large for the real-time mode's \
             pyramid (at most 32768 texels across)",
            m.size().0,
            m.size().1
        )));
    }
    let mut out = vec![[0u32; 4]; ENV_LEVEL_HEADERS];
    let mut offset = 0u32;
    for (k, l) in p.levels().iter().enumerate() {
        out[k] = [offset, l.width as u32, l.height as u32, 0];
        offset += (l.width * l.height) as u32;
    }
    for l in p.levels() {
        out.extend(
            l.texels
                .iter()
                .map(|t| [t.r as f32, t.g as f32, t.b as f32, 0.0].map(f32::to_bits)),
        );
    }
    Ok((out, p.levels().len() as u32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn env_tables_are_normalized_cdfs_and_densities() {
        let (w, h) = (7, 5);
        let texels: Vec<Rgb> = (0..w * h)
            .map(|i| Rgb::splat(((i * 37) % 11) as f64))
            .collect();
        let (tex, cdf) = env_tables(w, h, &texels);
        // The density integrates to 1 over the unit square.
        let s: f64 = tex.iter().map(|t| t[3] as f64).sum::<f64>() / (w * h) as f64;
        assert!((s - 1.0).abs() < 1e-5, "{s}");
        // Each CDF starts at 0, ends at 1 and never decreases.
        let check = |c: &[f32]| {
            assert_eq!(c[0], 0.0);
            assert_eq!(*c.last().unwrap(), 1.0);
            assert!(c.windows(2).all(|p| p[0] <= p[1]));
        };
        check(&cdf[..h + 1]);
        for y in 0..h {
            let row = &cdf[h + 1 + y * (w + 1)..h + 1 + (y + 1) * (w + 1)];
            check(row);
            // The probability of texel (x, y) is its density / (w h).
            for x in 0..w {
                let p = (cdf[y + 1] - cdf[y]) as f64 * (row[x + 1] - row[x]) as f64;
                let want = tex[y * w + x][3] as f64 / (w * h) as f64;
                assert!((p - want).abs() < 1e-6, "{x} {y} {p} {want}");
            }
        }
    }
}
