# Shared by the scripts in this folder; each sources it right after `set -euo pipefail`:
#   source "$(dirname "$0")/lib.sh"
# It sets
#   root        the repository
#   bench_data  where benchmark inputs are cached ($NBTF_BENCH_DATA, default build/bench_data)
# and defines the helpers below.

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bench_data=${NBTF_BENCH_DATA:-$root/build/bench_data}

# cmake_build DIR [cmake --build options]: builds with the per-file progress lines filtered out.
# (grep only filters: with pipefail the pipeline fails exactly when the build does.)
cmake_build() {
  local dir=$1
  shift
  cmake --build "$dir" -j "$(nproc)" "$@" -- --no-print-directory 2>&1 |
    { grep -vE '^\[ *[0-9]+%\] (Building|Linking)|^Scanning|^Consolidate' || true; }
}

# nbtf_build [setup.sh options]: installs what is missing and builds build/ (Release); sets
# `bin` to its binaries. With NBTF_BIN_DIR set, those binaries are used as they are instead.
nbtf_build() {
  bin=${NBTF_BIN_DIR:-}
  if [[ -z "$bin" ]]; then
    "$root/scripts/setup.sh" "$@"
    "$root/scripts/build.sh" "$root/build"
    bin=$root/build/bin
  fi
}

# synth_once DIR NBTF-SYNTH-OPTIONS...: generates a synthetic stack into DIR unless DIR already
# holds one (a synth.json); progress goes to stderr, so it can run inside $(...).
synth_once() {
  local dir=$1
  shift
  if [[ ! -f "$dir/synth.json" ]]; then
    echo "== generating nbtf-synth $* (once; cached in $dir)" >&2
    "$bin/nbtf-synth" "$@" -o "$dir" >&2
  fi
}

# file_bytes STATS-JSON: the written file's bytes a `nbtf compress --stats-json` recorded.
file_bytes() {
  python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["bytes"]["file"])' "$1"
}

# preset_stack SPEC OUT: the 100 x 100 synthetic stack of a preset SPEC, "NAME" (the UBO2003
# layout, 8-bit JPEG) or "NAME:utia" (the UTIA layout, 8-bit PNG), with its float ground truth,
# generated once into OUT/NAME100_LAYOUT; prints "LABEL DIR", LABEL naming the preset's runs
# (fabric, fabric_utia).
preset_stack() {
  local name=${1%%:*} layout=ubo2003 label options="--layout ubo2003"
  [[ $1 == *:* ]] && layout=${1#*:}
  case "$layout" in
    ubo2003) label=$name;;
    utia) label=${name}_utia options="--layout utia --format png";;
    *) echo "unknown layout '$layout' in preset '$1' (NAME or NAME:utia)" >&2; return 2;;
  esac
  # shellcheck disable=SC2086  # the options are words
  synth_once "$2/${name}100_$layout" --preset "$name" --size 100x100 $options --seed 1 -q
  echo "$label $2/${name}100_$layout"
}

# bench_banner [TEXT]: the first line of every benchmark's output: cores, date, commit, TEXT.
bench_banner() {
  echo "== $(nproc) cores, $(date -u '+%Y-%m-%d %H:%M UTC'), commit" \
    "$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)${1:+; $1}"
}

# compress_and_eval OUT PRESET LABEL DATA COMPRESS-OPTIONS...: compresses DATA into
# OUT/PRESET-LABEL.nbtf (10% of the images held out, seed 1; the summary in .stats.json) and
# evaluates it against DATA into OUT/PRESET-LABEL/; appends its report.json to the array
# `reports` (for `nbtf eval --summarize`; scripts/bench_reports.py reads them back).
compress_and_eval() {
  local out=$1 preset=$2 label=$3 data=$4
  shift 4
  local file=$out/$preset-$label.nbtf
  echo "== $preset: $label"
  "$bin/nbtf" compress "$data" -o "$file" "$@" --holdout 0.1 --seed 1 -q --stats-json "$out/$preset-$label.stats.json" |
    grep -E "^  (training|held-out|floor|modulated|total|ratio|file)" || true
  "$bin/nbtf" eval "$file" --reference "$data" -o "$out/$preset-$label" -q > /dev/null
  reports+=("$out/$preset-$label/report.json")
}

# run_rows OUT PRESET DATA ROW...: compress_and_eval for each ROW, "label|compress options".
run_rows() {
  local out=$1 preset=$2 data=$3 row
  local -a opts
  shift 3
  for row in "$@"; do
    read -r -a opts <<<"${row#*|}"
    compress_and_eval "$out" "$preset" "${row%%|*}" "$data" "${opts[@]}"
  done
}
