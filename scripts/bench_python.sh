#!/usr/bin/env bash
# Batched queries through the Python module (Material.query: texel + angles, numpy in and
# out) against the C++ batch path it calls (NbtfDecoder::evaluate, bench/bench_query_batch),
# on the same file, batch sizes 1 to 100,000: seconds per call on each side, the Python
# overhead per call (at batch size 1) and per element (the slope between the two largest
# batches), as a table. Run it alone on the machine.
#   scripts/bench_python.sh [FILE.nbtf] [SECONDS per batch size and side, default 2]
# Default file: a 100 x 100 synthetic fabric compressed with the defaults (k = 500, 60 s of
# training), cached in $NBTF_BENCH_DATA/python.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
nbtf_build
cmake --build "$root/build" --target bench_query_batch _nbtf -- --no-print-directory >/dev/null
python=$(sed -n 's/^NBTF_PYTHON_EXECUTABLE:INTERNAL=//p' "$root/build/CMakeCache.txt")
[[ -n "$python" ]] || { echo "bench_python: the build has no Python module (pybind11-dev, python3-dev)" >&2; exit 1; }
file=${1:-}
seconds=${2:-2}
if [[ -z "$file" ]]; then
  data=$bench_data/fabric100_ubo2003
  synth_once "$data" --preset fabric --size 100x100 --layout ubo2003 --seed 1 --no-ground-truth -q
  file=$bench_data/python/fabric100_k500.nbtf
  if [[ ! -f "$file" ]]; then
    mkdir -p "$(dirname "$file")"
    echo "== compressing $data (k = 500, 60 s training budget)" >&2
    "$bin/nbtf" compress "$data" -o "$file" --clusters 500 --time-budget 60 --seed 1 -q >/dev/null
  fi
fi
sizes=(1 10 100 1000 10000 100000)
bench_banner "$(basename "$file"), $(nproc) threads, $seconds s per batch size and side"
cpp=$("$root/build/bin/bench_query_batch" "$file" "$seconds" "${sizes[@]}")
PYTHONPATH=$root/build/python "$python" - "$file" "$seconds" "$cpp" "${sizes[@]}" <<'PY'
import sys, time
import numpy as np
import nbtf

path, seconds, cpp = sys.argv[1], float(sys.argv[2]), sys.argv[3]
sizes = [int(s) for s in sys.argv[4:]]
cpp_s = {int(n): float(s) for _, n, s in (line.split() for line in cpp.splitlines() if line.startswith("result "))}
rng = np.random.default_rng(1)
py_s = {}
with nbtf.open(path) as m:
    for n in sizes:
        xy = np.stack([rng.integers(0, m.width, n), rng.integers(0, m.height, n)], axis=1)
        light = np.stack([rng.uniform(0, 90, n), rng.uniform(0, 360, n)], axis=1)
        view = np.stack([rng.uniform(0, 90, n), rng.uniform(0, 360, n)], axis=1)
        rounds = []
        for _ in range(5):
            calls, start = 0, time.perf_counter()
            while True:
                m.query(texel=xy, light=light, view=view)
                calls += 1
                elapsed = time.perf_counter() - start
                if elapsed >= seconds / 5:
                    break
            rounds.append(elapsed / calls)
        py_s[n] = sorted(rounds)[2]

print(f"{'batch':>8} {'C++ s/call':>12} {'Python s/call':>14} {'C++ ns/query':>13} {'Python ns/query':>16} {'Python/C++':>11}")
for n in sizes:
    c, p = cpp_s[n], py_s[n]
    print(f"{n:>8} {c:>12.3g} {p:>14.3g} {1e9 * c / n:>13.4g} {1e9 * p / n:>16.4g} {p / c:>11.2f}")
a, b = sizes[-2], sizes[-1]
per_call = py_s[sizes[0]] - cpp_s[sizes[0]]
per_element = ((py_s[b] - py_s[a]) - (cpp_s[b] - cpp_s[a])) / (b - a)
print(f"Python overhead per call (batch {sizes[0]}): {1e6 * per_call:.2f} us; "
      f"per element (slope {a} -> {b}): {1e9 * per_element:.2f} ns "
      f"(the C++ path: {1e9 * (cpp_s[b] - cpp_s[a]) / (b - a):.1f} ns per query)")
PY
