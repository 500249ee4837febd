//! How well the wavefront's steps use a SIMT group's lanes, counted on a
//! render's own paths: a model of what the sorted wavefront saves on a GPU
//! of warp width `W` (8 lanes: lavapipe's AVX2 vectors; 32: NVIDIA; 64:
//! AMD's wave64), measured on any adapter, lavapipe included.
//!
//! ```text
//! cargo run --release -p isolux-gpu --example wavefront_lanes [-- SCENE.toml ...]
//!     [--width 1920] [--height 1080] [--samples 2]
//! ```
//!
//! The film must fit one wavefront tile: 1920 x 1080 on a GPU; lavapipe
//! binds 1.19 M paths, so there `--width 1280 --height 720` (docs/gpu.md,
//! "The sorted wavefront", has the figures of that size).
//!
//! Each sample of each scene (default: the gallery) is rendered by the
//! sorted wavefront, one tile, and `GpuFrame::sorted_steps` tells, per
//! path, the steps whose `trace_extend` found it a surface to shade. The
//! model then counts SIMT groups:
//!
//! - the plain wavefront's `trace` takes a step's queue in slot order (as
//!   its queue is built, warp by warp in lane order) in groups of `W`
//!   paths; a group with one path to shade runs the shading code with
//!   all its lanes, so each group with at least one is a *shading group*;
//! - the sorted wavefront's `trace_extend` takes the same groups, but
//!   shades in `trace_shade` only the listed paths, by material: per
//!   material `ceil(n / W)` groups.
//!
//! Both intersect the same rays; the difference is the shading groups. A
//! step's queue is approximated by the paths listed the step before (those
//! the shading then ended are few; the real queue's length is printed
//! beside it). The model knows nothing of the shading's cost per group or
//! of the memory traffic the sort adds: it says how much shading work
//! divergence adds to the plain wavefront, not the time
//! (docs/gpu.md, "The sorted wavefront").
use isolux_gpu::{Gpu, SortedSteps};
use std::path::PathBuf;

fn main() {
    if let Err(e) = run() {
        eprintln!("wavefront_lanes: {e}");
        std::process::exit(1);
    }
}

/// Options: scenes, film size, samples.
struct Args {
    scenes: Vec<PathBuf>,
    width: u32,
    height: u32,
    samples: u32,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        scenes: Vec::new(),
        width: 1920,
        height: 1080,
        samples: 2,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut number = |name: &str| -> Result<u32, String> {
            let v = it.next().ok_or(format!("{name} needs a value"))?;
            v.parse::<u32>()
                .ok()
                .filter(|&n| (1..=16384).contains(&n))
                .ok_or(format!("{name}: expected 1-16384, got {v:?}"))
        };
        match arg.as_str() {
            "--width" => a.width = number("--width")?,
            "--height" => a.height = number("--height")?,
            "--samples" => a.samples = number("--samples")?.min(64),
            s if s.starts_with("--") => return Err(format!("unknown option {s}")),
            s => a.scenes.push(s.into()),
        }
    }
    if a.scenes.is_empty() {
        a.scenes.push(
            concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../examples/scenes/gallery.toml"
            )
            .into(),
        );
    }
    Ok(a)
}

/// Warp widths modelled.
const WIDTHS: [usize; 3] = [8, 32, 64];

/// One step's counts, summed over samples: paths listed to shade, and per
/// warp width (groups, shading groups of `trace`, shading groups of
/// `trace_shade`, material branches of `trace`'s shading groups).
#[derive(Clone, Copy, Default)]
struct Step {
    listed: u64,
    groups: [(u64, u64, u64, u64); WIDTHS.len()],
}

/// Steps whose material branches are counted (one render each).
const BRANCH_STEPS: usize = 4;

/// The model's counts for one sample's paths (`sort`), with per step `k <
/// BRANCH_STEPS` the bins of its listed paths (`at[k]`, a render whose
/// paths end at depth `k + 1`: the same paths, their last list step `k`'s).
fn count(sort: &SortedSteps, at: &[SortedSteps], padded: usize, steps: &mut Vec<Step>) {
    let n = sort.lengths.len();
    if steps.len() < n {
        steps.resize(n, Step::default());
    }
    for (k, step) in steps.iter_mut().enumerate().take(n) {
        // The step's queue in slot order (the tile's pixels on step 0;
        // after, the paths listed the step before): each path's bin if it
        // is listed to shade at step k.
        let bin = |s: usize| at.get(k).map_or(0, |b| b.bins[s]);
        let queue: Vec<Option<u32>> = (0..padded)
            .filter(|&s| k == 0 || sort.listed[s] as usize >= k)
            .map(|s| (sort.listed[s] as usize > k).then(|| bin(s)))
            .collect();
        step.listed += sort.lengths[k] as u64;
        for (g, &width) in step.groups.iter_mut().zip(&WIDTHS) {
            g.0 += queue.len().div_ceil(width) as u64;
            for group in queue.chunks(width) {
                let mut bins: Vec<u32> = group.iter().flatten().copied().collect();
                bins.sort_unstable();
                bins.dedup();
                g.1 += !bins.is_empty() as u64;
                g.3 += bins.len() as u64;
            }
            g.2 += sort.counts[k]
                .iter()
                .map(|&n| (n as usize).div_ceil(width) as u64)
                .sum::<u64>();
        }
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let a = args().map_err(|e| {
        format!(
            "{e}\nusage: wavefront_lanes [SCENE.toml ...] [--width N] [--height N] [--samples N]"
        )
    })?;
    let gpu = Gpu::new()?;
    println!(
        "adapter: {}; {} x {}, {} samples",
        gpu.adapter, a.width, a.height, a.samples
    );
    for path in &a.scenes {
        let mut scene = isolux_scene::load(path)?;
        isolux_gpu::replace_unsupported(&mut scene);
        scene.film.width = a.width;
        scene.film.height = a.height;
        // The scene's sorted wavefront in one tile of the whole film.
        let padded = isolux_gpu::padded_pixels(a.width, a.height) as usize;
        let sorted_frame = |scene: &isolux_render::Scene| {
            gpu.prepare(scene).map(|mut f| {
                f.set_wavefront(true);
                f.set_sorted(true);
                f.set_wavefront_tile(padded as u64);
                f
            })
        };
        let mut frame = sorted_frame(&scene)?;
        if !frame.sorted() {
            println!(
                "\n{}: the subsurface integrator, not sorted",
                path.display()
            );
            continue;
        }
        // The same scene with paths that end at depth k + 1.
        let depth = scene.integrator.max_depth as usize;
        let mut limited = Vec::new();
        for k in 0..BRANCH_STEPS.min(depth) {
            scene.integrator.max_depth = k as u32 + 1;
            limited.push(sorted_frame(&scene)?);
        }
        let sorted = |f: &isolux_gpu::GpuFrame| -> Result<SortedSteps, String> {
            let sort = f
                .sorted_steps(&gpu)
                .map_err(|e| e.to_string())?
                .ok_or("the sorted wavefront did not run")?;
            if sort.listed.len() < padded {
                return Err(format!(
                    "the film ({padded} paths) does not fit one tile on this adapter: try --width 1280 --height 720"
                ));
            }
            Ok(sort)
        };
        let mut steps = Vec::new();
        let mut queued = Vec::new();
        for _ in 0..a.samples {
            frame.run(&gpu, 1);
            let sort = sorted(&frame)?;
            let mut at = Vec::new();
            for (k, f) in limited.iter_mut().enumerate() {
                f.run(&gpu, 1);
                let s = sorted(f)?;
                if s.lengths[k] != sort.lengths[k] {
                    return Err(format!(
                        "step {k}: {} paths listed at depth {}, {} at depth {depth}: not the same paths",
                        s.lengths[k],
                        k + 1,
                        sort.lengths[k]
                    )
                    .into());
                }
                at.push(s);
            }
            let q = frame.wavefront_steps(&gpu)?.unwrap_or_default();
            queued.resize(queued.len().max(q.len()), 0u64);
            for (s, n) in queued.iter_mut().zip(&q) {
                *s += *n as u64;
            }
            count(&sort, &at, padded, &mut steps);
        }
        let n = a.samples as u64;
        println!("\n{} (per sample)\n", path.display());
        print!("| step | queued | listed to shade |");
        for w in WIDTHS {
            print!(" W={w}: groups | shading, `trace` | material branches, `trace` | shading, sorted |");
        }
        println!();
        println!(
            "|---:|---:|---:|{}",
            "---:|---:|---:|---:|".repeat(WIDTHS.len())
        );
        let mut all = Step::default();
        for (k, s) in steps.iter().enumerate() {
            let q = queued.get(k).copied().unwrap_or(0);
            print!("| {k} | {} | {} |", q / n, s.listed / n);
            all.listed += s.listed;
            for (g, t) in s.groups.iter().zip(all.groups.iter_mut()) {
                let branches = if k < limited.len() {
                    (g.3 / n).to_string()
                } else {
                    "-".into()
                };
                print!(" {} | {} | {branches} | {} |", g.0 / n, g.1 / n, g.2 / n);
                t.0 += g.0;
                t.1 += g.1;
                t.2 += g.2;
            }
            println!();
        }
        print!("| all | | {} |", all.listed / n);
        for t in &all.groups {
            print!(" {} | {} | | {} |", t.0 / n, t.1 / n, t.2 / n);
        }
        println!("\n");
        for (i, w) in WIDTHS.iter().enumerate() {
            let first = &steps[..limited.len().min(steps.len())];
            let (branches, sorted): (u64, u64) = first
                .iter()
                .map(|s| (s.groups[i].3, s.groups[i].2))
                .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
            println!(
                "W={w}, steps 0-{}: material branches of the shading, sorted / trace {:.3} ({} / {})",
                first.len().saturating_sub(1),
                sorted as f64 / branches.max(1) as f64,
                sorted / n,
                branches / n
            );
        }
        for (w, t) in WIDTHS.iter().zip(&all.groups) {
            let busy = |g: u64| 100.0 * all.listed as f64 / (*w as u64 * g).max(1) as f64;
            println!(
                "W={w}: shading groups, sorted / trace {:.3}; lanes that shade, in trace's shading groups {:.1}%, in the sorted's {:.1}%",
                t.2 as f64 / t.1.max(1) as f64,
                busy(t.1),
                busy(t.2)
            );
        }
    }
    Ok(())
}
