#!/usr/bin/env bash
# Installs, from Debian 12's packages, whatever ultrasim needs to build, run and test that this
# machine lacks. Idempotent: when everything is present it asks apt nothing and returns at once.
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config git python3 clang-format
  # libraries (DESIGN.md §4)
  libeigen3-dev zlib1g-dev libpng-dev libtomlplusplus-dev libcli11-dev
  # fiducials: AprilTag's detector and families; OpenCV for capture (V4L2 or image files),
  # image processing and the dodecahedron's PnP (libopencv-dev holds OpenCV's CMake package)
  libapriltag-dev libopencv-dev
  # sparse Cholesky (CHOLMOD) for the exact FEM, on single-threaded OpenBLAS: the serial build
  # starts no threads of its own and is as fast on one core as the threaded one
  libsuitesparse-dev libopenblas0-serial
  # headless EGL + GLES on Mesa's software rasteriser (libgl1-mesa-dri holds swrast/llvmpipe)
  libegl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri
  # the dedicated display: DRM/KMS page flips and GBM buffers (render/kms_display)
  libdrm-dev libgbm-dev
  # the trainer's controls: Dear ImGui (its GLES 3 backend is built from the package's source)
  libimgui-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # reference FEM solver for the accuracy tests (DESIGN.md §4)
  calculix-ccx
  # the charts in docs/ (scripts/plot_engines.py)
  python3-matplotlib
  # an independent peer for the probe's CAN frames and candump logs (tests/integration)
  python3-can
  # SocketCAN in a real kernel: a QEMU VM with a busybox initramfs (tests/vm), can-utils inside
  qemu-system-x86 busybox-static can-utils
)

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done

if ((${#missing[@]} == 0)); then
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
sudo_cmd=()
if [[ $(id -u) -ne 0 ]]; then sudo_cmd=(sudo); fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
