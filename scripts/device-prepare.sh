#!/usr/bin/env bash
# Prepares, on this (CPU-only) machine, the folder `.device/` that the
# `device` tool carries to a lent NVIDIA machine, which has no network and
# no Rust toolchain: the release `isolux` binary and the GPU crate's test
# binaries (conformance, images, materials, realtime, aov), built here,
# stripped and gzipped, the Vulkan
# loader's Debian package, the kernel_stats example (registers and spills
# per kernel), and the commit they were built from; and the release
# `isolux` of a baseline commit (`isolux-baseline`), which device-check.sh
# times beside this build in the same run, so that the change since the
# last measurement reads as a ratio of one session's figures (the
# machines are shared, and a freshly started one reads slow).
#
#   bash scripts/device-prepare.sh              # baseline: 6f93828, the last commit measured on NVIDIA (an H200, 2026-12-04)
#   BASELINE=<commit> bash scripts/device-prepare.sh
#   BASELINE= bash scripts/device-prepare.sh    # no baseline
#   # then, with the device tool:
#   #   run(command = "bash scripts/device-check.sh", carry = [".device"], timeout_s = 590)
#   #   and at once, while the machine is warm, with the device time left:
#   #   run(command = "bash scripts/device-extra.sh", carry = [".device"])
#
# `.device/` is ignored through .git/info/exclude (this script adds it), so
# it never lands in a commit. See docs/gpu.md, "For the next session with
# a device".
set -euo pipefail
cd "$(dirname "$0")/.."
exclude=.git/info/exclude
mkdir -p "$(dirname "$exclude")"
grep -qx '/.device/' "$exclude" 2>/dev/null || echo '/.device/' >>"$exclude"
rm -rf .device
mkdir -p .device/bin .device/gl

echo "device-prepare: Vulkan loader and libglvnd packages"
lists=/tmp/device-apt-lists
mkdir -p "$lists/partial"
apt_opts=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 "-oDir::State::Lists=$lists")
apt-get "${apt_opts[@]}" update -qq
# libglvnd beside the loader: NVIDIA's Vulkan driver is libGLX_nvidia.so.0,
# which without libGLdispatch hands the loader no vkCreateInstance ("Found
# no drivers"; an H200, 2026-12-04).
(cd .device/gl && apt-get "${apt_opts[@]}" download libvulkan1 libglvnd0 libglx0 libgl1 libegl1 libopengl0 libgles2)

echo "device-prepare: release binaries"
cargo build --release -p isolux
strip -o .device/bin/isolux target/release/isolux
gzip -f .device/bin/isolux
# The kernels' register counts and spills as the driver's compiler reports
# them (crates/gpu/examples/kernel_stats.rs).
cargo build --release -p isolux-gpu --example kernel_stats
strip -o .device/bin/kernel_stats target/release/examples/kernel_stats
gzip -f .device/bin/kernel_stats
# The baseline, from its own source tree and target folder (two checkouts
# sharing one target folder can link one's crates into the other's
# binary: cargo names path crates' artifacts by their path relative to
# the workspace).
baseline=${BASELINE-6f93828}
if [ -n "$baseline" ]; then
    echo "device-prepare: baseline $baseline"
    base_src=/tmp/isolux-baseline-src
    rm -rf "$base_src"
    mkdir -p "$base_src"
    git archive "$baseline" | tar -x -C "$base_src"
    CARGO_TARGET_DIR=/tmp/isolux-baseline-target \
        cargo build --release --locked --manifest-path "$base_src/Cargo.toml" -p isolux
    strip -o .device/bin/isolux-baseline /tmp/isolux-baseline-target/release/isolux
    gzip -f .device/bin/isolux-baseline
    git rev-parse --short "$baseline" >.device/baseline
fi
# The test binaries' paths, from cargo's own report of what it built.
cargo test --release -p isolux-gpu --tests --no-run \
    --message-format=json 2>/dev/null |
    python3 -c '
import json, sys
for line in sys.stdin:
    try:
        m = json.loads(line)
    except ValueError:
        continue
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["kind"] == ["test"]:
        print(m["target"]["name"], m["executable"])
' | while read -r name exe; do
    strip -o ".device/bin/$name" "$exe"
    gzip -f ".device/bin/$name"
done
# The tests find the example scenes through the source path they were
# built at (CARGO_MANIFEST_DIR); device-check.sh links it to its checkout.
pwd >.device/source-dir
git rev-parse --short HEAD >.device/commit
git status --porcelain --untracked-files=no | grep -q . && echo "+ uncommitted changes" >>.device/commit
ls -la .device/bin .device/gl
du -sh .device
