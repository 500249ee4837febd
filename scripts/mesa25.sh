#!/usr/bin/env bash
# Runs a command on Mesa 25's Vulkan drivers, unpacked beside the system's
# Mesa 22.3 (which the CI uses) and never installed over it: a second
# compiler for the GPU kernels on a machine without a GPU.
#
#   bash scripts/mesa25.sh lvp  CMD [ARGS...]   # Mesa 25's lavapipe: runs the kernels on the CPU
#   bash scripts/mesa25.sh radv CMD [ARGS...]   # RADV's null device (navi21): compiles only,
#                                               # for crates/gpu/examples/kernel_stats
#
# e.g. the GPU image tests on Mesa 25's lavapipe:
#
#   cargo test --release -p isolux-gpu --no-run
#   bash scripts/mesa25.sh lvp cargo test --release -p isolux-gpu --test images
#
# The first call downloads mesa-vulkan-drivers 25.0.7 and the libdrm it
# needs from bookworm-backports into /opt/mesa25 (apt-get download and
# dpkg -x: nothing is installed) and writes ICD files with absolute library
# paths there. Mesa 25 has the same LLVM 15 as Mesa 22.3 but three years of
# NIR passes more; see docs/gpu.md, "NVIDIA: open defects" and "Register
# pressure, as a GPU compiler sees it".
set -euo pipefail
kind=${1:-}
case "$kind" in
lvp | radv) shift ;;
*)
    echo "usage: bash scripts/mesa25.sh lvp|radv CMD [ARGS...]" >&2
    exit 2
    ;;
esac
if [ $# -eq 0 ]; then
    echo "mesa25: no command to run" >&2
    exit 2
fi
dir=/opt/mesa25
lib=$dir/root/usr/lib/x86_64-linux-gnu
if [ ! -f "$dir/lvp.json" ] || [ ! -f "$dir/radeon.json" ]; then
    echo "mesa25: unpacking Mesa 25.0.7 into $dir" >&2
    list=/etc/apt/sources.list.d/backports.list
    grep -qs bookworm-backports "$list" ||
        echo "deb http://deb.debian.org/debian bookworm-backports main" >"$list"
    apt-get update -qq
    mkdir -p "$dir"
    (
        cd "$dir"
        rm -f ./*.deb
        apt-get download -q mesa-vulkan-drivers=25.0.7-2~bpo12+1 \
            libdrm2=2.4.123-1~bpo12+1 libdrm-amdgpu1=2.4.123-1~bpo12+1
        for deb in ./*.deb; do dpkg -x "$deb" root; done
    )
    icd=$dir/root/usr/share/vulkan/icd.d
    sed "s#\"libvulkan_lvp.so\"#\"$lib/libvulkan_lvp.so\"#" "$icd/lvp_icd.json" >"$dir/lvp.json"
    sed "s#\"libvulkan_radeon.so\"#\"$lib/libvulkan_radeon.so\"#" "$icd/radeon_icd.json" >"$dir/radeon.json"
fi
export LD_LIBRARY_PATH="$lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
# Mesa's device-select layer prints "XDG_RUNTIME_DIR is invalid" lines on a
# headless machine; the loader wants a runtime folder anyway.
export NODEVICE_SELECT=1
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
if [ "$kind" = lvp ]; then
    export VK_ICD_FILENAMES=$dir/lvp.json
else
    export VK_ICD_FILENAMES=$dir/radeon.json
    export RADV_FORCE_FAMILY=${RADV_FORCE_FAMILY:-navi21}
fi
exec "$@"
