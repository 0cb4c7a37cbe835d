#!/usr/bin/env bash
# Benchmark of decoding: a 100 x 100-texel material (81 x 81 images) compressed
# with the defaults (decoder 28-106-106-106-3: latent 8 + stereographic and Fourier direction
# inputs) with k = 500 and the same material per-texel, measured in one run: seconds to
# reconstruct all 6561 images (in memory as an 8-bit sRGB stack, and written as PNG files),
# batched query throughput, the machine's float matmul rate (Eigen and libtorch mm, 2048^2,
# all threads), and what the default's direction inputs cost against the paper's 4
# (random-weight clustered files of both input kinds, side by side).
# Targets: clustered reconstruction >= 10x faster than per-texel (in memory); batched
# query throughput >= 50% of the matmul rate in decoder FLOP terms (queries/s x FLOPs of
# one full decoder evaluation, against the faster of Eigen and libtorch mm).
# The .nbtf files come from `nbtf compress` on a synthetic fabric (cached in the work folder);
# --quick: a smoke run (8 lights x 81 views, 200k queries) on random-weight files of the same shapes.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
nbtf_build
work=$bench_data/decode
echo "== $(nproc) cores; work folder $work"
log=$(mktemp)
trap 'rm -f "$log"' EXIT
# The paper's setup, really compressed: a 100 x 100 synthetic fabric with k = 500 and the same
# material per-texel (cached; decode speed depends on the shapes, not on how long it trained).
data=$bench_data/fabric100_ubo2003
files=()
if [[ " $* " != *" --quick "* ]]; then
  synth_once "$data" --preset fabric --size 100x100 --layout ubo2003 --seed 1 --no-ground-truth -q
  mkdir -p "$work"
  for mode in "clustered_k500|--clusters 500" "per_texel|--clusters 0"; do
    name=${mode%%|*}
    if [[ ! -f "$work/real_$name.nbtf" ]]; then
      echo "== compressing $data ($name, 120 s training budget)"
      # shellcheck disable=SC2086
      "$root/build/bin/nbtf" compress "$data" -o "$work/real_$name.nbtf" ${mode#*|} --time-budget 120 -q
    fi
  done
  files=(--files "$work/real_clustered_k500.nbtf" "$work/real_per_texel.nbtf")
fi
"$root/build/bin/bench_decode" "$work" "$@" "${files[@]}" | tee "$log"
python3 - "$log" <<'PY'
import sys
r = {}
for line in open(sys.argv[1]):
    if line.startswith("result "):
        _, key, value = line.split(maxsplit=2)
        r[key] = value.strip()
f = {k: float(v) for k, v in r.items() if k != "isa"}
images = int(f["images"])
speedup = f["mem_per_texel_s"] / f["mem_clustered_s"]
png_speedup = f["png_per_texel_s"] / f["png_clustered_s"]
matmul = max(f["eigen_gflops"], f["torch_gflops"])
which = "libtorch mm" if f["torch_gflops"] >= f["eigen_gflops"] else "Eigen"
qps = min(f["query_clustered_qps"], f["query_per_texel_qps"])
gflops = qps * f["flops_per_eval"] / 1e9
share = gflops / matmul
print(f"all {images} images in memory: clustered {f['mem_clustered_s']:.2f} s, per-texel {f['mem_per_texel_s']:.2f} s")
print(f"all {images} images as PNG:    clustered {f['png_clustered_s']:.2f} s, per-texel {f['png_per_texel_s']:.2f} s "
      f"({png_speedup:.1f}x; file writes with fsync included)")
print(f"batched queries: clustered {f['query_clustered_qps']:.3g}/s, per-texel {f['query_per_texel_qps']:.3g}/s "
      f"({r['isa']} kernels); matmul rate {matmul:.1f} GFLOP/s ({which}, 2048^2 float, all threads)")
mem_cost = f["inputs_mem_fourier_s"] / f["inputs_mem_stereographic_s"]
query_cost = f["inputs_query_stereographic_qps"] / f["inputs_query_fourier_qps"]
uv_cost = f["inputs_uv_stereographic_qps"] / f["inputs_uv_fourier_qps"]
print(f"direction inputs (clustered k = 500, random weights, same shapes otherwise): stereographic+fourier2 "
      f"against stereographic: all images in memory {mem_cost:.2f}x the time; queries (texel + angles) "
      f"{query_cost:.2f}x the time ({f['inputs_query_fourier_qps']:.3g}/s against "
      f"{f['inputs_query_stereographic_qps']:.3g}/s); queries (uv + unit vectors) {uv_cost:.2f}x")
print(f"bench decode_clustered_speedup: {speedup:.1f}x faster than per-texel, all {images} images in memory "
      f"(target >= 10x) {'PASS' if speedup >= 10 else 'FAIL'}")
print(f"bench decode_query_throughput: {qps:.3g} queries/s = {gflops:.1f} GFLOP/s = {100 * share:.0f}% of the "
      f"{which} matmul rate (target >= 50%) {'PASS' if share >= 0.5 else 'FAIL'}")
PY
