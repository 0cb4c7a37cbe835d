#!/usr/bin/env bash
# Installs every Debian package nbtf needs. Idempotent: quiet and fast when all is there.
set -euo pipefail

PACKAGES=(
  cmake g++ make pkg-config
  libtorch-dev            # the neural model (CPU)
  libopenblas0-openmp     # without it libtorch falls back to the reference BLAS (~40x slower)
  libopencv-dev           # image decoding / encoding
  libeigen3-dev           # PCA, k-means
  libopenexr-dev          # half / float EXR
  libcxxopts-dev          # command-line options
  libgtest-dev            # tests
  nlohmann-json3-dev      # configs, reports
  libzstd-dev             # entropy coding of the id list and per-texel codes in .nbtf files
  libgloo-dev             # headers of libtorch's distributed backend (c10d Gloo): data-parallel training
  libgoogle-glog-dev      # libtorch's logging, initialized quietly by nbtf (src/model/autograd/torch_logging.cpp)
  pybind11-dev python3-dev python3-numpy  # the Python module `nbtf` (python/, docs/python.md)
  python3-pytest          # its tests (tests/python, run by ctest)
  chromium                # headless browser test of the viewer (tests/viewer_browser_test.cpp; WebGL2 on SwiftShader)
  blender                 # renders an exported glTF material headless with Cycles (tests/gltf_blender_test.py)
)
# Extra packages for optional tools: pass --with NAME... (e.g. python3-sklearn for bench_cluster.sh)
while [[ $# -gt 0 ]]; do
  case "$1" in
    --with) shift; PACKAGES+=("$1");;
    *) echo "setup.sh: unknown option '$1'" >&2; exit 2;;
  esac
  shift
done

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[[ ${#missing[@]} -eq 0 ]] && exit 0

echo "setup: installing ${missing[*]}"
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup: done"
