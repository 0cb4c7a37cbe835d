#!/usr/bin/env bash
# Configures and builds nbtf (Release). Usage: scripts/build.sh [BUILD_DIR] [extra cmake args...]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
shift || true
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
# (grep only filters: with pipefail the pipeline fails exactly when the build does)
cmake --build "$build" -j "$(nproc)" -- --no-print-directory 2>&1 | { grep -vE '^\[ *[0-9]+%\] (Building|Linking)|^Scanning|^Consolidate' || true; }
