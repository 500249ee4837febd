//! The baseline: Kautz and McCool's separable approximation (1999),
//! `f(wo, wi) ~= sum_k u_k(h) v_k(d)`, with `h` the half vector and `d`
//! the incident direction in `h`'s frame (Rusinkiewicz's change of
//! variables, the paper's best parameterization), both as parabolic maps
//! of the same resolution as the homomorphic factors.
//!
//! The terms minimize the *absolute* squared error over the valid entries
//! of the `n_v x n_v` matrix of `f` at texel centres (entries whose
//! `wo` or `wi` leave the fit domain, or where a table has no data, are
//! left out rather than zero-filled). Each term is the best rank-1 fit of
//! the residual of the terms before it, found by alternating
//! least-squares sweeps (power iterations; at most 30, fewer once `v`
//! changes by less than 1e-7 relative); with no entry missing this is
//! the truncated SVD (Eckart-Young), with some missing it is the weighted
//! analogue. Factors are signed, as the SVD's are; lookups interpolate
//! bilinearly.

use crate::source::{Sample, Source};
use isolux_core::{DVec3, Rgb};
use isolux_materials::merl::half_diff_vectors;
use isolux_materials::parabolic::ParabolicGrid;
use rayon::prelude::*;

/// A rank-`k` separable approximation, per colour channel.
#[derive(Clone, Debug)]
pub struct Separable {
    grid: ParabolicGrid,
    ord: Vec<u32>,
    /// `u[c][k][t]`, over valid texels.
    u: Vec<Vec<Vec<f64>>>,
    /// `v[c][k][t]`.
    v: Vec<Vec<Vec<f64>>>,
}

/// The inverse of [`half_diff_vectors`]: `(wo, wi)` from `h` and `d`.
pub fn from_half_diff(h: DVec3, d: DVec3) -> (DVec3, DVec3) {
    let (th, ph) = (h.z.clamp(-1.0, 1.0).acos(), h.y.atan2(h.x));
    let (s, c) = th.sin_cos();
    let t = DVec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
    let (s, c) = ph.sin_cos();
    let wi = DVec3::new(c * t.x - s * t.y, s * t.x + c * t.y, t.z);
    let wo = 2.0 * wi.dot(h) * h - wi;
    (wo, wi)
}

impl Separable {
    /// Fits ranks `1..=max_rank` at once; returns one approximation per
    /// rank. `None` when the source cannot be evaluated (scattered data:
    /// see [`Separable::fit_scattered`]).
    pub fn fit(
        source: &Source,
        res: usize,
        theta_max_deg: f64,
        max_rank: usize,
    ) -> Option<Vec<Self>> {
        if !source.is_evaluable() || max_rank == 0 {
            return None;
        }
        let grid = ParabolicGrid::new(res).ok()?;
        let valid = grid.valid().to_vec();
        let nv = valid.len();
        let cos_max = theta_max_deg.to_radians().cos() - 1e-9;
        // The matrix of f over (h texel, d texel); NaN marks a left-out entry.
        let m: Vec<[f32; 3]> = (0..nv * nv)
            .into_par_iter()
            .map(|e| {
                let (a, b) = (e / nv, e % nv);
                let h = grid.texel_direction(valid[a] as usize);
                let d = grid.texel_direction(valid[b] as usize);
                let (wo, wi) = from_half_diff(h, d);
                if wo.z < cos_max || wi.z < cos_max {
                    return [f32::NAN; 3];
                }
                match source.eval(wo, wi).flatten() {
                    Some(f) if f.is_finite() => f.to_array().map(|x| x as f32),
                    _ => [f32::NAN; 3],
                }
            })
            .collect();
        Some(Self::from_matrix(grid, &m, max_rank))
    }

    /// The same baseline for scattered measurements, which cannot be
    /// evaluated at texel centres: each sample's value goes to the matrix
    /// entry of the texels nearest to its `h` and `d` (the mean of the
    /// samples that share an entry; entries without a sample are left
    /// out, as missing ones are for a table). At `res` 32 that matrix has
    /// 660,000 entries, so sparse data leaves most of it empty and the
    /// alternating least squares runs on what there is.
    pub fn fit_scattered(samples: &[Sample], res: usize, max_rank: usize) -> Option<Vec<Self>> {
        if max_rank == 0 || samples.is_empty() {
            return None;
        }
        let grid = ParabolicGrid::new(res).ok()?;
        let nv = grid.valid().len();
        let ord = grid.valid_order();
        let nearest = |v: DVec3| -> usize {
            let taps = grid.taps(v);
            let (i, _) = taps
                .iter()
                .copied()
                .fold((0u32, -1.0), |a, t| if t.1 > a.1 { t } else { a });
            ord[i as usize] as usize
        };
        let mut sum = vec![[0.0f64; 3]; nv * nv];
        let mut count = vec![[0u32; 3]; nv * nv];
        for s in samples {
            let Some(f) = s.f else { continue };
            let (h, d) = half_diff_vectors(s.wo, s.wi);
            let e = nearest(h) * nv + nearest(d);
            for (c, v) in f.to_array().into_iter().enumerate() {
                if v.is_finite() {
                    sum[e][c] += v;
                    count[e][c] += 1;
                }
            }
        }
        let m: Vec<[f32; 3]> = sum
            .iter()
            .zip(&count)
            .map(|(s, n)| {
                std::array::from_fn(|c| {
                    if n[c] > 0 {
                        (s[c] / n[c] as f64) as f32
                    } else {
                        f32::NAN
                    }
                })
            })
            .collect();
        Some(Self::from_matrix(grid, &m, max_rank))
    }

    /// Ranks `1..=max_rank` fitted to the `n_v x n_v` matrix `m` over
    /// (h texel, d texel) of valid texels, NaN marking left-out entries.
    fn from_matrix(grid: ParabolicGrid, m: &[[f32; 3]], max_rank: usize) -> Vec<Self> {
        let res = grid.res();
        let valid = grid.valid().to_vec();
        let nv = valid.len();
        let ord = grid.valid_order();
        let centres: Vec<(f64, f64)> = valid
            .iter()
            .map(|&i| grid.center(i as usize % res, i as usize / res))
            .collect();
        let mut u = vec![Vec::new(); 3];
        let mut v = vec![Vec::new(); 3];
        for c in 0..3 {
            let entry = |a: usize, b: usize| -> Option<f64> {
                let x = m[a * nv + b][c];
                (!x.is_nan()).then_some(x as f64)
            };
            let (uc, vc) = als(nv, &entry, max_rank, &centres);
            u[c] = uc;
            v[c] = vc;
        }
        (1..=max_rank)
            .map(|rank| Separable {
                grid: grid.clone(),
                ord: ord.clone(),
                u: u.iter().map(|x| x[..rank].to_vec()).collect(),
                v: v.iter().map(|x| x[..rank].to_vec()).collect(),
            })
            .collect()
    }

    /// Rank of the approximation.
    pub fn rank(&self) -> usize {
        self.u[0].len()
    }

    /// Texels stored (all channels): `2 rank res^2 * 3`.
    pub fn storage_texels(&self) -> usize {
        2 * self.rank() * self.grid.len()
    }

    /// The approximation at a direction pair (may be negative).
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        let (h, d) = half_diff_vectors(wo, wi);
        let (th, td) = (self.grid.taps(h), self.grid.taps(d));
        let mut out = [0.0; 3];
        for (c, o) in out.iter_mut().enumerate() {
            for k in 0..self.rank() {
                let a: f64 = th
                    .iter()
                    .map(|(i, w)| w * self.u[c][k][self.ord[*i as usize] as usize])
                    .sum();
                let b: f64 = td
                    .iter()
                    .map(|(i, w)| w * self.v[c][k][self.ord[*i as usize] as usize])
                    .sum();
                *o += a * b;
            }
        }
        Rgb::from_array(out)
    }
}

/// Weighted low-rank fit of an `n x n` matrix with missing entries.
fn als(
    n: usize,
    entry: &(dyn Fn(usize, usize) -> Option<f64> + Sync),
    rank: usize,
    centres: &[(f64, f64)],
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    // Rows and columns with at least one valid entry.
    let row_has: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|a| (0..n).any(|b| entry(a, b).is_some()))
        .collect();
    let col_has: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|b| (0..n).any(|a| entry(a, b).is_some()))
        .collect();
    let mut us: Vec<Vec<f64>> = Vec::new();
    let mut vs: Vec<Vec<f64>> = Vec::new();
    // Successive rank-1 fits of the residual.
    for _ in 0..rank {
        let resid = |a: usize, b: usize| -> Option<f64> {
            entry(a, b).map(|x| x - (0..us.len()).map(|k| us[k][a] * vs[k][b]).sum::<f64>())
        };
        let mut v = vec![1.0; n];
        let mut u = vec![0.0; n];
        for _ in 0..30 {
            u = best_side(n, &v, resid);
            let next = best_side_columns(n, &u, resid);
            // Stop once the product u v^T no longer moves (v's scale is
            // tied to u's, so v's relative change measures it).
            let change = next
                .iter()
                .zip(&v)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>();
            let size = next.iter().map(|a| a * a).sum::<f64>();
            v = next;
            if change <= 1e-14 * size {
                break;
            }
        }
        fill_empty(&mut u, &row_has, centres);
        fill_empty(&mut v, &col_has, centres);
        us.push(u);
        vs.push(v);
    }
    (us, vs)
}

/// One alternating step: for each row `a`, the `x_a` minimizing
/// `sum_b (m(a, b) - x_a y_b)^2` over the valid entries (0 for a row
/// without any).
fn best_side(n: usize, y: &[f64], m: impl Fn(usize, usize) -> Option<f64> + Sync) -> Vec<f64> {
    (0..n)
        .into_par_iter()
        .map(|a| {
            let (mut num, mut den) = (0.0, 0.0);
            for (b, yb) in y.iter().enumerate() {
                if let Some(x) = m(a, b) {
                    num += x * yb;
                    den += yb * yb;
                }
            }
            if den > 0.0 {
                num / den
            } else {
                0.0
            }
        })
        .collect()
}

/// The other alternating step: for each column `b`, the `y_b` minimizing
/// `sum_a (m(a, b) - x_a y_b)^2` over the valid entries. The same result as
/// [`best_side`] on the transpose, computed row by row (the matrix is
/// stored by rows, and a walk down its columns misses the cache at every
/// entry): sums over fixed blocks of rows, added in block order, so the
/// result does not depend on the thread count.
fn best_side_columns(
    n: usize,
    x: &[f64],
    m: impl Fn(usize, usize) -> Option<f64> + Sync,
) -> Vec<f64> {
    const BLOCKS: usize = 32;
    let rows_per_block = n.div_ceil(BLOCKS).max(1);
    let partial: Vec<(Vec<f64>, Vec<f64>)> = (0..n.div_ceil(rows_per_block))
        .into_par_iter()
        .map(|blk| {
            let (mut num, mut den) = (vec![0.0; n], vec![0.0; n]);
            let first = blk * rows_per_block;
            let rows = &x[first..((blk + 1) * rows_per_block).min(n)];
            for (a, &xa) in (first..).zip(rows) {
                for b in 0..n {
                    if let Some(v) = m(a, b) {
                        num[b] += v * xa;
                        den[b] += xa * xa;
                    }
                }
            }
            (num, den)
        })
        .collect();
    (0..n)
        .map(|b| {
            let (mut num, mut den) = (0.0, 0.0);
            for (pn, pd) in &partial {
                num += pn[b];
                den += pd[b];
            }
            if den > 0.0 {
                num / den
            } else {
                0.0
            }
        })
        .collect()
}

/// Texels without a single valid entry (beyond the reach of the fit
/// domain) take the value of the nearest texel that has one, so that
/// bilinear lookups near the domain's edge do not blend in zeros.
fn fill_empty(x: &mut [f64], has: &[bool], centres: &[(f64, f64)]) {
    let src = x.to_vec();
    let dist = |a: usize, b: usize| {
        (centres[a].0 - centres[b].0).powi(2) + (centres[a].1 - centres[b].1).powi(2)
    };
    for (a, xa) in x.iter_mut().enumerate() {
        if has[a] {
            continue;
        }
        let nearest = (0..src.len())
            .filter(|b| has[*b])
            .min_by(|&b, &c| dist(a, b).total_cmp(&dist(a, c)));
        if let Some(b) = nearest {
            *xa = src[b];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn column_step_equals_the_row_step_on_the_transpose() {
        // A 70 x 70 matrix (more rows than blocks, not a multiple of them)
        // with missing entries and one empty column.
        let n = 70;
        let m = |a: usize, b: usize| -> Option<f64> {
            ((a * 7 + b * 3) % 5 != 0 && b != 11).then(|| ((a * 31 + b * 17) % 13) as f64 - 4.0)
        };
        let x: Vec<f64> = (0..n).map(|a| 0.5 + (a % 9) as f64 * 0.25).collect();
        let by_columns = best_side_columns(n, &x, m);
        let by_rows = best_side(n, &x, |b, a| m(a, b));
        assert_eq!(by_columns[11], 0.0);
        for (c, r) in by_columns.iter().zip(&by_rows) {
            assert!((c - r).abs() <= 1e-12 * r.abs().max(1.0), "{c} vs {r}");
        }
    }
}
