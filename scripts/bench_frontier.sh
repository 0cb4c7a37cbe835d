#!/usr/bin/env bash
# The rate-distortion frontier: on each synthetic preset (100 x 100 texels, UBO2003
# layout, 6561 images, 10% held out), every neural row gets the same wall-clock training budget
# (--time-budget S) and is compared side by side with the PCA curve (C = 1 .. 64):
#   per_texel      the per-texel neural BTF (one latent per texel), the default recipe;
#   baseline_k500  the default recipe of format 1.7 (no direction planes): the reference of target 1;
#   nbtf_k<K>      the recipe under test (--config, default configs/default.json) at each K of --clusters;
#   nbtf_k<K>_compact  configs/compact.json (width-64 decoder, one modulation coefficient per
#                  texel) at each K of --compact-clusters: the small end of the curve;
#   nbtf_k<K>_balanced configs/balanced.json (small cluster planes, 4 x 4 x 2 in 8 bits, three
#                  modulation terms) at each K of --balanced-clusters: the middle of the curve;
#   nbtf_k<K>_hifi configs/high_fidelity.json (cluster planes, three modulation terms) at each K
#                  of --fidelity-clusters: the large end of the curve (target 2).
# Every file is evaluated with `nbtf eval` against its stack (RMSE in linear RGB / alpha, eq. 10);
# the table (bytes, ratio, RMSE, held-out RMSE, blur sigma, training seconds) goes to frontier.md,
# the rate-distortion plots (RMSE against ratio, one curve per method) to summary/rd_<preset>.png.
# Targets, each a PASS/FAIL line per preset:
#   (1) nbtf_k<default K> (configs/default.json's clustering.clusters, 1000) at >= 1:10,000 has training
#       and held-out RMSE at least 15% below baseline_k500;
#   (2) a high-fidelity point: some nbtf row at >= 1:1,000 with RMSE <= 0.65 x baseline_k500's and
#       blur sigma <= half of baseline_k500's;
#   (3) monotone and dominant: at every ratio r from 1:500 to 1:20,000, the best nbtf row of ratio
#       >= r (that size or smaller) has a lower RMSE than every PCA or per-texel row of ratio
#       1:500 .. r (that size or larger, within the window).
# The full run (five presets, S = 400 s, K = 125 1000 2000, compact K = 250, balanced K = 500,
# high-fidelity K = 500) trains 5 x 8 rows of 400 s: about 4.5 hours on 2 cores. Run it alone on the machine.
#
# usage: scripts/bench_frontier.sh [--presets "fabric wool"] [--budget S] [--clusters "125 1000 2000"]
#                                  [--compact-clusters "250"] [--balanced-clusters "500"]
#                                  [--fidelity-clusters "500"] [--config FILE]
#                                  [--pca "1 2 4"] [-o DIR]
set -euo pipefail
source "$(dirname "$0")/lib.sh"
presets="fabric wool corduroy satin glossy"
budget=400
clusters="125 1000 2000"
compact_clusters="250"
balanced_clusters="500"
fidelity_clusters="500"
config=$root/configs/default.json
pcas="1 2 4 8 16 32 64"
out=$bench_data/frontier
while [[ $# -gt 0 ]]; do
  case "$1" in
    --presets) presets=$2; shift;;
    --budget) budget=$2; shift;;
    --clusters) clusters=$2; shift;;
    --compact-clusters) compact_clusters=$2; shift;;
    --balanced-clusters) balanced_clusters=$2; shift;;
    --fidelity-clusters) fidelity_clusters=$2; shift;;
    --config) config=$2; shift;;
    --pca) pcas=$2; shift;;
    -o) out=$2; shift;;
    *) echo "bench_frontier: unknown option '$1' (see the header of $0)" >&2; exit 2;;
  esac
  shift
done
# NBTF_BIN_DIR: binaries to measure (default: build them into build/).
nbtf_build
nbtf=$bin/nbtf
mkdir -p "$out"
bench_banner
echo "== training budget $budget s per neural row; clusters $clusters; config $config; work folder $out"

# The baseline: the default recipe with the direction planes off, linear codes, the short
# polish phase with fixed latents and clusters found in the log space (format 1.7's default).
baseline=$out/baseline.json
python3 - "$root/configs/default.json" "$baseline" <<'PY'
import json, sys
cfg = json.load(open(sys.argv[1]))
cfg["direction_planes"] = {"features": 0}
cfg["optimizer"].pop("plane_learning_rate", None)
cfg["optimizer"]["latent_learning_rate"] = 0
cfg["training"]["polish_fraction"] = 0.1
cfg["modulation"]["codes"] = "linear"
cfg["clustering"] = {"space": "log", "clusters": 500}
cfg["training"]["max_steps"] = 24000
json.dump(cfg, open(sys.argv[2], "w"), indent=2)
PY

reports=()
for preset in $presets; do
  data=$out/${preset}100
  synth_once "$data" --preset "$preset" --size 100x100 --layout ubo2003 --seed 1 --no-ground-truth -q
  runs=("per_texel|--clusters 0 --time-budget $budget"
        "baseline_k500|--clusters 500 --config $baseline --time-budget $budget")
  for k in $clusters; do runs+=("nbtf_k$k|--clusters $k --config $config --time-budget $budget"); done
  # The shipped points of the curve: label suffix, config, the K to run it at.
  for point in "compact|compact.json|$compact_clusters" "balanced|balanced.json|$balanced_clusters" \
               "hifi|high_fidelity.json|$fidelity_clusters"; do
    IFS='|' read -r suffix file ks <<<"$point"
    for k in $ks; do runs+=("nbtf_k${k}_$suffix|--clusters $k --config $root/configs/$file --time-budget $budget"); done
  done
  for c in $pcas; do runs+=("pca_$c|--method pca --components $c"); done
  run_rows "$out" "$preset" "$data" "${runs[@]}"
done

# ---- Rate-distortion plots and sweep tables from the same reports.
"$nbtf" eval --summarize -o "$out/summary" "${reports[@]}" > /dev/null

# ---- The table and the targets.
python3 - "$root/scripts" "$out" "$budget" "$root/configs/default.json" $presets <<'PY'
import json, os, sys
sys.path.insert(0, sys.argv[1])
from bench_reports import markdown_table, runs_of
out, budget, presets = sys.argv[2], sys.argv[3], sys.argv[5:]
default_k = json.load(open(sys.argv[4]))["clustering"]["clusters"]
rows, verdicts = [], []
for preset in presets:
    runs = runs_of(out, preset)
    for label, (st, rep) in sorted(runs.items(), key=lambda kv: -kv[1][0]["ratio"]):
        seconds = st["seconds"]["train"] or st["seconds"].get("pca", 0)
        rows.append([preset, label, st["bytes"]["file"], f'1:{st["ratio"]:.0f}', f'{rep["rmse"]:.5f}',
                     f'{rep["rmse_holdout"]:.5f}' if rep["rmse_holdout"] is not None else "-",
                     f'{rep["rmse_ground_truth"]:.5f}' if rep.get("rmse_ground_truth") is not None else "-",
                     f'{rep["psnr"]:.2f}', f'{rep["blur_sigma"]:.2f}', f'{seconds:.0f}'])
    base = runs.get("baseline_k500")
    nbtf = {l: r for l, r in runs.items() if l.startswith("nbtf_k")}
    if not base or not nbtf: continue
    bs, br = base
    if f"nbtf_k{default_k}" in nbtf:
        s, r = nbtf[f"nbtf_k{default_k}"]
        gain, gain_h = 1 - r["rmse"] / br["rmse"], 1 - r["rmse_holdout"] / br["rmse_holdout"]
        ok = s["ratio"] >= 10000 and gain >= 0.15 and gain_h >= 0.15
        verdicts.append(f'bench frontier_{preset}_default: k = {default_k}, ratio 1:{s["ratio"]:.0f}, RMSE {r["rmse"]:.5f} vs baseline '
                        f'{br["rmse"]:.5f} ({100 * gain:.1f}% lower), held-out {r["rmse_holdout"]:.5f} vs '
                        f'{br["rmse_holdout"]:.5f} ({100 * gain_h:.1f}% lower) (target >= 1:10000, both >= 15% lower) '
                        f'{"PASS" if ok else "FAIL"}')
    fid = [(r["rmse"], l, s, r) for l, (s, r) in nbtf.items() if s["ratio"] >= 1000]
    if fid:
        rmse, l, s, r = min(fid)
        ok = rmse <= 0.65 * br["rmse"] and r["blur_sigma"] <= 0.5 * br["blur_sigma"]
        verdicts.append(f'bench frontier_{preset}_high_fidelity: best at >= 1:1000 is {l} (1:{s["ratio"]:.0f}), RMSE '
                        f'{rmse:.5f} = {rmse / br["rmse"]:.2f} x baseline, blur sigma {r["blur_sigma"]:.2f} vs '
                        f'{br["blur_sigma"]:.2f} (target <= 0.65 x, <= half) {"PASS" if ok else "FAIL"}')
    # (3): step functions of the ratio; checked at 1:500, 1:20000 and every point between.
    ours = [(s["ratio"], r["rmse"]) for s, r in nbtf.values()]
    others = [(s["ratio"], r["rmse"], l) for l, (s, r) in runs.items() if l.startswith("pca_") or l == "per_texel"]
    worst = None
    for ratio in sorted({500, 20000} | {x for x, *_ in ours + others if 500 <= x <= 20000}):
        best = min((e for x, e in ours if x >= ratio), default=None)
        rival = min(((e, l) for x, e, l in others if 500 <= x <= ratio), default=None)
        if rival is None: continue
        if best is None or best >= rival[0]:
            worst = worst or (ratio, best, rival)
    verdicts.append(f'bench frontier_{preset}_dominant: ' +
                    ("at every ratio from 1:500 to 1:20000 nbtf's best point beats PCA and per-texel at that size or larger PASS"
                     if worst is None else
                     f'at 1:{worst[0]:.0f} nbtf\'s best point of that size or smaller has RMSE '
                     f'{"none" if worst[1] is None else f"{worst[1]:.5f}"} against {worst[2][1]}\'s {worst[2][0]:.5f} FAIL'))
head = ["preset", "run", "file B", "ratio", "RMSE", "held-out RMSE", "RMSE vs ground truth", "PSNR dB", "blur sigma",
        "train s"]
text = markdown_table(head, rows) + (f"\n\nNeural rows: {budget} s training budget each. RMSE and held-out RMSE: linear RGB / alpha "
                           "(eq. 10), all images (held-out: the 10% kept out of training); RMSE vs ground truth: the same against the "
                           "float ground truth nbtf-synth wrote beside the stack, not its 8-bit images; PSNR: peak 1 in that space; "
                           "ratio: the float32 stack over the file's counted bytes; train s: training (PCA: the fit).\n")
with open(os.path.join(out, "frontier.md"), "w") as f: f.write(text + "\n" + "\n".join(verdicts) + "\n")
print(text)
print("\n".join(verdicts))
PY
echo "bench_frontier: table $out/frontier.md, reports $out/<preset>-<run>/report.html, plots $out/summary/"
