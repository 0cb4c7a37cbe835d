#!/usr/bin/env bash
# Installs what nbtf needs, builds it (Release), and runs every test through ctest.
#   scripts/test.sh              the normal run (what CI calls)
#   scripts/test.sh --sanitize   the same suite built with AddressSanitizer + UBSan
set -euo pipefail
source "$(dirname "$0")/lib.sh"
build=$root/build
cmake_args=()
if [[ "${1:-}" == "--sanitize" ]]; then
  build=$root/build-sanitize
  cmake_args+=(-DNBTF_SANITIZE=ON)
fi
"$root/scripts/setup.sh"
"$root/scripts/build.sh" "$build" "${cmake_args[@]}"
cd "$build"
ctest --output-on-failure -j "$(nproc)" --timeout 900
