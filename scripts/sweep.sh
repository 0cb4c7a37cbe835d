#!/usr/bin/env bash
# Rate-distortion sweep of one material: compresses it with the PCA baseline at several
# component counts (`nbtf compress --method pca`), the per-texel neural BTF and the
# clustered neural BTF at several k, evaluates each against the reference with
# `nbtf eval`, and writes the paper-style table (sweep.md) and a rate-distortion plot
# (rd_<material>.png, drawn by nbtf itself) into the folder summary/ of the output folder
# (beside the runs' files and report folders, which it reads).
#
# usage: scripts/sweep.sh <input stack> [options] [-- extra nbtf compress options]
#   -o DIR            output folder (default: sweep_<material>)
#   --k "LIST"        cluster counts (default: "500 1000 2000")
#   --pca "LIST"      PCA component counts (default: "4 8 16 32")
#   --no-per-texel    skip the per-texel neural BTF
#   --crop X,Y,W,H    crop (default: whole images; the paper used 100 x 100)
#   --holdout F       fraction of images kept out of training / the PCA fit (interpolation error)
#   --seed N | --threads N | --layout L     passed to every `nbtf compress`
#   --epochs N | --time-budget S | --config FILE
#                     passed to the neural runs only (PCA has no training)
#   -- OPTIONS        extra `nbtf compress` options for the neural runs
# Several materials: run once per material, then combine the reports:
#   build/bin/nbtf eval --summarize -o all sweep_*/*/report.json
# Re-running the same command keeps every finished report and resumes an interrupted neural run
# from its checkpoint.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
nbtf=${NBTF_BIN:-$root/build/bin/nbtf}

die() { echo "sweep: $*" >&2; exit 1; }
[[ $# -ge 1 && $1 != -* ]] || { sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
input=$1; shift
[[ -d "$input" ]] || die "input '$input' is not a folder"
material=$(basename "$(cd "$input" && pwd)")
out="sweep_$material"
ks="500 1000 2000"
pcas="4 8 16 32"
per_texel=1
common=()   # every run
neural=()   # neural runs only
while [[ $# -gt 0 ]]; do
  case "$1" in
    -o) out=$2; shift;;
    --k) ks=$2; shift;;
    --pca) pcas=$2; shift;;
    --no-per-texel) per_texel=0;;
    --crop|--holdout|--seed|--threads|--layout) common+=("$1" "$2"); shift;;
    --epochs|--time-budget|--config) neural+=("$1" "$2"); shift;;
    --) shift; neural+=("$@"); break;;
    *) die "unknown option '$1' (see the header of $0)";;
  esac
  shift
done

# ---- Tools: the nbtf binary.
[[ -x "$nbtf" ]] || "$root/scripts/build.sh" "$root/build"
[[ -x "$nbtf" ]] || die "no nbtf binary at $nbtf"

mkdir -p "$out"
runs=()    # label|kind|compress options
for c in $pcas; do runs+=("pca_$c|pca|--method pca --components $c"); done
[[ $per_texel -eq 1 ]] && runs+=("per_texel|neural|--method per-texel")
for k in $ks; do runs+=("k$k|neural|--clusters $k"); done

# ---- Compress and evaluate each setting (a finished report is kept; an interrupted neural
# run continues from its checkpoint: --resume starts afresh where there is none).
reports=()
for run in "${runs[@]}"; do
  label=${run%%|*}
  rest=${run#*|}
  kind=${rest%%|*}
  read -r -a opts <<<"${rest#*|}"
  [[ $kind == neural ]] && opts+=(--resume ${neural[@]+"${neural[@]}"})
  file="$out/$label.nbtf"
  report="$out/$label/report.json"
  if [[ ! -f "$report" ]]; then
    echo "== $material: $label"
    "$nbtf" compress "$input" -o "$file" "${opts[@]}" ${common[@]+"${common[@]}"}
    "$nbtf" eval "$file" --reference "$input" -o "$out/$label"
  else
    echo "== $material: $label (report exists, kept)"
  fi
  reports+=("$report")
done

# ---- Table and plot, in a folder of their own (the report folders are the summary's inputs).
"$nbtf" eval --summarize -o "$out/summary" "${reports[@]}"
echo "sweep: table $out/summary/sweep.md, plot(s): $(ls "$out"/summary/rd_*.png | tr '\n' ' ')"
