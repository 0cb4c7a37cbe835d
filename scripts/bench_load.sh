#!/usr/bin/env bash
# Benchmark of the stack loader: load a 100 x 100 crop of a 256 x 256 UBO2003
# stack (6561 JPEGs), nbtf vs a plain sequential cv::imread loop, same files, same run.
# Targets: >= 1.6x faster than the loop on 2 cores; peak memory <= 1.3 x the 8-bit size of
# the cropped data + 150 MB.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
nbtf_build --with time
data=$bench_data/fabric256_ubo2003
crop=78,78,100,100
synth_once "$data" --preset fabric --size 256x256 --layout ubo2003 --seed 1 --no-ground-truth
sync
echo "== $(nproc) cores; crop $crop of $data"
measure() {  # prints "seconds peak_kib"
  /usr/bin/time -f "%e %M" -o /tmp/nbtf_bench_time "$@" >/dev/null
  cat /tmp/nbtf_bench_time
}
# Warm the page cache once so both sides read from memory, then alternate runs.
"$bin/bench_load_baseline" "$data" "$crop" >/dev/null
best_base=999999; best_nbtf=999999; mem_base=0; mem_nbtf=0
for run in 1 2 3; do
  read -r t m < <(measure "$bin/bench_load_baseline" "$data" "$crop")
  echo "run $run: sequential cv::imread loop  ${t} s  peak ${m} KiB"
  best_base=$(python3 -c "print(min($best_base, $t))"); mem_base=$m
  read -r t m < <(measure "$bin/nbtf" info "$data" --crop "$crop" -q)
  echo "run $run: nbtf info (loader)          ${t} s  peak ${m} KiB"
  best_nbtf=$(python3 -c "print(min($best_nbtf, $t))"); mem_nbtf=$m
done
python3 - "$best_base" "$best_nbtf" "$mem_nbtf" <<'PY'
import sys
base, nbtf, mem_kib = float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
speedup = base / nbtf
data_mb = 6561 * 100 * 100 * 3 / 1e6
limit_mb = 1.3 * data_mb + 150
mem_mb = mem_kib * 1024 / 1e6
print(f"best of 3: baseline {base:.2f} s, nbtf {nbtf:.2f} s; cropped 8-bit data {data_mb:.1f} MB")
print(f"bench load_speedup: {speedup:.2f}x vs sequential cv::imread (target >= 1.6x) {'PASS' if speedup >= 1.6 else 'FAIL'}")
print(f"bench load_peak_memory: {mem_mb:.0f} MB (target <= {limit_mb:.0f} MB) {'PASS' if mem_mb <= limit_mb else 'FAIL'}")
PY
