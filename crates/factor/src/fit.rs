//! The homomorphic fit: `ln f = ln p(wo) + ln q(h) + ln p(wi) + ln r(theta_h,
//! theta_d)` by linear least squares over scattered samples, with a
//! Laplacian smoothness term.
//!
//! Unknowns are the logarithms of the *valid* texels of the two maps
//! (centre inside the unit disk; the others are stand-ins, see
//! [`isolux_materials::parabolic`]), then of the `n_d x n_d` texels of the
//! `r` table, `2 n_v + n_d^2` in all. Each sample gives one row with
//! sixteen bilinear taps (four per lookup); the objective is
//!
//! ```text
//! (1/M) sum_s (row_s . x - ln f_s)^2  +  (lambda/n_v) sum_maps sum_i (L x)_i^2  +  eps |x|^2
//! ```
//!
//! where `(L x)_i = sum_{j ~ i} (x_i - x_j)` over the valid 4-neighbours
//! (the graph Laplacian of each map and of the `r` table), `lambda` is
//! `--smoothness` and the tiny ridge `eps` (1e-9 of the mean diagonal)
//! fixes the exact degeneracies, `p -> c p, q -> q / c^2` and `q -> c q, r
//! -> r / c`. The normal matrix is dense (any
//! `wo` texel meets any `wi` texel), so up to [`DENSE_MAX_RES`] it is
//! assembled column-parallel and factored once by a dense Cholesky (faer)
//! for all colour channels that share the same set of usable samples; the
//! right-hand sides of those channels are solved together. Above it,
//! Jacobi-preconditioned conjugate gradients minimize the same objective
//! matrix-free, started from the fit at half the resolution.

use crate::source::Sample;
use crate::FactorError;
use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef, Side};
use isolux_core::{DVec3, Rgb};
use isolux_materials::factored::hd_taps;
use isolux_materials::parabolic::ParabolicGrid;
use isolux_materials::Factored;
use rayon::prelude::*;
use std::time::Instant;

/// Settings of a fit.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Texels per side of each map.
    pub res: usize,
    /// Weight `lambda` of the Laplacian term.
    pub smoothness: f64,
    /// Largest polar angle of `wo` and `wi` in the fit, degrees.
    pub theta_max_deg: f64,
    /// Gauss-Newton iterations toward the relative error after the log fit.
    pub refine: usize,
    /// Texels per side of the angle factor `r(theta_h, theta_d)`: `None`
    /// for the default ([`FitOptions::hd_res`]), `Some(0)` for no such
    /// factor (the plain `p q p` of the paper).
    pub hd_res: Option<usize>,
    /// The largest `res` solved by a dense Cholesky factorization (default
    /// [`DENSE_MAX_RES`]); above it, conjugate gradients.
    pub dense_max_res: usize,
    /// The floor of the fit, relative to each channel's largest sample
    /// value ([`DEFAULT_DYNAMIC_RANGE`]): smaller values, zeros included,
    /// are fitted as the floor.
    pub dynamic_range: f64,
}

/// The default `--smoothness`.
pub const DEFAULT_SMOOTHNESS: f64 = 1e-3;

/// The default `--dynamic-range`: values below 1e-4 of a channel's
/// largest are fitted (and measured) as that floor.
///
/// A log fit of the raw values broke on the peaked materials that have no
/// diffuse term: a Beckmann lobe of roughness 0.3 falls to 1e-156 at 80
/// degrees off its peak and an exponent-100 Phong lobe to exactly 0, so
/// the logarithms spanned hundreds of units (or the zeros were dropped,
/// leaving texels to the smoothness term alone), and the factors' products
/// reached 1e43 between the samples: `cook_torrance` with its default
/// reflectance 0, `phong`, `ward` and `beckmann` reported errors of
/// 1e100 or infinity, or failed. A floor 80 dB under the peak is far
/// below anything visible beside the peak and keeps the logarithms within
/// 9.2 units of it.
pub const DEFAULT_DYNAMIC_RANGE: f64 = 1e-4;

/// The accepted `--dynamic-range`: from 1e-8 (18.4 log units) to 0.1.
pub const DYNAMIC_RANGE_LIMITS: std::ops::RangeInclusive<f64> = 1e-8..=0.1;

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            res: 32,
            smoothness: DEFAULT_SMOOTHNESS,
            theta_max_deg: 80.0,
            refine: 1,
            hd_res: None,
            dense_max_res: DENSE_MAX_RES,
            dynamic_range: DEFAULT_DYNAMIC_RANGE,
        }
    }
}

impl FitOptions {
    /// Texels per side of the `r(theta_h, theta_d)` table: as set, or by
    /// default `res / 4` (at least 2), so that the table adds a sixteenth
    /// of one map to the storage.
    pub fn hd_res(&self) -> usize {
        self.hd_res.unwrap_or((self.res / 4).max(2))
    }

    /// The most Gauss-Newton iterations (each a whole weighted solve; one,
    /// the default, takes the error most of the way).
    pub const MAX_REFINE: usize = 100;

    /// Checks the ranges: `res` in 4..=512, `theta_max` in (0, 90],
    /// `smoothness` finite and non-negative, `refine` at most
    /// [`Self::MAX_REFINE`]; an error names the flag.
    pub fn validate(&self) -> Result<(), FactorError> {
        let bad = FactorError::input;
        if !isolux_materials::parabolic::RES_RANGE.contains(&self.res) {
            return bad("--res", format!("must lie in 4..=512, got {}", self.res));
        }
        let nd = self.hd_res();
        if nd == 1 || nd > 512 {
            return bad(
                "--hd-res",
                format!("must be 0 (no r factor) or lie in 2..=512, got {nd}"),
            );
        }
        if !(self.theta_max_deg > 0.0 && self.theta_max_deg <= 90.0) {
            return bad(
                "--theta-max",
                format!("must lie in (0, 90] degrees, got {}", self.theta_max_deg),
            );
        }
        if self.refine > Self::MAX_REFINE {
            return bad(
                "--refine",
                format!(
                    "must be at most {} iterations, got {}",
                    Self::MAX_REFINE,
                    self.refine
                ),
            );
        }
        if !(self.smoothness >= 0.0 && self.smoothness.is_finite()) {
            return bad(
                "--smoothness",
                format!("must be finite and non-negative, got {}", self.smoothness),
            );
        }
        if !DYNAMIC_RANGE_LIMITS.contains(&self.dynamic_range) {
            return bad(
                "--dynamic-range",
                format!(
                    "must lie in [1e-8, 0.1], got {}",
                    isolux_core::short_number(self.dynamic_range)
                ),
            );
        }
        Ok(())
    }
}

/// A fitted factorization: `f = scale * p(wo) q(h) p(wi)`.
#[derive(Clone, Debug)]
pub struct Factorization {
    /// Texels per side.
    pub res: usize,
    /// Fit domain, degrees.
    pub theta_max_deg: f64,
    /// `p` texels (`res^2`, row 0 at the top), largest value 1 per channel.
    pub p: Vec<Rgb>,
    /// `q` texels, largest value 1 per channel.
    pub q: Vec<Rgb>,
    /// Texels per side of the `r(theta_h, theta_d)` table (0: none).
    pub hd_res: usize,
    /// `r` texels (`hd_res^2`, row `theta_h`, column `theta_d`; empty
    /// without that factor), largest value 1 per channel.
    pub r: Vec<Rgb>,
    /// Per-channel scale.
    pub scale: Rgb,
    /// Per channel, the floor the fit raised smaller values to
    /// ([`FitOptions::dynamic_range`] times the largest sample value);
    /// errors are measured against it too ([`crate::evaluate`]).
    pub floor: Rgb,
    /// Bookkeeping.
    pub stats: FitStats,
}

/// What a fit used and how long it took.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FitStats {
    /// Samples offered.
    pub samples: usize,
    /// Per channel: samples used in the log fit.
    pub used: [usize; 3],
    /// Per channel: samples excluded (missing: a negative or non-finite
    /// value).
    pub excluded: [usize; 3],
    /// Per channel: samples used at the floor (their value, zero included,
    /// was below it).
    pub floored: [usize; 3],
    /// Cholesky factorizations computed (1 when all channels share their
    /// samples; 0 above [`DENSE_MAX_RES`], where conjugate gradients solve).
    pub factorizations: usize,
    /// Conjugate-gradient iterations, all solves and coarser levels
    /// together (0 at or below [`DENSE_MAX_RES`]).
    pub cg_iterations: usize,
    /// Unknowns (`2 n_v`).
    pub unknowns: usize,
    /// Seconds assembling the normal equations.
    pub assemble_s: f64,
    /// Seconds in the Cholesky factorization and solves (or the
    /// conjugate-gradient solves).
    pub solve_s: f64,
    /// Seconds in the coarser fits that start the conjugate gradients.
    pub coarse_s: f64,
    /// The largest relative residual `|b - A x| / |b|` at which a
    /// conjugate-gradient solve of this resolution stopped (0 for the
    /// dense solve): above the tolerance `1e-5`, the iteration cap was
    /// reached first.
    pub cg_residual: f64,
}

impl Factorization {
    /// The renderable material (the same texel values as the files, after
    /// rounding to `f32`).
    pub fn material(&self) -> Result<Factored, FactorError> {
        let r = |v: &[Rgb]| -> Vec<Rgb> { v.iter().map(|c| c.map(|x| x as f32 as f64)).collect() };
        let bad = |e: String| {
            FactorError::Fit(format!("the fitted factors are not a valid material: {e}"))
        };
        let m = Factored::new(self.res, &r(&self.p), &r(&self.q), self.scale).map_err(bad)?;
        if self.r.is_empty() {
            Ok(m)
        } else {
            m.with_hd(self.hd_res, &r(&self.r)).map_err(bad)
        }
    }
}

/// Logarithms below this (relative to a map's largest value) are clamped,
/// so that every texel stays a normal positive `f32`.
pub const MIN_LOG: f64 = -80.0;

/// Fits `p` and `q` to `samples`.
pub fn fit(samples: &[Sample], opts: &FitOptions) -> Result<Factorization, FactorError> {
    opts.validate()?;
    let grid = ParabolicGrid::new(opts.res).map_err(FactorError::Fit)?;
    let res = opts.res;
    let valid = grid.valid();
    let nv = valid.len();
    let ord = grid.valid_order();
    let t0 = Instant::now();
    // Rows: twelve taps per sample (four per lookup), plus two for the
    // theta_d factor when there is one (zero weights otherwise).
    let nd = opts.hd_res();
    let n = 2 * nv + nd * nd;
    let rows: Vec<Row> = samples
        .par_iter()
        .map(|s| {
            let h = (s.wo + s.wi).normalize();
            let mut row = [(0u32, 0.0); TAPS];
            for (k, (i, w)) in grid
                .taps(s.wo)
                .into_iter()
                .chain(grid.taps(s.wi))
                .enumerate()
            {
                row[k] = (ord[i as usize], w);
            }
            for (k, (i, w)) in grid.taps(h).into_iter().enumerate() {
                row[8 + k] = (ord[i as usize] + nv as u32, w);
            }
            if nd > 0 {
                for (k, (i, w)) in hd_taps(nd, s.wo, s.wi).into_iter().enumerate() {
                    row[12 + k] = (i + 2 * nv as u32, w);
                }
            }
            row
        })
        .collect();
    // Usable samples per channel, and channel groups sharing them. A
    // negative value is missing data (MERL's convention); zero is a value,
    // fitted at the floor.
    let usable = |s: &Sample, c: usize| {
        s.f.is_some_and(|f| {
            let v = f.to_array()[c];
            v >= 0.0 && v.is_finite()
        })
    };
    let masks: Vec<Vec<bool>> = (0..3)
        .map(|c| samples.iter().map(|s| usable(s, c)).collect())
        .collect();
    let mut stats = FitStats {
        samples: samples.len(),
        unknowns: n,
        ..Default::default()
    };
    for c in 0..3 {
        stats.used[c] = masks[c].iter().filter(|m| **m).count();
        stats.excluded[c] = samples.len() - stats.used[c];
        if stats.used[c] < 16 {
            return Err(FactorError::Fit(format!(
                "channel {} has {} usable samples of {} (values must be non-negative and finite): too few to fit",
                ["R", "G", "B"][c],
                stats.used[c],
                samples.len()
            )));
        }
    }
    // Each channel's floor: the dynamic range times its largest value.
    let mut floor = [0.0; 3];
    for c in 0..3 {
        let top = samples
            .iter()
            .zip(&masks[c])
            .filter(|(_, m)| **m)
            .map(|(s, _)| s.f.expect("usable").to_array()[c])
            .fold(0.0, f64::max);
        if !(top > 0.0) {
            return Err(FactorError::Fit(format!(
                "channel {} is zero at every usable sample: a logarithm cannot fit it",
                ["R", "G", "B"][c]
            )));
        }
        floor[c] = opts.dynamic_range * top;
        stats.floored[c] = samples
            .iter()
            .zip(&masks[c])
            .filter(|(s, m)| **m && s.f.expect("usable").to_array()[c] < floor[c])
            .count();
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for c in 0..3 {
        match groups.iter_mut().find(|g| masks[g[0]] == masks[c]) {
            Some(g) => g.push(c),
            None => groups.push(vec![c]),
        }
    }
    let lap = laplacian_rows(&grid, &ord, nv, nd);
    // Per channel, the unknowns: `ln p` at the valid texels, then `ln q`.
    let mut x: [Vec<f64>; 3] = Default::default();
    // Above DENSE_MAX_RES: conjugate gradients, started from the fit at
    // half the resolution (recursively, down to a dense solve).
    let warm = if res > opts.dense_max_res {
        let tc = Instant::now();
        let (x0, coarse) = coarse_start(samples, opts, &grid, nv, nd)?;
        stats.coarse_s = tc.elapsed().as_secs_f64();
        stats.cg_iterations = coarse.cg_iterations;
        Some(x0)
    } else {
        None
    };
    let mut solver = Solver {
        rows: &rows,
        lap: &lap,
        n,
        lam: opts.smoothness / nv as f64,
        assemble_s: 0.0,
        solve_s: 0.0,
        factorizations: 0,
        cg_iterations: 0,
        cg_residual: 0.0,
        cg: warm.is_some().then(|| CgColumns::new(&rows, n)),
    };
    solver.assemble_s = t0.elapsed().as_secs_f64() - stats.coarse_s;
    let ln_f = |s: &Sample, c: usize| s.f.expect("usable").to_array()[c].max(floor[c]).ln();
    for g in &groups {
        let mask = &masks[g[0]];
        let weights: Vec<f64> = mask.iter().map(|m| if *m { 1.0 } else { 0.0 }).collect();
        let targets: Vec<Vec<f64>> = g
            .iter()
            .map(|&c| {
                samples
                    .iter()
                    .zip(mask)
                    .map(|(s, m)| if *m { ln_f(s, c) } else { 0.0 })
                    .collect()
            })
            .collect();
        let starts: Vec<Vec<f64>> = g
            .iter()
            .map(|&c| warm.as_ref().map_or_else(|| vec![0.0; n], |w| w[c].clone()))
            .collect();
        for (xc, &c) in solver
            .solve(&weights, &targets, &starts)?
            .into_iter()
            .zip(g)
        {
            x[c] = xc;
        }
    }
    // Gauss-Newton refinement toward the relative error: linearizing
    // exp(d) - 1 about the current log residual d gives a weighted log fit
    // with weights exp(2d) and targets a.x - (1 - exp(-d)).
    // Channels with bit-identical data (grey materials) are solved once.
    let twin = |c: usize| -> Option<usize> {
        (0..c).find(|&d| {
            samples.iter().all(|s| {
                s.f.is_none_or(|f| f.to_array()[c].to_bits() == f.to_array()[d].to_bits())
            })
        })
    };
    let twins: Vec<Option<usize>> = (0..3).map(twin).collect();
    for _ in 0..opts.refine {
        for c in 0..3 {
            if let Some(d) = twins[c] {
                x[c] = x[d].clone();
                continue;
            }
            let mut weights = vec![0.0; samples.len()];
            let mut target = vec![0.0; samples.len()];
            for (k, ((row, s), m)) in rows.iter().zip(samples).zip(&masks[c]).enumerate() {
                if !*m {
                    continue;
                }
                let ax: f64 = row.iter().map(|(i, w)| w * x[c][*i as usize]).sum();
                let d = (ax - ln_f(s, c)).clamp(-3.0, 3.0);
                weights[k] = (2.0 * d).exp();
                target[k] = ax - (1.0 - (-d).exp());
            }
            let start = std::mem::take(&mut x[c]);
            x[c] = solver.solve(&weights, &[target], &[start])?.remove(0);
        }
    }
    stats.factorizations = solver.factorizations;
    stats.cg_iterations += solver.cg_iterations;
    stats.cg_residual = solver.cg_residual;
    stats.assemble_s = solver.assemble_s;
    stats.solve_s = solver.solve_s;
    if x.iter().flatten().any(|v| !v.is_finite()) {
        return Err(FactorError::Fit(
            "the solve produced non-finite values; try a larger --smoothness".into(),
        ));
    }
    // Normalize each map's largest value to 1, moving the rest to scale.
    let max = |xc: &[f64]| xc.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let pmax = x.each_ref().map(|xc| max(&xc[..nv]));
    let qmax = x.each_ref().map(|xc| max(&xc[nv..2 * nv]));
    let smax = x
        .each_ref()
        .map(|xc| if nd > 0 { max(&xc[2 * nv..]) } else { 0.0 });
    let scale = Rgb::new(
        (2.0 * pmax[0] + qmax[0] + smax[0]).exp(),
        (2.0 * pmax[1] + qmax[1] + smax[1]).exp(),
        (2.0 * pmax[2] + qmax[2] + smax[2]).exp(),
    );
    if !(scale.r > 0.0 && scale.g > 0.0 && scale.b > 0.0 && scale.is_finite()) {
        return Err(FactorError::Fit(format!(
            "the fitted scale {:?} is out of range",
            scale.to_array()
        )));
    }
    // Every texel of a map (offset 0 for p, nv for q), stand-ins included.
    let expand = |offset: usize, max: [f64; 3]| -> Vec<Rgb> {
        (0..grid.len())
            .map(|i| {
                let t = offset + ord[grid.alias(i)] as usize;
                let v = |c: usize| (x[c][t] - max[c]).max(MIN_LOG).exp();
                Rgb::new(v(0), v(1), v(2))
            })
            .collect()
    };
    Ok(Factorization {
        res,
        theta_max_deg: opts.theta_max_deg,
        p: expand(0, pmax),
        q: expand(nv, qmax),
        hd_res: nd,
        r: (0..nd * nd)
            .map(|k| {
                let v = |c: usize| (x[c][2 * nv + k] - smax[c]).max(MIN_LOG).exp();
                Rgb::new(v(0), v(1), v(2))
            })
            .collect(),
        scale,
        floor: Rgb::new(floor[0], floor[1], floor[2]),
        stats,
    })
}

/// Assembles and solves the weighted normal equations.
struct Solver<'a> {
    rows: &'a [Row],
    lap: &'a [Vec<(u32, f64)>],
    n: usize,
    lam: f64,
    assemble_s: f64,
    solve_s: f64,
    factorizations: usize,
    cg_iterations: usize,
    cg_residual: f64,
    /// Set above [`DENSE_MAX_RES`]: solve by conjugate gradients, over
    /// the rows transposed.
    cg: Option<CgColumns>,
}

impl Solver<'_> {
    /// Minimizes `sum_s w_s (a_s.x - y_s)^2 / sum w + lam |L x|^2 + eps |x|^2`
    /// for each target vector `y` (one Cholesky factorization for all).
    fn solve(
        &mut self,
        weights: &[f64],
        targets: &[Vec<f64>],
        starts: &[Vec<f64>],
    ) -> Result<Vec<Vec<f64>>, FactorError> {
        if self.cg.is_some() {
            return Ok(targets
                .iter()
                .zip(starts)
                .map(|(y, x0)| self.solve_cg(weights, y, x0.clone()))
                .collect());
        }
        let t1 = Instant::now();
        let n = self.n;
        let rows = self.rows;
        let wsum: f64 = weights.iter().sum();
        let wdata = 1.0 / wsum;
        // Lower triangle, column-major: column j holds rows i >= j.
        let mut ata = vec![0.0f64; n * n];
        let cols_per_chunk = n.div_ceil(rayon::current_num_threads().max(1) * 8).max(1);
        ata.par_chunks_mut(cols_per_chunk * n)
            .enumerate()
            .for_each(|(chunk, buf)| {
                let j0 = chunk * cols_per_chunk;
                let j1 = (j0 + cols_per_chunk).min(n);
                for (row, &ws) in rows.iter().zip(weights) {
                    if ws == 0.0 {
                        continue;
                    }
                    for &(j, wj) in row {
                        let j = j as usize;
                        if j < j0 || j >= j1 {
                            continue;
                        }
                        let col = &mut buf[(j - j0) * n..(j - j0 + 1) * n];
                        let wj = wj * ws * wdata;
                        for &(i, wi) in row {
                            if (i as usize) >= j {
                                col[i as usize] += wi * wj;
                            }
                        }
                    }
                }
            });
        // A tap pair (a, b) with equal indices lands twice on the
        // diagonal, once per order, exactly as in the outer product of the
        // summed row; off-diagonal pairs land once in the lower triangle.
        for r in self.lap {
            for &(j, wj) in r {
                for &(i, wi) in r {
                    if i >= j {
                        ata[j as usize * n + i as usize] += self.lam * wi * wj;
                    }
                }
            }
        }
        let mean_diag = (0..n).map(|i| ata[i * n + i]).sum::<f64>() / n as f64;
        let eps = 1e-9 * mean_diag.max(f64::MIN_POSITIVE);
        for i in 0..n {
            ata[i * n + i] += eps;
        }
        let mut atb = Mat::<f64>::zeros(n, targets.len());
        for (k, y) in targets.iter().enumerate() {
            for ((row, &ws), &yk) in rows.iter().zip(weights).zip(y) {
                if ws == 0.0 {
                    continue;
                }
                for &(i, w) in row {
                    atb[(i as usize, k)] += w * ws * wdata * yk;
                }
            }
        }
        self.assemble_s += t1.elapsed().as_secs_f64();
        let t2 = Instant::now();
        let a = MatRef::from_column_major_slice(&ata, n, n);
        let llt = a.llt(Side::Lower).map_err(|e| {
            FactorError::Fit(format!(
                "the normal matrix is not positive definite ({e:?}); try a larger --smoothness"
            ))
        })?;
        let x = llt.solve(&atb);
        self.solve_s += t2.elapsed().as_secs_f64();
        self.factorizations += 1;
        Ok((0..targets.len())
            .map(|k| (0..n).map(|i| x[(i, k)]).collect())
            .collect())
    }
}

/// Taps per sample row: four per map lookup, two for `s(theta_d)`.
const TAPS: usize = 16;
type Row = [(u32, f64); TAPS];

/// The largest `res` solved by a dense Cholesky factorization; above it
/// the normal equations are solved matrix-free by preconditioned
/// conjugate gradients, started from the fit at half the resolution.
pub const DENSE_MAX_RES: usize = 32;

/// Relative residual at which the conjugate gradients stop.
pub const CG_TOLERANCE: f64 = 1e-5;
/// Iteration cap of one conjugate-gradient solve.
pub const CG_MAX_ITERATIONS: usize = 300;

/// The sample rows transposed (for each unknown, the samples that tap it),
/// so that `A^T z` is a gather, parallel over unknowns and deterministic.
struct CgColumns {
    start: Vec<usize>,
    entries: Vec<(u32, f64)>,
}

impl CgColumns {
    fn new(rows: &[Row], n: usize) -> Self {
        let mut start = vec![0usize; n + 1];
        for row in rows {
            for &(i, w) in row {
                if w != 0.0 {
                    start[i as usize + 1] += 1;
                }
            }
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut entries = vec![(0u32, 0.0); start[n]];
        for (k, row) in rows.iter().enumerate() {
            for &(i, w) in row {
                if w != 0.0 {
                    entries[fill[i as usize]] = (k as u32, w);
                    fill[i as usize] += 1;
                }
            }
        }
        Self { start, entries }
    }
}

/// A dot product summed in a fixed order (the same whatever the threads).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.par_chunks(8192)
        .zip(b.par_chunks(8192))
        .map(|(x, y)| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>())
        .collect::<Vec<f64>>()
        .iter()
        .sum()
}

impl Solver<'_> {
    /// `y = (A^T W A / sum w + lam L L + eps I) x`.
    fn apply(&self, cols: &CgColumns, wdata: &[f64], eps: f64, x: &[f64], y: &mut [f64]) {
        let z: Vec<f64> = self
            .rows
            .par_iter()
            .zip(wdata)
            .map(|(row, &ws)| {
                if ws == 0.0 {
                    0.0
                } else {
                    ws * row.iter().map(|(i, w)| w * x[*i as usize]).sum::<f64>()
                }
            })
            .collect();
        let mut lx = vec![0.0; self.n];
        for r in self.lap {
            lx[r[0].0 as usize] = r.iter().map(|(i, w)| w * x[*i as usize]).sum();
        }
        let mut llx = vec![0.0; self.n];
        for r in self.lap {
            llx[r[0].0 as usize] = r.iter().map(|(i, w)| w * lx[*i as usize]).sum();
        }
        y.par_iter_mut().enumerate().for_each(|(i, yi)| {
            let data: f64 = cols.entries[cols.start[i]..cols.start[i + 1]]
                .iter()
                .map(|(k, w)| w * z[*k as usize])
                .sum();
            *yi = data + self.lam * llx[i] + eps * x[i];
        });
    }

    /// One right-hand side by Jacobi-preconditioned conjugate gradients
    /// from `x`; the same objective as the dense solve.
    fn solve_cg(&mut self, weights: &[f64], target: &[f64], mut x: Vec<f64>) -> Vec<f64> {
        let t = Instant::now();
        let cols = self.cg.as_ref().expect("conjugate gradients set up");
        let n = self.n;
        let wsum: f64 = weights.iter().sum();
        let wdata: Vec<f64> = weights.iter().map(|w| w / wsum).collect();
        // The diagonal of the normal matrix, for the ridge and the
        // preconditioner.
        let mut diag: Vec<f64> = (0..n)
            .into_par_iter()
            .map(|i| {
                cols.entries[cols.start[i]..cols.start[i + 1]]
                    .iter()
                    .map(|(k, w)| w * w * wdata[*k as usize])
                    .sum()
            })
            .collect();
        for r in self.lap {
            for &(i, w) in r {
                diag[i as usize] += self.lam * w * w;
            }
        }
        let eps = 1e-9 * (diag.iter().sum::<f64>() / n as f64).max(f64::MIN_POSITIVE);
        for d in &mut diag {
            *d += eps;
        }
        // b = A^T W y / sum w.
        let b: Vec<f64> = (0..n)
            .into_par_iter()
            .map(|i| {
                cols.entries[cols.start[i]..cols.start[i + 1]]
                    .iter()
                    .map(|(k, w)| w * wdata[*k as usize] * target[*k as usize])
                    .sum()
            })
            .collect();
        let mut ax = vec![0.0; n];
        self.apply(cols, &wdata, eps, &x, &mut ax);
        let mut r: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
        let mut z: Vec<f64> = r.iter().zip(&diag).map(|(r, d)| r / d).collect();
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        let b_norm = dot(&b, &b).sqrt().max(f64::MIN_POSITIVE);
        let mut ap = vec![0.0; n];
        let mut iterations = 0;
        loop {
            let residual = dot(&r, &r).sqrt() / b_norm;
            if residual <= CG_TOLERANCE || iterations == CG_MAX_ITERATIONS {
                self.cg_residual = self.cg_residual.max(residual);
                break;
            }
            iterations += 1;
            self.apply(cols, &wdata, eps, &p, &mut ap);
            let alpha = rz / dot(&p, &ap);
            if !alpha.is_finite() {
                self.cg_residual = self.cg_residual.max(residual);
                break;
            }
            x.par_iter_mut().zip(&p).for_each(|(x, p)| *x += alpha * p);
            r.par_iter_mut().zip(&ap).for_each(|(r, a)| *r -= alpha * a);
            z.par_iter_mut()
                .zip(&r)
                .zip(&diag)
                .for_each(|((z, r), d)| *z = r / d);
            let rz_new = dot(&r, &z);
            let beta = rz_new / rz;
            rz = rz_new;
            p.par_iter_mut()
                .zip(&z)
                .for_each(|(p, z)| *p = z + beta * *p);
            self.cg_iterations += 1;
        }
        self.solve_s += t.elapsed().as_secs_f64();
        x
    }
}

/// The starting point of the conjugate gradients at `opts.res`: the fit at
/// half the resolution (same samples; an `r` table no finer than that
/// resolution's default, so that the dense solve at the bottom stays
/// small), read at the fine texels' directions (`ln p`, `ln q + ln
/// scale`, `ln r`), per channel.
fn coarse_start(
    samples: &[Sample],
    opts: &FitOptions,
    grid: &ParabolicGrid,
    nv: usize,
    nd: usize,
) -> Result<([Vec<f64>; 3], FitStats), FactorError> {
    let coarse_res = (opts.res / 2).max(opts.dense_max_res.min(opts.res)).max(4);
    let mut coarse_opts = FitOptions {
        res: coarse_res,
        hd_res: None,
        ..opts.clone()
    };
    coarse_opts.hd_res = Some(if nd == 0 {
        0
    } else {
        nd.min(coarse_opts.hd_res())
    });
    let coarse = fit(samples, &coarse_opts)?;
    let m = coarse.material()?;
    let scale = coarse.scale.to_array().map(f64::ln);
    // ln r at the fine table's texel centres, bilinear in the coarse one:
    // a pair (wo, wi) with exactly those theta_h and theta_d.
    let step = std::f64::consts::FRAC_PI_2 / nd.max(1) as f64;
    let r_logs: Vec<[f64; 3]> = (0..nd * nd)
        .map(|t| {
            let (th, td) = ((t / nd) as f64 + 0.5, (t % nd) as f64 + 0.5);
            let (th, td) = (th * step, td * step);
            let h = DVec3::new(th.sin(), 0.0, th.cos());
            let side = DVec3::Y * td.sin();
            m.log_r(h * td.cos() + side, h * td.cos() - side)
        })
        .collect();
    let x = std::array::from_fn(|c| {
        let mut x = Vec::with_capacity(2 * nv + nd * nd);
        for &i in grid.valid() {
            x.push(m.log_p(grid.texel_direction(i as usize))[c]);
        }
        for &i in grid.valid() {
            x.push(m.log_q(grid.texel_direction(i as usize))[c] + scale[c]);
        }
        x.extend(r_logs.iter().map(|t| t[c]));
        x
    });
    Ok((x, coarse.stats))
}

/// Graph-Laplacian rows of both maps and of the `theta_d` table, over
/// unknown indices.
fn laplacian_rows(grid: &ParabolicGrid, ord: &[u32], nv: usize, nd: usize) -> Vec<Vec<(u32, f64)>> {
    let res = grid.res();
    let mut out = Vec::with_capacity(2 * nv + nd * nd);
    let base = 2 * nv as u32;
    for k in 0..nd as i64 {
        for l in 0..nd as i64 {
            let at = |k: i64, l: i64| base + (k * nd as i64 + l) as u32;
            let mut row = vec![(at(k, l), 0.0)];
            for (dk, dl) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                let (kk, ll) = (k + dk, l + dl);
                if kk >= 0 && ll >= 0 && kk < nd as i64 && ll < nd as i64 {
                    row.push((at(kk, ll), -1.0));
                    row[0].1 += 1.0;
                }
            }
            out.push(row);
        }
    }
    for offset in [0, nv as u32] {
        for &i in grid.valid() {
            let (c, r) = ((i as usize) % res, (i as usize) / res);
            let mut row = vec![(ord[i as usize] + offset, 0.0)];
            for (dc, dr) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                let (cc, rr) = (c as i64 + dc, r as i64 + dr);
                if cc < 0 || rr < 0 || cc >= res as i64 || rr >= res as i64 {
                    continue;
                }
                let j = rr as usize * res + cc as usize;
                if ord[j] == u32::MAX {
                    continue;
                }
                row.push((ord[j] + offset, -1.0));
                row[0].1 += 1.0;
            }
            if row.len() > 1 {
                out.push(row);
            }
        }
    }
    out
}
