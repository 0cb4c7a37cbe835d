#!/usr/bin/env bash
# bench_defaults: is the default amount of training enough on any material (issue 15)?
# For each grid point (direction subset, texel count, k) it compresses with the default
# options and with configs/converged.json (the same recipe, 4x the steps: 80 epochs,
# 8000..64000 steps), and compares the training RMSE (eq. 10, linear RGB / alpha).
# Target: default RMSE within 10% of the 4x run at every point.
#
# Data: one synthetic fabric, 128 x 128 texels, UTIA layout (PNG), generated once; the grid's
# stacks are links to its files: "view1" = one view (0/0) x 81 lights, "sub9x9" = 9 views x 9
# lights (every 9th of each). Texel counts come from --crop (the top-left S x S texels).
# Every point is 2000 + 8000 optimizer steps (an epoch of k x 81 images is never more than
# 10 steps here, so the default's minimum of 2000 steps decides): 5-10 minutes a point on 2
# idle cores (the default grid took 67 minutes on a shared, loaded machine).
#
# Usage: scripts/bench_defaults.sh [WORK_DIR]   (default build/bench_defaults)
#   NBTF_BENCH_GRID="view1:16:16 sub9x9:32:64 ..."   subset:size:k points instead of the default grid
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work=${1:-$root/build/bench_defaults}
grid=${NBTF_BENCH_GRID:-"view1:16:16 view1:32:32 sub9x9:64:500 view1:128:2000 sub9x9:128:16"}
bin=$root/build/bin
if [[ ! -x $bin/nbtf || ! -x $bin/nbtf-synth ]]; then
  cmake -S "$root" -B "$root/build" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$root/build" -j "$(nproc)" --target nbtf_cli nbtf_synth_cli >/dev/null
fi
mkdir -p "$work"

full=$work/fabric128_utia
if [[ ! -f $full/synth.json ]]; then
  echo "== generating the 128 x 128 UTIA fabric (once; cached in $full)"
  "$bin/nbtf-synth" --preset fabric --size 128x128 --layout utia --format png --seed 1 --no-ground-truth -q -o "$full"
fi

# view1: the first view folder whole (81 lights). sub9x9: 9 view folders, 9 lights in each.
make_subset() {
  local name=$1 out=$work/$1
  [[ -d $out ]] && return
  mkdir -p "$out.tmp"
  mapfile -t views < <(find "$full" -mindepth 1 -maxdepth 1 -type d -printf '%f\n' | sort)
  mapfile -t lights < <(find "$full/${views[0]}" -maxdepth 1 -name '*.png' -printf '%f\n' | sed 's/_tv.*//' | sort)
  local vstep=81 lstep=1
  [[ $name == sub9x9 ]] && vstep=9 lstep=9
  for ((v = 0; v < ${#views[@]}; v += vstep)); do
    mkdir -p "$out.tmp/${views[v]}"
    for ((l = 0; l < ${#lights[@]}; l += lstep)); do
      for f in "$full/${views[v]}/${lights[l]}"_*.png; do ln -s "$f" "$out.tmp/${views[v]}/"; done
    done
  done
  mv "$out.tmp" "$out"
}
make_subset view1
make_subset sub9x9

results=$work/results.txt
: > "$results"
echo "== $(nproc) cores, $(date -u '+%Y-%m-%d %H:%M UTC'), grid: $grid"
for point in $grid; do
  IFS=: read -r subset size k <<< "$point"
  for run in default long; do
    opts=()
    [[ $run == long ]] && opts=(--config "$root/configs/converged.json")
    stats=$work/${subset}_${size}_${k}_$run.json
    start=$(date +%s.%N)
    "$bin/nbtf" compress "$work/$subset" -o "$work/out.nbtf" --clusters "$k" --crop "0,0,$size,$size" --seed 1 -q \
      --stats-json "$stats" "${opts[@]}" > /dev/null
    echo "$subset $size $k $run $(python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); print(s["rmse_train"], s["steps"], s["epochs"], round(s["seconds"]["train"], 1), s["images"])' "$stats")" \
      | tee -a "$results"
  done
done

echo "== results"
python3 - "$results" <<'EOF'
import sys
rows = {}
for line in open(sys.argv[1]):
    subset, size, k, run, rmse, steps, epochs, seconds, images = line.split()
    rows.setdefault((subset, int(size), int(k), int(images)), {})[run] = (float(rmse), int(steps), int(epochs), float(seconds))
print("| stack | texels | k | default RMSE | steps (epochs) | train s | 4x RMSE | steps | train s | default / 4x |")
print("|---|---|---|---|---|---|---|---|---|---|")
verdicts = []
for (subset, size, k, images), r in rows.items():
    d, l = r["default"], r["long"]
    ratio = d[0] / l[0]
    name = f"{subset} ({images} images)"
    print(f"| {name} | {size} x {size} | {k} | {d[0]:.5f} | {d[1]} ({d[2]}) | {d[3]:.0f} | {l[0]:.5f} | {l[1]} | {l[3]:.0f} | {ratio:.3f} |")
    verdicts.append((f"{subset}_{size}_k{k}", ratio))
for name, ratio in verdicts:
    print(f"bench defaults_{name}: default RMSE {100 * (ratio - 1):+.1f}% vs the 4x run (target <= +10%) "
          f"{'PASS' if ratio <= 1.10 else 'FAIL'}")
EOF
