//! AOV layers on the GPU (`render --gpu --aov`) against the CPU's: the
//! first hit's albedo, outward normal and distance, averaged over each
//! pixel's samples. With 64 stratified samples per pixel both back ends
//! estimate the same pixel integrals, so away from edges (silhouettes and
//! material boundaries, where the two sample sets cut a discontinuity
//! differently) they agree closely:
//! - albedo: to 1e-5 (a per-material constant, the CPU's `albedo()`);
//! - normal: the angle between the mean normals below 3 degrees in every
//!   pixel, 0.1 degree on average (the bumps bend the surface within a
//!   pixel, and the two sample sets differ);
//! - depth: within 2% relative in every pixel, 0.05% on average.
//!
//! Measured on lavapipe (64 x 48, 64 spp, perturbed-sphere.toml): albedo
//! 5e-7, normal worst 0.87 degree, depth worst 0.5% (the means are
//! printed).
//! Also: in the real-time mode, and background pixels are 0 in every
//! layer on both.

mod common;

use isolux_core::Aovs;
use isolux_render::{render, RenderOptions};
use std::path::Path;

/// Pixels whose 3 x 3 neighbourhood on the CPU is all hit with one
/// albedo: away from silhouettes and material boundaries.
fn interior(a: &Aovs, w: usize, h: usize) -> Vec<usize> {
    let mut out = Vec::new();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            let ok = (-1i64..=1).all(|dy| {
                (-1i64..=1).all(|dx| {
                    let j = ((y as i64 + dy) as usize) * w + (x as i64 + dx) as usize;
                    a.depth[j] > 0.0 && a.albedo[j] == a.albedo[i]
                })
            });
            if ok {
                out.push(i);
            }
        }
    }
    out
}

fn compare(cpu: &Aovs, gpu: &Aovs, w: usize, h: usize, label: &str) {
    let inside = interior(cpu, w, h);
    assert!(
        inside.len() > w * h / 4,
        "{label}: {} interior pixels",
        inside.len()
    );
    let (mut worst_alb, mut worst_angle, mut worst_depth) = (0.0f64, 0.0f64, 0.0f64);
    let (mut mean_angle, mut mean_depth) = (0.0f64, 0.0f64);
    for &i in &inside {
        for k in 0..3 {
            worst_alb = worst_alb.max((cpu.albedo[i][k] - gpu.albedo[i][k]).abs() as f64);
        }
        let dot: f32 = (0..3).map(|k| cpu.normal[i][k] * gpu.normal[i][k]).sum();
        let angle = (dot.clamp(-1.0, 1.0) as f64).acos().to_degrees();
        let depth = ((cpu.depth[i] - gpu.depth[i]) / cpu.depth[i]).abs() as f64;
        worst_angle = worst_angle.max(angle);
        worst_depth = worst_depth.max(depth);
        mean_angle += angle / inside.len() as f64;
        mean_depth += depth / inside.len() as f64;
    }
    eprintln!(
        "{label}: {} interior pixels; worst albedo {worst_alb:.2e}, normal {worst_angle:.3} deg \
         (mean {mean_angle:.4}), depth {worst_depth:.2e} relative (mean {mean_depth:.2e})",
        inside.len()
    );
    assert!(worst_alb < 1e-5, "{label}: albedo {worst_alb}");
    assert!(
        worst_angle < 3.0 && mean_angle < 0.1,
        "{label}: normal {worst_angle} deg, mean {mean_angle}"
    );
    assert!(
        worst_depth < 2e-2 && mean_depth < 5e-4,
        "{label}: depth {worst_depth}, mean {mean_depth}"
    );
    // Background (no sample hits on either): 0 in every layer.
    for i in 0..w * h {
        if cpu.depth[i] == 0.0 && gpu.depth[i] == 0.0 {
            assert_eq!(gpu.albedo[i], [0.0; 3], "{label}: pixel {i}");
            assert_eq!(gpu.normal[i], [0.0; 3], "{label}: pixel {i}");
        }
    }
}

#[test]
fn gpu_aovs_match_the_cpu() {
    let Some(gpu) = common::open("AOV comparison") else {
        return;
    };
    let p =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenes/perturbed-sphere.toml");
    let mut scene = isolux_scene::load(&p).unwrap();
    scene.film.width = 64;
    scene.film.height = 48;
    scene.film.spp = 64;
    scene.integrator.max_depth = 2;
    let (w, h) = (64, 48);

    let options = RenderOptions {
        aov: true,
        realtime: false,
    };
    let (cpu, _) = render(&scene, &options, &|_, _| {}).unwrap();
    let (g, _) = gpu.render_with_aov(&scene, true, &|_, _| {}).unwrap();
    compare(
        cpu.aov.as_ref().unwrap(),
        g.aov.as_ref().unwrap(),
        w,
        h,
        "path",
    );

    // The real-time mode (16 samples per pixel, its own grid).
    scene.film.spp = 16;
    let options = RenderOptions {
        aov: true,
        realtime: true,
    };
    let (cpu, _) = render(&scene, &options, &|_, _| {}).unwrap();
    let (g, _) = gpu.render_realtime_with_aov(&scene, true).unwrap();
    let (ca, ga) = (cpu.aov.as_ref().unwrap(), g.aov.as_ref().unwrap());
    // Fewer samples: compare the albedo exactly and the geometry loosely.
    let inside = interior(ca, w, h);
    for &i in &inside {
        for k in 0..3 {
            assert!(
                (ca.albedo[i][k] - ga.albedo[i][k]).abs() < 1e-5,
                "realtime albedo at {i}"
            );
        }
        assert!(
            ((ca.depth[i] - ga.depth[i]) / ca.depth[i]).abs() < 1e-2,
            "realtime depth at {i}"
        );
    }
}

/// A first-hits frame (`Gpu::prepare_first_hits`, `isolux bench gpu`'s
/// "first hit" row) traces in its runs exactly the first hits the AOVs of
/// a render take: 5 then 3 samples give the layers of an 8-sample render
/// bit for bit, and a reset starts them over. It fails when a run traces
/// nothing (the bench would time an empty dispatch), when runs repeat
/// their sample positions, or when a reset leaves the layers.
#[test]
fn first_hit_frames_trace_the_renders_aovs() {
    let Some(gpu) = common::open("first-hit frames") else {
        return;
    };
    let p =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenes/perturbed-sphere.toml");
    let mut scene = isolux_scene::load(&p).unwrap();
    scene.film.width = 40;
    scene.film.height = 30;
    scene.film.spp = 8;
    scene.integrator.max_depth = 1;
    let (g, _) = gpu.render_with_aov(&scene, true, &|_, _| {}).unwrap();
    let want = g.aov.unwrap();
    assert!(want.depth.iter().filter(|&&d| d > 0.0).count() > 40 * 30 / 4);

    let mut frame = gpu.prepare_first_hits(&scene).unwrap();
    for round in 0..2 {
        frame.reset(&gpu);
        frame.run(&gpu, 5);
        frame.run(&gpu, 3);
        let got = frame.aovs(&gpu).unwrap();
        assert_eq!(got.depth, want.depth, "round {round}: depth");
        assert_eq!(got.normal, want.normal, "round {round}: normal");
        assert_eq!(got.albedo, want.albedo, "round {round}: albedo");
        let (img, _) = frame.image(&gpu).unwrap();
        assert!(
            img.rgb.iter().flatten().all(|&c| c == 0.0),
            "shades nothing"
        );
    }
}
