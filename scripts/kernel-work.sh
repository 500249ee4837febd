#!/usr/bin/env bash
# Instructions that lavapipe executes per frame of the GPU kernels, counted
# by valgrind (callgrind): a work meter repeatable to about 0.1%, where
# lavapipe's timings on a shared 2-core machine vary by 20-40% between runs.
# Lavapipe runs the kernels 8 lanes wide (256-bit SIMD) under a lane mask,
# and runs the body of an `if` even when no lane takes it (loops do stop when
# every lane is done): so code behind a branch that a GPU warp would skip
# still counts here. Read the counts as the work of the code that every
# sample runs (traversal, segment walk, root isolation, shading), and a
# rare branch's code as a cost on lavapipe only. What it cannot show at
# all is a GPU's registers and occupancy (crates/gpu/examples/kernel_stats.rs)
# or its memory system.
#
# Each count is the difference of two renders of one binary that differ only
# in samples per pixel (path traced: 17 and 1; real time: 20 and 4), so the
# process's start, the scene's load and the kernels' compilation (served from
# Mesa's shader cache, warmed by an uncounted run first) cancel out: what
# remains is 16 samples per pixel of the mode's kernels.
#
# usage: scripts/kernel-work.sh [--size WxH] [--mode path|realtime|both] BINARY[=LABEL]... -- SCENE...
# e.g.:  scripts/kernel-work.sh /tmp/isolux-old=before target/release/isolux=after -- examples/scenes/gallery.toml
set -euo pipefail
size=48x27
modes="path realtime"
bins=()
while [ $# -gt 0 ]; do
    case "$1" in
        --size) size="$2"; shift 2 ;;
        --mode) [ "$2" = both ] && modes="path realtime" || modes="$2"; shift 2 ;;
        --) shift; break ;;
        -h|--help) sed -n '2,18p' "$0"; exit 0 ;;
        *) bins+=("$1"); shift ;;
    esac
done
scenes=("$@")
if [ ${#bins[@]} -eq 0 ] || [ ${#scenes[@]} -eq 0 ]; then
    echo "usage: $0 [--size WxH] [--mode path|realtime|both] BINARY[=LABEL]... -- SCENE..." >&2
    exit 2
fi
command -v valgrind >/dev/null || { echo "$0: valgrind is not installed (apt-get install valgrind)" >&2; exit 1; }
w=${size%x*}
h=${size#*x}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

count() { # binary scene mode spp -> instructions
    local flags=(--gpu --width "$w" --height "$h" --spp "$4" -q -o "$tmp/out.png")
    [ "$3" = realtime ] && flags+=(--realtime)
    valgrind --tool=callgrind --callgrind-out-file="$tmp/cg.out" "$1" render "$2" "${flags[@]}" 2>"$tmp/log" >/dev/null \
        || { cat "$tmp/log" >&2; exit 1; }
    sed -n 's/.*I *refs: *//p' "$tmp/log" | tr -d ,
}

echo "lavapipe instructions per frame of 16 samples per pixel at ${w} x ${h} (millions)"
echo
echo "| scene | mode | binary | instructions (M) | per pixel and sample |"
echo "|---|---|---|---:|---:|"
for scene in "${scenes[@]}"; do
    for mode in $modes; do
        if [ "$mode" = path ]; then lo=1; hi=17; else lo=4; hi=20; fi
        for spec in "${bins[@]}"; do
            bin=${spec%%=*}
            label=${spec#*=}
            # Warm Mesa's shader cache under valgrind without counting
            # (valgrind's CPU reports other features than the host's, so a
            # native run's cache entries do not serve it).
            flags=(--gpu --width 8 --height 8 --spp "$lo" -q -o "$tmp/warm.png")
            [ "$mode" = realtime ] && flags+=(--realtime)
            valgrind --tool=none "$bin" render "$scene" "${flags[@]}" 2>/dev/null
            a=$(count "$bin" "$scene" "$mode" "$lo")
            b=$(count "$bin" "$scene" "$mode" "$hi")
            python3 -c "d=$b-$a; print(f'| $(basename "$scene") | $mode | $label | {d/1e6:.1f} | {d/($w*$h*16):.0f} |')"
        done
    done
done
