# Sourced by scripts/device-check.sh and scripts/device-extra.sh on a lent
# NVIDIA machine: checks that `.device/` came along, installs the Vulkan
# loader where the machine has none, points the loader at NVIDIA's driver,
# links the source path the test binaries were built at to this checkout,
# unpacks the binaries into $bin, prints the GPU and its clocks, and
# defines `step LIMIT COMMAND...`, which runs one command under its own
# time limit and reports its exit status and duration. The caller sets
# `log` (the log's file name under $OUT) before sourcing.
out=${OUT:-/tmp/device-check}
mkdir -p "$out"
exec > >(tee "$out/$log") 2>&1

if [ ! -d .device/bin ]; then
    echo "$log: no .device/ here: run scripts/device-prepare.sh and carry .device" >&2
    exit 2
fi
echo "$log: commit $(cat .device/commit), $(date -u +%FT%TZ)"
# The Vulkan loader and libglvnd (NVIDIA's Vulkan driver lives in
# libGLX_nvidia.so.0, which without libGLdispatch cannot hand the loader
# vkCreateInstance: "Found no drivers", seen on an H200, 2026-12-04).
for f in .device/gl/*.deb; do dpkg -x "$f" /; done
ldconfig
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -e "$icd" ] && export VK_DRIVER_FILES=$icd
src=$(cat .device/source-dir)
if [ ! -e "$src" ]; then
    mkdir -p "$(dirname "$src")"
    ln -s "$PWD" "$src"
fi
bin=/tmp/isolux-bin
mkdir -p "$bin"
for f in .device/bin/*.gz; do
    gunzip -c "$f" >"$bin/$(basename "$f" .gz)"
    chmod +x "$bin/$(basename "$f" .gz)"
done
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm --format=csv || true
nproc

step() {
    local limit=$1
    shift
    echo
    echo "==== $* (limit ${limit} s)"
    local t0=$SECONDS
    timeout "$limit" "$@"
    echo "==== rc $? after $((SECONDS - t0)) s"
}

