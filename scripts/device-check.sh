#!/usr/bin/env bash
# Runs on a lent NVIDIA machine (the `device` tool), over the folder that
# scripts/device-prepare.sh filled here, everything issue 7 asks to be
# measured on real hardware, in one call:
#   1. `isolux bench gpu --f64 --wavefront --sorted --checked --kernels`
#      on the gallery at 1920 x 1080 (real-time 4 spp, path traced 16 spp,
#      direct light; f32 and f64,
#      the megakernel, the wavefront path tracer and the sorted wavefront
#      with and without its sort by material, the kernels with and
#      without wgpu's run-time checks, and the CPU on all cores; then each
#      frame's GPU time kernel by kernel and step by step; the
#      columns of `--per-sample` and `--tiles` were 1.00-1.02 on an H200,
#      2026-12-04, and `--general`'s 2.6-9.6x, and are left out for
#      time), then
#      the same geometry with every material diffuse (a control: what the
#      material library costs); each table's "first hit" row times the
#      camera rays' intersection alone;
#   2. the conformance suite (its f64 assertion failed on the H100 at
#      b93c7db), the material, real-time and AOV tests;
#   3. the whole-image tests, the ignored ones included (the underwater
#      scene's variants with their table, and the bounds probe, right
#      after the warm-up: docs/gpu.md, "NVIDIA: open defects");
#   4. the kernels' registers and spills (kernel_stats), where the driver
#      reports them;
# and, after the warm-up, where device-prepare.sh built one, the baseline
# commit's `bench gpu` and this build's one after the other, for the
# change since then as a ratio of figures taken side by side.
# The log lands in $OUT/device-check.log. Each step has its own time limit
# so that a hang in one still reports the others; the whole takes about
# 9 minutes (on an H200, 2026-12-04: 477 s with the conformance binary
# and kernel_stats cut at 45 and 60 s, their limits since raised to 120
# and 90): run it with timeout_s = 590. QUICK=1 runs each step small (64 x 36, one repetition, no
# image tests): a dry run of the script itself on any machine with an
# adapter (lavapipe included).
set -uo pipefail
cd "$(dirname "$0")/.."
log=device-check.log
# shellcheck source=scripts/device-env.sh
. scripts/device-env.sh

size=(--width 1920 --height 1080)
repeat=(--repeat 10)
few=(--repeat 5)
if [ "${QUICK:-0}" = 1 ]; then
    size=(--width 64 --height 36)
    repeat=(--repeat 1)
    few=(--repeat 1)
fi
# Warm the GPU first: a freshly started machine reads its first minutes'
# real-time frames 3-5x slow (benchmarks.md, 2026-11-24).
step 45 "$bin/isolux" bench gpu --skip-cpu "${size[@]}" "${repeat[@]}"
# The underwater scene and its variants against the CPU, as a table
# (docs/gpu.md, "NVIDIA: open defects"): early, and printed whether or
# not it passes.
if [ "${QUICK:-0}" != 1 ]; then
    step 150 "$bin/images" --ignored --exact underwater_variants_match_the_cpu --nocapture
    # Whether any render kernel reads out of bounds on NVIDIA: the same
    # images with every index out of bounds clamped and read as zero
    # (docs/gpu.md, "Probing for indices out of bounds"; bit for bit on
    # lavapipe, underwater.toml included).
    step 60 "$bin/bounds" --include-ignored --nocapture
fi
# Not in the QUICK dry run: on lavapipe the baseline's kernels take minutes
# to compile (benchmarks.md: 70 s each at b93c7db), seconds on NVIDIA.
if [ -x "$bin/isolux-baseline" ] && [ "${QUICK:-0}" != 1 ]; then
    echo "device-check: baseline $(cat .device/baseline) against $(cat .device/commit)"
    # The scene by its path here: the baseline's default is its build
    # folder's. The gallery is b93c7db's but for the line `caustics =
    # "none"` (2026-12-04), a key b93c7db does not know and whose
    # behaviour is its only one: for that baseline its copy goes without
    # it (beside the original, for the environment map's relative path);
    # later baselines read the key.
    old_gallery=examples/scenes/.gallery-baseline.toml
    if [ "$(cat .device/baseline)" = b93c7db ]; then
        grep -v '^caustics = "none"' examples/scenes/gallery.toml >"$old_gallery"
    else
        cp examples/scenes/gallery.toml "$old_gallery"
    fi
    # Once each: on the H200 two rounds agreed within 0.3%.
    step 90 "$bin/isolux-baseline" bench gpu "$old_gallery" --skip-cpu "${size[@]}" "${repeat[@]}"
    step 45 "$bin/isolux" bench gpu examples/scenes/gallery.toml --skip-cpu "${size[@]}" "${repeat[@]}"
    rm -f "$old_gallery"
fi
step 255 "$bin/isolux" bench gpu --f64 --wavefront --sorted --checked --kernels "${size[@]}" "${repeat[@]}"
# The gallery's geometry with every material diffuse (examples/bench): how
# much of the frame the material library costs on this GPU.
step 60 "$bin/isolux" bench gpu examples/bench/gallery-diffuse.toml --skip-cpu "${size[@]}" "${few[@]}"
# With the ignored f32_condition_table: the f32 intersection of bumps that
# dwarf their base, the table behind F32_CONDITION_LIMIT (docs/gpu.md,
# "Precision"), measured on lavapipe only so far.
step 120 "$bin/conformance" --include-ignored --nocapture
if [ "${QUICK:-0}" != 1 ]; then
    step 60 "$bin/materials"
    step 45 "$bin/realtime"
    step 30 "$bin/aov"
    step 150 "$bin/images" --include-ignored --skip underwater_variants_match_the_cpu
fi
# Registers, spills and code size of each kernel, where the driver reports
# them (VK_KHR_pipeline_executable_properties): what occupancy the kernels
# allow, beside their times above. Last: the measurements come first.
step 90 "$bin/kernel_stats"
echo "device-check: done, $(date -u +%FT%TZ)"
