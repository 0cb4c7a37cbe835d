#!/usr/bin/env bash
# bench_adaptive: adaptive clusters against fixed k at matched file sizes.
# For each synthetic preset (100 x 100 texels, UTIA layout) it compresses with fixed
# k = 250, 500, 1000, 2000 (default options), then with --adaptive --clusters k
# --size-budget <that fixed-k file's size>: the same schedule of optimizer steps (the plan
# of fixed k, so the same training time up to the per-stage overhead), at most the same bytes.
# Every file is evaluated (`nbtf eval`, reports with the cluster map) and the curves are
# plotted by `nbtf eval --summarize` (rd_*.png).
# Target: at equal file size at least 10% lower RMSE than fixed k, or the same
# RMSE at 25% fewer bytes (log-log interpolation on the adaptive curve).
#
# Usage: scripts/bench_adaptive.sh [WORK_DIR]   (default build/bench_adaptive)
#   NBTF_BENCH_PRESETS="fabric glossy"   presets
#   NBTF_BENCH_K="250 500 1000 2000"     fixed k (each also the adaptive run's --clusters)
#   NBTF_BENCH_SUBSET=full|sub9x9        all 81 x 81 images, or 9 views x 9 lights (81 images;
#                                        a reduced run for small machines)
#   NBTF_BENCH_ARGS="..."                extra compress options for every run (e.g. --threads 2)
#   NBTF_BENCH_STACKS="fabric=DIR ..."    use these 100 x 100 stacks (any layout) instead of generating
set -euo pipefail
source "$(dirname "$0")/lib.sh"
work=${1:-$root/build/bench_adaptive}
presets=${NBTF_BENCH_PRESETS:-"fabric glossy"}
ks=${NBTF_BENCH_K:-"250 500 1000 2000"}
subset=${NBTF_BENCH_SUBSET:-full}
read -r -a extra <<< "${NBTF_BENCH_ARGS:-}"
# NBTF_BIN_DIR: binaries to measure (default: build them into build/).
nbtf_build
mkdir -p "$work"

# 9 view folders x 9 lights in each (every 9th, in name order), as scripts/bench_defaults.sh;
# copies, so the subset does not depend on the full stack staying where it is.
make_subset() {
  local full=$1 out=$2
  [[ -d $out ]] && return
  mkdir -p "$out.tmp"
  mapfile -t views < <(find -H "$full" -mindepth 1 -maxdepth 1 -type d -printf '%f\n' | sort)
  for ((v = 0; v < ${#views[@]}; v += 9)); do
    mkdir -p "$out.tmp/${views[v]}"
    mapfile -t files < <(find -H "$full/${views[v]}" -maxdepth 1 -type f -printf '%f\n' | sort)
    for ((l = 0; l < ${#files[@]}; l += 9)); do cp "$full/${views[v]}/${files[l]}" "$out.tmp/${views[v]}/"; done
  done
  mv "$out.tmp" "$out"
}
declare -A given=()
for pair in ${NBTF_BENCH_STACKS:-}; do given[${pair%%=*}]=${pair#*=}; done

results=$work/results.txt
: > "$results"
reports=()
echo "== $(nproc) cores, $(date -u '+%Y-%m-%d %H:%M UTC'), presets: $presets, k: $ks, images: $subset"
for preset in $presets; do
  full=${given[$preset]:-$work/${preset}_utia}
  synth_once "$full" --preset "$preset" --size 100x100 --layout utia --format png --seed 1 --no-ground-truth -q
  data=$full
  if [[ $subset == sub9x9 ]]; then
    data=$work/${preset}_sub9x9
    make_subset "$full" "$data"
  fi
  for k in $ks; do
    for run in fixed adaptive; do
      name=$preset-$run-$k
      opts=(--clusters "$k")
      if [[ $run == adaptive ]]; then
        budget=$(file_bytes "$work/$preset-fixed-$k.json")
        opts+=(--adaptive --size-budget "$budget")
      fi
      "$bin/nbtf" compress "$data" -o "$work/$name.nbtf" "${opts[@]}" --seed 1 -q --stats-json "$work/$name.json" \
        "${extra[@]}" > "$work/$name.log"
      "$bin/nbtf" eval "$work/$name.nbtf" --reference "$data" -o "$work/$name" -q > /dev/null
      reports+=("$work/$name/report.json")
      python3 - "$work/$name.json" "$preset" "$run" "$k" <<'PY' | tee -a "$results"
import json, sys
s = json.load(open(sys.argv[1]))
print(sys.argv[2], sys.argv[3], sys.argv[4], s["clusters"], s["bytes"]["file"], s["rmse_train"], s["steps"],
      round(s["seconds"]["train"] + s["seconds"]["cluster"], 1))
PY
    done
  done
done

"$bin/nbtf" eval --summarize -o "$work/summary" "${reports[@]}" > /dev/null

echo "== results"
python3 - "$results" <<'PY'
import math, sys
rows = [l.split() for l in open(sys.argv[1]) if l.strip()]
by = {}
for preset, run, k, kk, size, rmse, steps, secs in rows:
    by.setdefault(preset, {}).setdefault(run, []).append((int(k), int(kk), int(size), float(rmse), int(steps), float(secs)))
def bytes_at(curve, rmse):
    """Bytes the adaptive curve needs for `rmse` (log-log interpolation; None outside it)."""
    pts = sorted((r, b) for _, _, b, r, _, _ in curve)
    for (r0, b0), (r1, b1) in zip(pts, pts[1:]):
        if r0 <= rmse <= r1 and r0 != r1:
            t = (math.log(rmse) - math.log(r0)) / (math.log(r1) - math.log(r0))
            return math.exp(math.log(b0) + t * (math.log(b1) - math.log(b0)))
    return None
print("| preset | fixed k | bytes | RMSE | steps | s | adaptive k | bytes | RMSE | steps | s | RMSE change | bytes for the fixed RMSE |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
passes = total = 0
for preset, runs in by.items():
    ad = {k: v for k, *v in runs.get("adaptive", [])}
    for k, kk, size, rmse, steps, secs in runs.get("fixed", []):
        if k not in ad: continue
        akk, asize, armse, asteps, asecs = ad[k]
        change = armse / rmse - 1
        b = bytes_at(runs["adaptive"], rmse)
        saving = f"{b / size - 1:+.0%}" if b else "n/a"
        ok = change <= -0.10 or (b is not None and b <= 0.75 * size)
        passes += ok; total += 1
        print(f"| {preset} | {kk} | {size} | {rmse:.5f} | {steps} | {secs} | {akk} | {asize} | {armse:.5f} | {asteps} | {asecs} | {change:+.1%} | {saving} |")
print(f"\ntarget (>= 10% lower RMSE at <= the bytes, or the same RMSE at >= 25% fewer bytes): {passes} of {total} points pass")
PY
echo "bench_adaptive: results $work/results.txt, reports $work/<preset>-<run>-<k>/report.html, plots $work/summary/"
