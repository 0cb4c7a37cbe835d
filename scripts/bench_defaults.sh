#!/usr/bin/env bash
# bench_defaults: is the default amount of training enough on any material?
# For each grid point (direction subset, texel count, k) it compresses with the default
# options and with configs/converged.json (the same recipe, 4x the steps: 80 epochs,
# 8000..48000 steps, 96 steps per encoder input), and compares the training RMSE (eq. 10,
# linear RGB / alpha). Target: default RMSE within 10% of the 4x run at every point.
# The table also gives the cluster-mean floor (with the per-texel modulation), a lower bound
# for any run: the training MSE is the floor's plus the network's, so a default within 10% of
# the floor is within 10% of any longer run.
#
# Data: one synthetic fabric, 128 x 128 texels (256 x 256 for points larger than 128), UTIA
# layout (PNG), generated once; the grid's stacks are links to its files: "view1" = one view
# (0/0) x 81 lights, "views3" = 3 views (every 27th) x 81 lights (243 images: the learning-rate
# rule's middle, x 1.45), "sub9x9" = 9 views x 9 lights (every 9th of each), "full" = all 6561
# images. Texel counts come from --crop (the top-left S x S texels). On these stacks the
# default trains max(2000, 24 k) steps, at most 12000, and the 4x run 4x that: from 10,000
# steps a point (k <= 83) to 48,000 (k >= 500), about 5 to 25 minutes a point on 2 idle
# cores with --threads 2.
#
# Usage: scripts/bench_defaults.sh [WORK_DIR]   (default build/bench_defaults)
#   NBTF_BENCH_GRID="view1:16:16 sub9x9:32:64 ..."   subset:size:k points instead of the default grid
#   NBTF_BENCH_RUNS="default long"                   which of the two runs (default: both)
#   NBTF_BENCH_THREADS=1                             --threads of every run (the RMSE does not depend on it)
set -euo pipefail
source "$(dirname "$0")/lib.sh"
work=${1:-$root/build/bench_defaults}
grid=${NBTF_BENCH_GRID:-"view1:16:16 view1:32:32 sub9x9:64:500 view1:128:2000 sub9x9:128:16 view1:256:125"}
runs=${NBTF_BENCH_RUNS:-default long}
threads=${NBTF_BENCH_THREADS:-1}
# NBTF_BIN_DIR: binaries to measure (default: build them into build/).
nbtf_build
mkdir -p "$work"

# The fabric of a size (128 x 128, or 256 x 256 for larger points), generated once and cached.
source_of() {
  local n=128
  (($1 > 128)) && n=256
  local src=$work/fabric${n}_utia
  synth_once "$src" --preset fabric --size "${n}x${n}" --layout utia --format png --seed 1 --no-ground-truth -q
  echo "$src"
}

# view1: the first view folder whole (81 lights). views3: 3 view folders whole. sub9x9: 9 view
# folders, 9 lights in each.
# full: the whole stack.
make_subset() {
  local name=$1 full=$2 out=$3
  [[ -e $out ]] && return
  if [[ $name == full ]]; then
    ln -s "$full" "$out"
    return
  fi
  mkdir -p "$out.tmp"
  mapfile -t views < <(find -H "$full" -mindepth 1 -maxdepth 1 -type d -printf '%f\n' | sort)
  mapfile -t lights < <(find -H "$full/${views[0]}" -maxdepth 1 -name '*.png' -printf '%f\n' | sed 's/_tv.*//' | sort)
  local vstep=81 lstep=1
  [[ $name == sub9x9 ]] && vstep=9 lstep=9
  [[ $name == views3 ]] && vstep=27
  for ((v = 0; v < ${#views[@]}; v += vstep)); do
    mkdir -p "$out.tmp/${views[v]}"
    for ((l = 0; l < ${#lights[@]}; l += lstep)); do
      for f in "$full/${views[v]}/${lights[l]}"_*.png; do ln -s "$f" "$out.tmp/${views[v]}/"; done
    done
  done
  mv "$out.tmp" "$out"
}

# subset size -> the stack's folder: <subset> of the 128 x 128 fabric, <subset>_256 of the other.
stack_of() {
  local src out
  src=$(source_of "$2")
  out=$work/$1
  (($2 > 128)) && out=$work/${1}_256
  make_subset "$1" "$src" "$out"
  echo "$out"
}

results=$work/results.txt
: > "$results"
echo "== $(nproc) cores, $(date -u '+%Y-%m-%d %H:%M UTC'), grid: $grid, runs: $runs, --threads $threads"
for point in $grid; do
  IFS=: read -r subset size k <<< "$point"
  stack=$(stack_of "$subset" "$size")
  for run in $runs; do
    opts=()
    [[ $run == long ]] && opts=(--config "$root/configs/converged.json")
    stats=$work/${subset}_${size}_${k}_$run.json
    "$bin/nbtf" compress "$stack" -o "$work/out.nbtf" --clusters "$k" --crop "0,0,$size,$size" --seed 1 -q \
      --threads "$threads" --stats-json "$stats" "${opts[@]}" > /dev/null
    echo "$subset $size $k $run $(python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); f=s.get("rmse_floor_modulated") or s.get("rmse_floor") or 0; print(s["rmse_train"], s["steps"], s["epochs"], round(s["seconds"]["train"], 1), s["images"], f)' "$stats")" \
      | tee -a "$results"
  done
done

echo "== results"
python3 - "$results" <<'EOF'
import sys
rows = {}
for line in open(sys.argv[1]):
    subset, size, k, run, rmse, steps, epochs, seconds, images, floor = line.split()
    rows.setdefault((subset, int(size), int(k), int(images)), {})[run] = (float(rmse), int(steps), int(epochs), float(seconds), float(floor))
print("| stack | texels | k | floor | default RMSE | steps (epochs) | train s | 4x RMSE | steps | train s | default / 4x | default / floor |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
verdicts = []
for (subset, size, k, images), r in rows.items():
    d, l = r.get("default"), r.get("long")
    floor = (d or l)[4]
    cells = [f"{subset} ({images} images)", f"{size} x {size}", str(k), f"{floor:.5f}"]
    cells += [f"{d[0]:.5f}", f"{d[1]} ({d[2]})", f"{d[3]:.0f}"] if d else ["-"] * 3
    cells += [f"{l[0]:.5f}", str(l[1]), f"{l[3]:.0f}"] if l else ["-"] * 3
    cells += [f"{d[0] / l[0]:.3f}" if d and l else "-", f"{d[0] / floor:.3f}" if d and floor > 0 else "-"]
    print("| " + " | ".join(cells) + " |")
    if d:
        verdicts.append((f"{subset}_{size}_k{k}", d[0], l[0] if l else None, floor))
for name, dr, lr, floor in verdicts:
    if lr is not None:
        ratio = dr / lr
        print(f"bench defaults_{name}: default RMSE {100 * (ratio - 1):+.1f}% vs the 4x run (target <= +10%) "
              f"{'PASS' if ratio <= 1.10 else 'FAIL'}")
    elif floor > 0 and dr <= 1.10 * floor:
        print(f"bench defaults_{name}: default RMSE {100 * (dr / floor - 1):+.1f}% vs the floor: within 10% of any "
              "longer run PASS")
    else:
        print(f"bench defaults_{name}: no 4x run; default RMSE {100 * (dr / floor - 1):+.1f}% vs the floor (undecided)")
EOF
