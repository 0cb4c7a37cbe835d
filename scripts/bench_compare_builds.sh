#!/usr/bin/env bash
# Two builds side by side, in one run: the quick decode benchmark (bench_decode --quick) and
# the training throughput (nbtf-bench-train --throughput, the built-in default recipe, in-memory 100 x 100
# material, k = 500), alternating A, B, A, B... for ROUNDS rounds, so that a busy or drifting
# host affects both alike. For refactors that must not change speed.
#   scripts/bench_compare_builds.sh A_BIN_DIR B_BIN_DIR [ROUNDS=3] [TRAIN_SECONDS=20]
set -euo pipefail
source "$(dirname "$0")/lib.sh"
a=$1 b=$2 rounds=${3:-3} seconds=${4:-20}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for bin in "$a" "$b"; do
  [[ -x "$bin/bench_decode" && -x "$bin/nbtf-bench-train" ]] || { echo "no bench_decode / nbtf-bench-train in $bin" >&2; exit 1; }
done
echo "== $(nproc) cores; A = $a, B = $b; $rounds rounds; load average $(cut -d' ' -f1-3 /proc/loadavg)"
for r in $(seq 1 "$rounds"); do
  for side in A B; do
    bin=$a; [[ $side == B ]] && bin=$b
    "$bin/bench_decode" "$work/decode_$side" --quick | grep -E "^result (mem_clustered_s|mem_per_texel_s|query_clustered_qps|query_per_texel_qps)" |
      sed "s/^result /r$r $side decode_/"
    "$bin/nbtf-bench-train" --throughput --seconds "$seconds" |
      grep -E "^throughput_(samples_per_second|decoder_gflops)" | sed "s/^/r$r $side train_/"
  done
done | tee "$work/log"
python3 - "$work/log" <<'PY'
import sys, statistics, collections
v = collections.defaultdict(lambda: collections.defaultdict(list))
for line in open(sys.argv[1]):
    r, side, key, val = line.split()
    v[key][side].append(float(val))
print("\nmedian over rounds (B / A: > 1 means B is faster for rates, slower for seconds)")
for key in v:
    a, b = statistics.median(v[key]["A"]), statistics.median(v[key]["B"])
    print(f"{key:32s} A {a:12.5g}  B {b:12.5g}  B/A {b / a:6.3f}")
PY
