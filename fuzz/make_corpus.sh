#!/usr/bin/env bash
# Regenerates the fuzzer's seed corpus fuzz/corpus/: small but real .nbtf files, written by
# `nbtf compress` from a tiny synthetic material (nbtf-synth, 8 x 8 texels, 81 x 81
# directions) with a tiny network (fuzz/tiny_config.json), so each file is a few KB and
# every section the writer produces (except the optional encoder) is in at least one.
#   fuzz/make_corpus.sh [BUILD_DIR]    (default build/, made by scripts/build.sh)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${1:-$root/build}/bin
out=$root/fuzz/corpus
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

"$bin/nbtf-synth" --preset fabric --size 8 --layout utia --format png --seed 1 --no-ground-truth -q -o "$tmp/stack"
compress() {  # NAME ARGS...: one corpus file (CONFIG=file: another recipe than tiny_config.json)
  local name=$1
  shift
  "$bin/nbtf" compress "$tmp/stack" -o "$tmp/$name.nbtf" --config "${CONFIG:-$root/fuzz/tiny_config.json}" --seed 1 \
    --threads 1 -q "$@" >/dev/null
}
# Clustered, whole image, 1-byte ids.
compress clustered --clusters 3
# Clustered with a crop and a hold-out set (section HOLD). (--save-encoder is left out: the
# serialized encoder is ~40 KB, and the reader only copies section ENCD as opaque bytes.)
compress clustered_crop_holdout --clusters 5 --crop 1,2,5,4 --holdout 0.01
# Format 1.2: per-texel modulation (TXSC), half-precision decoder and latents (DECH, LATH),
# zstd-coded ids (TXIZ).
CONFIG=$root/fuzz/tiny_compact_config.json compress compact --clusters 5
# Per-texel (no id list), cropped to 3 x 2 texels.
compress per_texel --clusters 0 --crop 2,2,3,2
# PCA baseline (sections PCAM/PCAB/PCAC). Its mean and basis have a row per image, so the
# seed comes from a 3-light x 2-view subset of the stack (the loader takes any complete
# light x view set): a file of a few KB, well inside the fuzzer's -max_len.
mkdir -p "$tmp/small"
for view in $(ls "$tmp/stack" | grep '^tv' | head -2); do
  mkdir -p "$tmp/small/$view"
  for image in $(ls "$tmp/stack/$view" | sort | head -3); do cp "$tmp/stack/$view/$image" "$tmp/small/$view/"; done
done
"$bin/nbtf" compress "$tmp/small" -o "$tmp/pca.nbtf" --method pca --components 2 --seed 1 --threads 1 -q >/dev/null

rm -f "$out"/*.nbtf
cp "$tmp"/*.nbtf "$out/"
ls -l "$out"
