#!/usr/bin/env bash
# Benchmark of `nbtf render`: adaptive oversampling by automatic
# differentiation against uniform supersampling. On the sphere and cloth scenes with a
# compressed 100 x 100 material (synthetic fabric, k = 500, a 60 s training budget; cached),
# every method is compared with a 16 x 16-supersampled reference of the same scene: RMSE
# (linear radiance), rays traced (derivative and plain), ray-equivalents (a derivative ray
# counted at its measured cost relative to a plain one, `--ray-cost`), seconds, and the
# fraction of pixels refined, side by side in one run.
# Target: the adaptive method reaches the RMSE of uniform 9 x 9 (within 10%) with at least
# 10x fewer ray-equivalents, on both scenes.
# adaptive2_centre is the ablation without the footprint filter (unsplit pixels keep their
# centre's value, as in the seed), at a threshold of 0.01.
# Options: --size WxH (default 320x240, the render default), --threads T (default all cores).
set -euo pipefail
source "$(dirname "$0")/lib.sh"
size=320x240
threads=0
while [[ $# -gt 0 ]]; do
  case $1 in
    --size) size=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    *) echo "bench_render.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
# NBTF_BIN_DIR: binaries to measure (default: build them into build/).
nbtf_build
nbtf=$bin/nbtf
work=$bench_data/render
mkdir -p "$work"
echo "== $(nproc) cores; $(date -u +%Y-%m-%d); work folder $work; image $size"
material=$bench_data/fabric100_ubo2003
synth_once "$material" --preset fabric --size 100x100 --layout ubo2003 --seed 1 --no-ground-truth -q
nbtf_file=$work/fabric100_k500_60s.nbtf
if [[ ! -f "$nbtf_file" ]]; then
  echo "== compressing $material (k = 500, 60 s training budget)"
  "$nbtf" compress "$material" -o "$nbtf_file" --clusters 500 --time-budget 60 -q
fi
common=(--size "$size" --threads "$threads" -q)
results=$work/results.tsv
: >"$results"
for scene in sphere cloth; do
  ref=$work/${scene}_ref16.exr
  echo "== $scene: reference, uniform 16 x 16"
  "$nbtf" render "$nbtf_file" --scene "$scene" -o "$work/${scene}_ref16.png" --exr "$ref" --uniform 16 \
    --stats-json "$work/${scene}_ref16.json" "${common[@]}"
  for method in "uniform1|--uniform 1" "uniform3|--uniform 3" "uniform9|--uniform 9" \
                "adaptive1|--adaptive --levels 1" "adaptive2|--adaptive --levels 2" \
                "adaptive2_centre|--adaptive --levels 2 --no-footprint-filter --threshold 0.01"; do
    name=${method%%|*}
    echo "== $scene: $name"
    # shellcheck disable=SC2086
    "$nbtf" render "$nbtf_file" --scene "$scene" -o "$work/${scene}_$name.png" ${method#*|} --reference "$ref" \
      --ray-cost --stats-json "$work/${scene}_$name.json" --show-refined "$work/${scene}_${name}_refined.png" "${common[@]}"
    printf '%s\t%s\t%s\n' "$scene" "$name" "$work/${scene}_$name.json" >>"$results"
  done
done
python3 - "$results" <<'PY'
import json, sys
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1]) if l.strip()]
data = {}
for scene, name, path in rows:
    data.setdefault(scene, {})[name] = json.load(open(path))
print()
print("| scene | method | RMSE vs 16x16 | derivative rays | plain rays | derivative/plain cost | ray-equivalents / pixel | seconds | pixels refined |")
print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
for scene, methods in data.items():
    for name, j in methods.items():
        px = j["pixels"]
        refined = f'{100 * j["refined_fraction"]:.1f}% ({100 * j["refined_twice"] / px:.1f}% twice)' if name.startswith("adaptive") else "-"
        label = j["sampling"] + (", centre values, threshold 0.01" if name == "adaptive2_centre" else "")
        print(f'| {scene} | {label} | {j["rmse_vs_reference"]:.5f} | {j["derivative_rays"] / px:.2f}/px | '
              f'{j["plain_rays"] / px:.2f}/px | {j["ray_cost"]["derivative_over_plain"]:.2f} | '
              f'{j["ray_equivalents_per_pixel"]:.2f} | {j["seconds"]:.2f} | {refined} |')
print()
ok = True
for scene, m in data.items():
    u9, a2 = m["uniform9"], m["adaptive2"]
    rmse_ratio = a2["rmse_vs_reference"] / u9["rmse_vs_reference"]
    saving = u9["ray_equivalents_per_pixel"] / a2["ray_equivalents_per_pixel"]
    passed = rmse_ratio <= 1.1 and saving >= 10
    ok &= passed
    print(f"bench render_{scene}: adaptive (2 levels) {saving:.1f}x fewer ray-equivalents than uniform 9x9 at "
          f"{rmse_ratio:.2f}x its RMSE (target >= 10x at <= 1.10x) {'PASS' if passed else 'FAIL'}")
PY
