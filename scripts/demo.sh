#!/usr/bin/env bash
# The main job on the built-in default material: set up, build, generate the material
# (synthetic fabric, 100 x 100 texels, all 81 x 81 light/view images, UBO2003 layout),
# compress it with the default recipe (k = 1000 clusters), and evaluate the result against the stack.
# Output goes to demo_out/ (or $1). NBTF_DEMO_BUDGET=SECONDS trains for a time budget instead
# of the default recipe (deterministic: 12000 steps at k = 1000, about 5-8 minutes
# on 2 cores).
set -euo pipefail
source "$(dirname "$0")/lib.sh"
out=${1:-$root/demo_out}
budget=${NBTF_DEMO_BUDGET:-}  # seconds; empty: the default recipe (12000 steps, 5-8 minutes on 2 cores)
"$root/scripts/setup.sh"
"$root/scripts/build.sh" "$root/build"
bin=$root/build/bin
mkdir -p "$out"

echo "== 1/5 generating the default material (fabric, 100 x 100 texels, UBO2003 JPEG)"
"$bin/nbtf-synth" --preset fabric --size 100x100 --layout ubo2003 --seed 1 -o "$out/fabric"

echo "== 2/5 loading it"
"$bin/nbtf" info "$out/fabric" -q

training=(); what="configs/default.json"
if [[ -n $budget ]]; then training=(--time-budget "$budget"); what="${budget} s training budget"; fi
echo "== 3/5 compressing it (the default k = 1000, 10% of the images held out, $what)"
"$bin/nbtf" compress "$out/fabric" -o "$out/fabric.nbtf" --holdout 0.1 \
  "${training[@]}" --seed 1 --stats-json "$out/fabric_stats.json"

echo "== 4/5 the compressed file"
"$bin/nbtf" info "$out/fabric.nbtf"

echo "== 5/5 evaluating it against the stack"
"$bin/nbtf" eval "$out/fabric.nbtf" --reference "$out/fabric" -o "$out/report" -q
echo
echo "report: $out/report/report.html (also report.md, report.json)"
