#!/usr/bin/env bash
# scripts/sweep.sh end to end on a tiny material (nbtf-synth, 8 x 8 texels): the PCA baseline
# and one clustered run, their reports, and the summary (table and plot) in the sweep's own
# summary/ folder; a second run keeps the finished reports and writes the summary again.
#   tests/sweep_script_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
"$build/bin/nbtf-synth" --preset wool --size 8x8 --layout ubo2003 --seed 1 -q -o "$work/wool"
run() {
  NBTF_BIN="$build/bin/nbtf" "$src/scripts/sweep.sh" "$work/wool" -o "$work/sweep" --k "4" --pca "2" \
    --no-per-texel --threads 1 --epochs 1 > "$work/log.txt" 2>&1 || { cat "$work/log.txt" >&2; fail "sweep.sh exited non-zero"; }
}
run
for f in sweep/pca_2.nbtf sweep/k4.nbtf sweep/pca_2/report.json sweep/k4/report.json sweep/summary/sweep.md \
         sweep/summary/rd_wool.png; do
  [[ -s "$work/$f" ]] || fail "$f was not written"
done
grep -q "PCA" "$work/sweep/summary/sweep.md" || fail "the table has no PCA column"
grep -q "k = 4" "$work/sweep/summary/sweep.md" || fail "the table has no k = 4 column"
run
grep -q "k4 (report exists, kept)" "$work/log.txt" || fail "a second run did not keep the finished report"
[[ -s "$work/sweep/summary/sweep.md" ]] || fail "a second run lost the summary"
echo "sweep.sh: 2 runs, table and plot in summary/: ok"
