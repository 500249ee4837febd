#!/usr/bin/env bash
# Prepares, on this (CPU-only) machine, the folder `.device/` that the
# `device` tool carries to a lent NVIDIA machine, which has no network and
# no Rust toolchain: the release `isolux` binary and the GPU crate's test
# binaries (conformance, images, materials, realtime, aov), built here,
# stripped and gzipped, the Vulkan
# loader's Debian package, the kernel_stats example (registers and spills
# per kernel), and the commit they were built from.
#
#   bash scripts/device-prepare.sh
#   # then, with the device tool:
#   #   run(command = "bash scripts/device-check.sh", carry = [".device"], timeout_s = 560)
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

echo "device-prepare: Vulkan loader package"
lists=/tmp/device-apt-lists
mkdir -p "$lists/partial"
apt_opts=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 "-oDir::State::Lists=$lists")
apt-get "${apt_opts[@]}" update -qq
(cd .device/gl && apt-get "${apt_opts[@]}" download libvulkan1)

echo "device-prepare: release binaries"
cargo build --release -p isolux
strip -o .device/bin/isolux target/release/isolux
gzip -f .device/bin/isolux
# The kernels' register counts and spills as the driver's compiler reports
# them (crates/gpu/examples/kernel_stats.rs).
cargo build --release -p isolux-gpu --example kernel_stats
strip -o .device/bin/kernel_stats target/release/examples/kernel_stats
gzip -f .device/bin/kernel_stats
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
