#!/usr/bin/env bash
# Installs the system packages trilab needs on Debian 12 (bookworm), only where missing:
#   - lavapipe (Mesa's CPU Vulkan driver) from bookworm-backports: Mesa 25.0.7 runs trilab's
#     kernels about 1.3x faster than bookworm's 22.3.6 (bunny, 160x120 camera, 20k random rays,
#     8 methods; median per cell 1.36x, 1.02-2.09x, over 36 interleaved runs on a shared 2-core
#     AMD EPYC: docs/drivers.md, "On Debian 12's own Mesa"), adds VK_KHR_ray_query, and prints its
#     machine code under GALLIVM_DEBUG=asm (trilab driver-stats; 22.3.6's release build does not);
#   - the Vulkan loader and headers, the Khronos validation layers, vulkaninfo, spirv-tools;
#   - Debian 12's shaderc 2023.2 as static libraries (libshaderc-dev, glslang-dev, spirv-tools):
#     build.rs's shaderc links them (crates/shaderc-link), so a first build takes minutes; without
#     them shaderc-sys builds shaderc, glslang and SPIRV-Tools from source (about 20 minutes on
#     2 cores), for which cmake, python3, git and g++ stay listed;
#   - procps, for the `kill` the Ctrl-C test sends SIGINT with;
#   - Debian 12's own lavapipe (Mesa 22.3.6) unpacked, not installed, under
#     ~/.cache/trilab/stock-mesa by scripts/stock-mesa.sh (an 8 MB download, once), so
#     tests/stock_mesa.rs can check trilab on the driver a user without backports has;
#   - Google's SwiftShader (Vulkan on the CPU with its own JIT, not Mesa) unpacked from
#     chromium-common, not installed, under ~/.cache/trilab/swiftshader by
#     scripts/swiftshader.sh (a 32 MB download, once), for tests/swiftshader.rs;
#   - LunarG's GFXReconstruct 0.9.18 (capture layer and gfxrecon-replay) unpacked from Debian 12's
#     gfxreconstruct, not installed, under ~/.cache/trilab/gfxreconstruct by
#     scripts/gfxreconstruct.sh (a 5 MB download, once), for `trilab repro` and tests/repro.rs.
# Safe to run repeatedly; needs root (or sudo) for apt; the stock driver is unpacked as the
# calling user.
set -euo pipefail

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

# liblz4-1 and libzstd1: GFXReconstruct's tools and layer link them.
# pocl-opencl-icd and the OpenCL headers: the device run's rehearsal (tests/device_run.rs) builds
# tinybvh's peer with OpenCL and runs its kernels on PoCL beside lavapipe, as a lent GPU runs
# them on its own OpenCL beside its Vulkan driver.
base_pkgs=(libvulkan1 libvulkan-dev vulkan-validationlayers vulkan-tools spirv-tools libshaderc-dev glslang-dev
  cmake python3 g++ pkg-config procps
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers
  liblz4-1 libzstd1)
missing=()
for p in "${base_pkgs[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done

# Mesa from backports: the installed mesa-vulkan-drivers must be 25.x, not bookworm's 22.3.6.
mesa_ver=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true)
need_mesa=1
case "$mesa_ver" in 2[5-9].*|3*) need_mesa=0 ;; esac

# Debian 12's own lavapipe and SwiftShader beside the installed driver (never installed over it); apt's lists are
# refreshed once if they do not know the bookworm package yet.
unpacked_drivers() {
  local script
  script="$(dirname "$0")/stock-mesa.sh"
  "$script" --quiet >/dev/null 2>&1 || { $SUDO apt-get update -qq && "$script" --quiet >/dev/null; }
  echo "install-deps: stock lavapipe for tests/stock_mesa.rs: $("$script" --quiet)"
  script="$(dirname "$0")/swiftshader.sh"
  "$script" --quiet >/dev/null 2>&1 || { $SUDO apt-get update -qq && "$script" --quiet >/dev/null; }
  echo "install-deps: SwiftShader for tests/swiftshader.rs: $("$script" --quiet)"
  script="$(dirname "$0")/gfxreconstruct.sh"
  "$script" --quiet >/dev/null 2>&1 || { $SUDO apt-get update -qq && "$script" --quiet >/dev/null; }
  echo "install-deps: GFXReconstruct for trilab repro: $("$script" --quiet)"
}

if [ ${#missing[@]} -eq 0 ] && [ $need_mesa -eq 0 ]; then
  echo "install-deps: all system packages present (mesa-vulkan-drivers $mesa_ver)"
  unpacked_drivers
  exit 0
fi

if [ $need_mesa -eq 1 ] && ! grep -rqs 'bookworm-backports' /etc/apt/sources.list /etc/apt/sources.list.d/; then
  echo "install-deps: enabling bookworm-backports"
  echo 'deb http://deb.debian.org/debian bookworm-backports main' | $SUDO tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
fi

export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}"
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
if [ $need_mesa -eq 1 ]; then
  echo "install-deps: installing mesa-vulkan-drivers from bookworm-backports"
  $SUDO apt-get install -y -qq --no-install-recommends -t bookworm-backports mesa-vulkan-drivers >/dev/null
fi
echo "install-deps: mesa-vulkan-drivers $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers)"
unpacked_drivers
