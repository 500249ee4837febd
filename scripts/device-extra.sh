#!/usr/bin/env bash
# The second call of a device session, run at once after
# scripts/device-check.sh while the machine is still warm, over the same
# `.device/` (carry it again), with whatever device time is left: what
# device-check.sh leaves out, in order of worth, so that a call cut short
# by the session's budget still returns the first of them.
#   0. samples a run of the sorted wavefront (`bench gpu --runs`): the
#      gallery path traced and direct lit at 1920 x 1080 with 1, 2
#      (the default tile), 4, 8 and 16 samples' paths a run, to say
#      whether larger tiles (fewer, fuller steps; up to 5.8 GB) should
#      be the default;
#   1. how the GPU frame scales with the film: the gallery at 480 x 270,
#      960 x 540 and 3840 x 2160 (real time, path traced, direct light,
#      first hits), beside device-check.sh's 1920 x 1080;
#   2. GPU against the CPU on all cores on the scenes whose integrators
#      the gallery does not exercise: caustics through glass
#      (caustics.toml), lamps under water with a random-walk medium
#      (underwater.toml) and a translucent random walk
#      (translucent-random-walk.toml), at 1920 x 1080 (`bench gpu`'s
#      default size, whatever the scene's film), the megakernel, the
#      wavefront and the sorted wavefront (`-` where a medium leaves the
#      sort out);
#   3. the caustics scene rendered on the GPU to $OUT/caustics-gpu.exr at
#      240 x 160, 64 spp, for comparison with the CPU's image here
#      (docs/gpu.md, "Caustics").
# The log lands in $OUT/device-extra.log. QUICK=1 runs each step small.
set -uo pipefail
cd "$(dirname "$0")/.."
log=device-extra.log
# shellcheck source=scripts/device-env.sh
. scripts/device-env.sh

repeat=(--repeat 5)
sizes=("480 270" "960 540" "3840 2160")
scene_run=(--wavefront --sorted --repeat 3)
if [ "${QUICK:-0}" = 1 ]; then
    repeat=(--repeat 1)
    sizes=("32 18")
    scene_run=(--wavefront --sorted --width 32 --height 18 --repeat 1)
fi
# The first seconds warm the GPU up (a fresh clock reads slow), though
# this call follows device-check.sh's on a machine still warm.
if [ "${QUICK:-0}" = 1 ]; then
    step 60 "$bin/isolux" bench gpu --skip-cpu --runs --width 32 --height 18 --repeat 1
else
    step 90 "$bin/isolux" bench gpu --skip-cpu --runs --width 1920 --height 1080 "${repeat[@]}"
fi
for wh in "${sizes[@]}"; do
    read -r w h <<<"$wh"
    step 60 "$bin/isolux" bench gpu --skip-cpu --width "$w" --height "$h" "${repeat[@]}"
done
for scene in caustics underwater translucent-random-walk; do
    step 90 "$bin/isolux" bench gpu "examples/scenes/$scene.toml" "${scene_run[@]}"
done
step 60 "$bin/isolux" render --gpu -q examples/scenes/caustics.toml \
    --width 240 --height 160 --spp 64 -o "$out/caustics-gpu.exr"
echo "device-extra: done, $(date -u +%FT%TZ)"
