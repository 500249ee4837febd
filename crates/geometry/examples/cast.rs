//! Casts the geometry benchmark's primary rays (`samples::cast_rows`, tiles
//! of 8 x 8) on one thread, for profiling: `perf record cargo run --release
//! -p isolux-geometry --example cast -- BUMPS [REPEAT] [SIZE]`.

use isolux_geometry::samples::{bumpy_sphere, cast_rows};
use std::time::Instant;

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("usage: cast BUMPS [REPEAT] [SIZE]"))
        .collect();
    let bumps = args.first().copied().unwrap_or(16);
    let repeat = args.get(1).copied().unwrap_or(10);
    let size = args.get(2).copied().unwrap_or(1024) as u32;
    let obj = bumpy_sphere(bumps);
    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..repeat {
        let s = Instant::now();
        hits = cast_rows(&obj, size, 0..size, true);
        best = best.min(s.elapsed().as_secs_f64());
    }
    println!(
        "{bumps} bumps, {size}^2 rays: best {:.1} ms, {hits} hits",
        best * 1e3
    );
}
