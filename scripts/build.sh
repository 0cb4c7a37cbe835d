#!/usr/bin/env bash
# Configures and builds nbtf (Release). Usage: scripts/build.sh [BUILD_DIR] [extra cmake args...]
set -euo pipefail
source "$(dirname "$0")/lib.sh"
build=${1:-$root/build}
shift || true
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake_build "$build"
