//! Primary-ray casting, Isolux against fidget's JIT 3D renderer, side by
//! side in one run (issue: foundation, §9).
//!
//! The scene: a sphere of radius 0.6 with N bumps `f max(Q, 0)^3`, each `Q`
//! a sphere of radius 0.2 centred on the surface (`isolux_geometry::samples`).
//! Isolux casts one exact ray per pixel of a 1024 x 1024 orthographic view
//! of `[-1, 1]^2`; fidget renders the same view as a 1024^3-voxel heightmap
//! (its native 3D mode, interval-arithmetic tile pruning with a JIT), which
//! resolves depth only to 1/512 of the box. fidget's shape is `-F'` (it is
//! negative inside).
//!
//! Isolux casts its rays in tiles of 8 x 8, each culled once through its
//! beam (`Object::cull`), as fidget prunes per tile; `--per-ray` walks the
//! BVH for every ray instead.
//!
//! Run: `cargo run --release -p isolux-fidget-bench [-- SIZE] [--per-ray]
//! [--repeat N]`; `ISOLUX_SIMD=avx2` caps Isolux's vector instructions at
//! fidget's own (its x86-64 JIT requires and uses AVX2).

use fidget::context::Tree;
use fidget::jit::JitShape;
use fidget::render::{RenderHints, ThreadPool, VoxelRenderConfig, VoxelSize};
use isolux_geometry::samples::{bumpy_sphere, cast_rows, fibonacci_sphere, BAND, BUMP_FACTOR};
use rayon::prelude::*;
use std::time::Instant;

fn fidget_tree(bumps: usize) -> Tree {
    let (x, y, z) = Tree::axes();
    let mut f = Tree::constant(0.36) - (x.square() + y.square() + z.square());
    for c in fibonacci_sphere(bumps, 0.6) {
        let q = Tree::constant(0.04)
            - ((x.clone() - c.x).square()
                + (y.clone() - c.y).square()
                + (z.clone() - c.z).square());
        let r = q.max(0.0);
        f += r.clone() * r.clone() * r * BUMP_FACTOR;
    }
    -f
}

fn best(repeat: usize, mut f: impl FnMut() -> usize) -> (f64, usize) {
    let mut t = f64::INFINITY;
    let mut out = 0;
    for _ in 0..repeat {
        let s = Instant::now();
        out = f();
        t = t.min(s.elapsed().as_secs_f64());
    }
    (t, out)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    // `--repeat N`: best of N (default 3); the first other number is SIZE.
    let repeat_at = args.iter().position(|a| a == "--repeat");
    let repeat: usize = match repeat_at {
        Some(i) => match args.get(i + 1).and_then(|n| n.parse().ok()) {
            Some(n) if n > 0 => n,
            _ => {
                eprintln!("error: --repeat takes a positive whole number");
                std::process::exit(2);
            }
        },
        None => 3,
    };
    let size: u32 = args
        .iter()
        .enumerate()
        .filter(|(i, _)| repeat_at.map(|r| r + 1) != Some(*i))
        .find_map(|(_, s)| s.parse().ok())
        .unwrap_or(1024);
    // Isolux casts in tiles of TILE x TILE rays culled together (as fidget
    // prunes per tile); `--per-ray` walks the BVH for every ray instead.
    let coherent = !args.iter().any(|a| a == "--per-ray");
    let threads = rayon::current_num_threads();
    let single = ThreadPool::Custom(
        rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap(),
    );
    println!(
        "primary rays {size}x{size}, best of {repeat}; times in ms; {threads} threads available; isolux vector instructions {} (cap with ISOLUX_SIMD=avx2|sse2)",
        isolux_geometry::simd::isa().name()
    );
    println!("| bumps | isolux 1T | fidget 1T | ratio 1T | isolux {threads}T | fidget {threads}T | ratio {threads}T | isolux hits | fidget hits |");
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for bumps in [0usize, 16, 64, 256] {
        let obj = bumpy_sphere(bumps);
        let (i1, ih) = best(repeat, || cast_rows(&obj, size, 0..size, coherent));
        let (in_, _) = best(repeat, || {
            (0..size.div_ceil(BAND))
                .into_par_iter()
                .map(|b| cast_rows(&obj, size, b * BAND..((b + 1) * BAND).min(size), coherent))
                .sum()
        });

        let shape = JitShape::from(fidget_tree(bumps));
        let run = |pool: &ThreadPool| {
            let cfg = VoxelRenderConfig {
                image_size: VoxelSize::from(size),
                tile_sizes: fidget::jit::JitFunction::tile_sizes_3d(),
                threads: Some(pool),
                ..Default::default()
            };
            let img = cfg.run(shape.clone()).expect("not cancelled");
            img.iter().filter(|p| p.depth > 0).count()
        };
        let (f1, fh) = best(repeat, || run(&single));
        let (fnn, _) = best(repeat, || run(&ThreadPool::Global));
        println!(
            "| {bumps} | {:.1} | {:.1} | {:.1}x | {:.1} | {:.1} | {:.1}x | {ih} | {fh} |",
            i1 * 1e3,
            f1 * 1e3,
            f1 / i1,
            in_ * 1e3,
            fnn * 1e3,
            fnn / in_
        );
    }
}
