#!/usr/bin/env bash
# Benchmark of `nbtf export-gltf`: the glTF 2.0 fit of each synthetic preset (100 x 100, UBO2003
# layout, 8-bit JPEG, seed 1, with its float ground truth): fit and measuring seconds, the
# textures' bytes and ratio, RMSE (linear / alpha, all 6561 images) against the stack and the
# ground truth, and the worst light-elevation band. With --nbtf, beside each: the default
# `nbtf compress` of the same stack (10% held out), its file ratio and its RMSE against the
# ground truth on all images, from `nbtf eval`.
# With --optimizers, after the table: the fit's two optimizers on the first preset
# (bench/bench_gltf_fit.cpp): Levenberg-Marquardt per texel, what the export runs, against all
# texels at once with libtorch's Adam, on the base material's sample RMSE and seconds.
# Options: --presets "a b ..." (default: fabric wool corduroy satin glossy), --nbtf, --optimizers.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
presets="fabric wool corduroy satin glossy"
with_nbtf=
optimizers=
while [[ $# -gt 0 ]]; do
  case $1 in
    --presets) presets=$2; shift 2 ;;
    --nbtf) with_nbtf=1; shift ;;
    --optimizers) optimizers=1; shift ;;
    *) echo "bench_gltf.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
nbtf_build
work=$bench_data/gltf
mkdir -p "$work"
bench_banner "nbtf export-gltf, defaults (512 images fitted per texel)"
reports=()
rows=()
for preset in $presets; do
  read -r label data < <(preset_stack "$preset" "$bench_data")
  out=$work/$label.gltf
  rm -rf "$out"
  "$bin/nbtf" export-gltf "$data" -o "$out" -q > /dev/null
  nbtf_cells="| | |"
  if [[ -n $with_nbtf ]]; then
    compress_and_eval "$work" "$label" default "$data" > /dev/null
    nbtf_cells=$(python3 - "$work/$label-default/report.json" <<'PY'
import json, sys
def find(node, key):  # the first value of `key` anywhere in the report
    if isinstance(node, dict):
        if key in node and not isinstance(node[key], (dict, list)):
            return node[key]
        for v in node.values():
            got = find(v, key)
            if got is not None:
                return got
    return None
r = json.load(open(sys.argv[1]))
print("| 1:%s | %.5f |" % (format(round(find(r, "ratio")), ","), find(r, "rmse_ground_truth")))
PY
)
  fi
  rows+=("$(python3 - "$out/fit_report.json" "$label" "$nbtf_cells" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
e = r["rmse"]
worst = max(e["stack"]["by_light_elevation"], key=lambda b: b["rmse"])
print("| %s | %.1f | %.1f | %.1f | 1:%s | %.5f | %.5f | %d-%d: %.4f %s" % (
    sys.argv[2], r["fit"]["seconds"], r["measure_seconds"], r["texture_bytes"]["total"] / 1024,
    format(round(r["compression_ratio"]), ","), e["stack"]["rmse"], e.get("ground_truth", {}).get("rmse", float("nan")),
    worst["theta_from_deg"], worst["theta_to_deg"], worst["rmse"], sys.argv[3]))
PY
)")
done
echo
echo "| preset | fit s | measure s | textures KiB | ratio | RMSE vs stack | RMSE vs truth | worst light band (vs stack) | nbtf default ratio | nbtf default vs truth |"
echo "|---|---|---|---|---|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
if [[ -n $optimizers ]]; then
  read -r label data < <(preset_stack "${presets%% *}" "$bench_data")
  echo
  echo "== the fit's optimizers on $label (the base material: no sheen, no specular)"
  "$bin/bench_gltf_fit" "$data" | tee "$work/optimizers.txt"
  python3 - "$work/optimizers.txt" <<'PY'
import sys
r = dict(l.split()[1:3] for l in open(sys.argv[1]) if l.startswith("result "))
lm_s, lm_e, t_s, t_e = (float(r[k]) for k in ("lm_seconds", "lm_rmse", "torch_seconds", "torch_rmse"))
faster = "Levenberg-Marquardt" if lm_s <= t_s else "torch Adam"
lower = "Levenberg-Marquardt" if lm_e <= t_e else "torch Adam"
print("bench gltf_fit_optimizers: Levenberg-Marquardt %.1f s, sample RMSE %.5f; torch Adam %.1f s, %.5f "
      "(faster: %s, lower: %s)" % (lm_s, lm_e, t_s, t_e, faster, lower))
PY
fi
