#!/usr/bin/env bash
# bench_cluster: nbtf's clustering stage against scikit-learn, in one run, on the same data.
#
# Data: the standardized log ABRDFs (10,000 texels x 19,683 dimensions) of a synthetic
# 100 x 100 fabric: nbtf-synth's when it is built, otherwise the procedural weave built
# into nbtf-bench-cluster. Both tools read the same matrix file.
# Stages: PCA to 32 components (sklearn: PCA(svd_solver='randomized')), then k-means++
# for k = 500, 1000, 2000 (sklearn: KMeans(init='k-means++', n_init=1)).
# Targets: nbtf >= 3x faster than scikit-learn for PCA + k-means at every k, with inertia
# no more than 1% worse (k-means inertia, and the inertia of the labels in the full
# 19,683-dimensional space, scored by the same numpy code for both).
#
# Usage: scripts/bench_cluster.sh [WORK_DIR]   (default build/bench_cluster)
set -euo pipefail
source "$(dirname "$0")/lib.sh"
work=${1:-$root/build/bench_cluster}
ks=(500 1000 2000)
repeat=${BENCH_REPEAT:-3}  # runs per stage and tool, the fastest kept (the machine is shared)

nbtf_build --with python3-sklearn
mkdir -p "$work"
# scikit-learn is Debian's, which lives in the system python (not a pyenv one on PATH).
python=/usr/bin/python3

echo "== data"
if [[ -x "$bin/nbtf-synth" ]]; then
  source_text="synthetic fabric (nbtf-synth --preset fabric --size 100x100 --seed 1), log + standardized"
else
  source_text="procedural weave (nbtf-bench-cluster matrix --synthetic 100x100), log + standardized"
fi
if [[ ! -f "$work/data.f32" || "$(cat "$work/data.txt" 2>/dev/null)" != "$source_text" ]]; then
  rm -f "$work/data.f32"
  if [[ -x "$bin/nbtf-synth" ]]; then
    "$bin/nbtf-synth" --preset fabric --size 100x100 --layout ubo2003 --seed 1 --no-ground-truth -q -o "$work/fabric"
    "$bin/nbtf-bench-cluster" matrix --stack "$work/fabric" -o "$work/data.f32"
  else
    "$bin/nbtf-bench-cluster" matrix --synthetic 100x100 -o "$work/data.f32"
  fi
  echo "$source_text" > "$work/data.txt"
fi
echo "data: $(cat "$work/data.txt")"

echo "== nbtf"
"$bin/nbtf-bench-cluster" run --matrix "$work/data.f32" --clusters "$(IFS=,; echo "${ks[*]}")" --repeat "$repeat" --out "$work"
echo "== scikit-learn"
"$python" "$root/scripts/bench_cluster_sklearn.py" "$work/data.f32" "$work" "$repeat" "${ks[@]}"

echo "== results"
"$python" - "$work" <<'EOF'
import json, os, sys
work = sys.argv[1]
nb = json.load(open(os.path.join(work, "nbtf.json")))
sk = json.load(open(os.path.join(work, "sklearn.json")))
print(f"data: {nb['texels']} texels x {nb['dimensions']} dimensions, {nb['threads']} threads, scikit-learn {sk['sklearn_version']}, "
      f"fastest of {nb['repeat']} runs per stage; load average at the end {os.getloadavg()[0]:.1f}")
print(f"nbtf PCA: {nb['pca']['power_iterations']} power iterations, oversampling {nb['pca']['oversampling']}; "
      "scikit-learn PCA: n_iter='auto' (7 here), oversampling 10")
print(f"PCA, 32 components: nbtf {nb['pca']['seconds']:.2f} s (explained {nb['pca']['explained_variance_ratio']:.5f}), "
      f"scikit-learn {sk['pca']['seconds']:.2f} s (explained {sk['pca']['explained_variance_ratio']:.5f})")
print(f"{'k':>5} | {'nbtf k-means':>12} {'sklearn k-means':>15} | {'nbtf total':>10} {'sklearn total':>13} {'speed-up':>8} | "
      f"{'inertia nbtf':>13} {'sklearn':>13} {'diff':>7} | {'full-space nbtf':>15} {'sklearn':>13} {'diff':>7}")
lines = []
for n, s in zip(nb["kmeans"], sk["kmeans"]):
    k = n["k"]
    nbtf_total = nb["pca"]["seconds"] + n["seconds"]
    sk_total = sk["pca"]["seconds"] + s["seconds"]
    speedup = sk_total / nbtf_total
    inertia_diff = n["inertia"] / s["inertia"] - 1
    full_diff = s["nbtf_full_space_inertia"] / s["full_space_inertia"] - 1
    print(f"{k:>5} | {n['seconds']:>10.2f} s {s['seconds']:>13.2f} s | {nbtf_total:>8.2f} s {sk_total:>11.2f} s {speedup:>7.1f}x | "
          f"{n['inertia']:>13.6g} {s['inertia']:>13.6g} {100 * inertia_diff:>+6.2f}% | "
          f"{s['nbtf_full_space_inertia']:>15.6g} {s['full_space_inertia']:>13.6g} {100 * full_diff:>+6.2f}%")
    lines.append(f"bench cluster k={k} speed: PCA + k-means {speedup:.1f}x faster than scikit-learn "
                 f"({nbtf_total:.2f} s vs {sk_total:.2f} s) (target >= 3x) {'PASS' if speedup >= 3 else 'FAIL'}")
    worst = max(inertia_diff, full_diff)
    lines.append(f"bench cluster k={k} inertia: {100 * inertia_diff:+.2f}% (k-means), {100 * full_diff:+.2f}% (full space) "
                 f"vs scikit-learn (target <= +1%) {'PASS' if worst <= 0.01 else 'FAIL'}")
print("\n".join(lines))
EOF
