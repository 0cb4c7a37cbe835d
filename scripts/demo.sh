#!/usr/bin/env bash
# The main job on the built-in default material: set up, build, generate the material,
# and load it. Output goes to demo_out/ (or $1).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/demo_out}
"$root/scripts/setup.sh"
"$root/scripts/build.sh" "$root/build"
bin=$root/build/bin
mkdir -p "$out"
echo "== generating the default material (fabric, 100 x 100 texels, UBO2003 layout)"
"$bin/nbtf-synth" --preset fabric --size 100x100 --layout ubo2003 --seed 1 -o "$out/fabric"
echo "== loading it"
"$bin/nbtf" info "$out/fabric"
