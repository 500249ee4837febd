//! `isolux bench`: performance tables.

use anyhow::{bail, Result};
use clap::{Args, ValueEnum};
use isolux_geometry::{
    samples::{bumpy_sphere, cast_rows},
    Object,
};
use rayon::prelude::*;
use std::time::Instant;

/// What to benchmark.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Suite {
    /// Primary-ray casting of a bumpy sphere (SPEC §1).
    Geometry,
}

/// Run benchmarks.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Which benchmark.
    #[arg(value_enum)]
    pub suite: Suite,
    /// Image edge in pixels (rays = size^2).
    #[arg(long, default_value_t = 1024)]
    pub size: u32,
    /// Bump counts to measure, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "0,16,64,256")]
    pub bumps: Vec<usize>,
    /// Repetitions; the fastest is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
}

/// Primary rays of [`cast_rows`] over the whole image, rows in parallel.
pub fn cast_primary(obj: &Object, size: u32) -> usize {
    (0..size)
        .into_par_iter()
        .map(|y| cast_rows(obj, size, y..y + 1))
        .sum()
}

fn best_of(repeat: u32, mut f: impl FnMut() -> usize) -> (f64, usize) {
    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..repeat.max(1) {
        let t = Instant::now();
        hits = f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    (best, hits)
}

/// Runs `isolux bench`.
pub fn run(a: BenchArgs) -> Result<()> {
    if a.size == 0 {
        bail!("--size must be at least 1");
    }
    match a.suite {
        Suite::Geometry => {
            let threads = rayon::current_num_threads();
            println!(
                "primary rays, {}x{} orthographic, sphere r = 0.6 with bumps r = 0.2 (best of {})",
                a.size, a.size, a.repeat
            );
            println!("| bumps | hits | 1 thread (ms) | {threads} threads (ms) | Mrays/s ({threads} threads) |");
            println!("|---:|---:|---:|---:|---:|");
            let single = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
            for &n in &a.bumps {
                let obj = bumpy_sphere(n);
                let (t1, hits) =
                    best_of(a.repeat, || single.install(|| cast_primary(&obj, a.size)));
                let (tn, _) = best_of(a.repeat, || cast_primary(&obj, a.size));
                let rays = (a.size as f64).powi(2);
                println!(
                    "| {n} | {hits} | {:.1} | {:.1} | {:.2} |",
                    t1 * 1e3,
                    tn * 1e3,
                    rays / tn / 1e6
                );
            }
        }
    }
    Ok(())
}
