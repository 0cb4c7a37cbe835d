#!/usr/bin/env bash
# Data-parallel training on this machine, in one run: the same compress run
# (100 x 100 fabric, 6561 images, k = 500, --epochs E) as one process on all cores and as two
# processes (one core each) on the loopback interface. Prints training seconds, the gradient
# all-reduce per step (bytes and seconds, from each run's summary) and what N machines would
# give from the measured step time and message size (ring all-reduce: each rank sends and
# receives 2 (N - 1) / N of the message per step).
#   scripts/bench_distributed.sh [--epochs E]   (default 2)
set -euo pipefail
source "$(dirname "$0")/lib.sh"
epochs=2
[[ ${1:-} == --epochs ]] && epochs=$2
nbtf_build
data=$bench_data/fabric100_ubo2003
synth_once "$data" --preset fabric --size 100x100 --layout ubo2003 --seed 1 --no-ground-truth -q
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cores=$(nproc)
common=("$data" --clusters 500 --epochs "$epochs" --seed 1 -q)
echo "== $cores cores; load average $(cut -d' ' -f1-3 /proc/loadavg); ${common[*]}"
echo "== 1 process, 1 thread (the same arithmetic as each rank: the RMSE reference)"
"$bin/nbtf" compress "${common[@]}" --threads 1 -o "$work/one1.nbtf" --stats-json "$work/one1.json" > /dev/null
echo "== 1 process, $cores threads"
"$bin/nbtf" compress "${common[@]}" --threads "$cores" -o "$work/one.nbtf" --stats-json "$work/one.json" > /dev/null
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
# Every rank presents the run's shared secret at the rendezvous (docs/model.md).
NBTF_DIST_SECRET=$(od -An -N16 -tx1 /dev/urandom | tr -d ' \n')
export NBTF_DIST_SECRET
echo "== 2 processes, 1 thread each, loopback (master 127.0.0.1:$port)"
"$bin/nbtf" compress "${common[@]}" --threads 1 -o "$work/rank1.nbtf" --world-size 2 --rank 1 \
  --master "127.0.0.1:$port" > "$work/rank1.log" 2>&1 &
rank1=$!
"$bin/nbtf" compress "${common[@]}" --threads 1 -o "$work/two.nbtf" --stats-json "$work/two.json" --world-size 2 \
  --rank 0 --master "127.0.0.1:$port" > /dev/null
wait "$rank1"
python3 - "$work/one.json" "$work/two.json" "$work/one1.json" <<'PY'
import json, sys
one, two, one1 = (json.load(open(p)) for p in sys.argv[1:4])
steps = one["steps"]
t1, t2 = one["seconds"]["train"], two["seconds"]["train"]
msg, comm = two["all_reduce_bytes_per_step"], two["all_reduce_seconds_per_step"]
print(f"steps                         {steps} (both)")
print(f"RMSE (linear / alpha)         1 process x 1 thread {one1['rmse_train']:.6f}, 2 processes x 1 thread "
      f"{two['rmse_train']:.6f} (1 process x all threads {one['rmse_train']:.6f}: another thread count, other sums)")
print(f"training seconds              1 process x all threads {t1:.1f}, 2 processes x 1 thread {t2:.1f} "
      f"(ratio {t2 / t1:.2f}), 1 process x 1 thread {one1['seconds']['train']:.1f}")
print(f"all-reduce per step           {msg / 1024:.1f} KiB, {1e3 * comm:.2f} ms on rank 0 (includes waiting for the peer)")
step = t1 / steps
print(f"step time, 1 process          {1e3 * step:.1f} ms")
for gbit in (1, 10):
    for n in (2, 4, 8):
        wire = 2 * (n - 1) / n * msg * 8 / (gbit * 1e9)
        est = step / n + wire
        print(f"estimate {n} machines, {gbit:2d} Gbit/s: step {1e3 * est:6.1f} ms (compute {1e3 * step / n:.1f} + "
              f"network {1e3 * wire:.2f}), speed-up {step / est:.2f}x")
PY
