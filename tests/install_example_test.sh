#!/usr/bin/env bash
# The installed package works for an outside project: `cmake --install` the build into a
# fresh prefix, build examples/decode_texel against it with find_package(nbtf) and
# nbtf::decode alone, check that it links neither torch nor OpenCV nor OpenEXR, and that it
# decodes committed files to exactly what `nbtf query` prints; and that the installed Python
# package (where the build has one) imports from the prefix and answers the same.
#   tests/install_example_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" >/dev/null
cmake -S "$src/examples/decode_texel" -B "$work/example" -DCMAKE_PREFIX_PATH="$work/prefix" \
  -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/example" -- --no-print-directory >/dev/null
example=$work/example/decode_texel
# Names and paths only: ldd's load addresses are hex, and one holding "c10" is not libc10.
if ldd "$example" | awk '{print $1, $3}' | grep -Ei 'torch|opencv|openexr|imath|c10'; then
  echo "FAIL: the decode example links a training or image library (above)" >&2
  exit 1
fi
status=0
for file in legacy_v1_0 compact_v1_2; do
  nbtf=$src/tests/data/$file.nbtf
  query=(5 3 30 60 45 180)
  got=$("$example" "$nbtf" "${query[@]}" "$work/$file.pfm")
  want=$("$build/bin/nbtf" query "$nbtf" --texel "${query[0]},${query[1]}" --light "${query[2]},${query[3]}" \
         --view "${query[4]},${query[5]}")
  if [[ "$got" != "$want" ]]; then
    echo "FAIL: $file: the example printed '$got', nbtf query '$want'" >&2
    status=1
  fi
  # A PFM of the whole material: header, then width x height x 3 floats.
  read -r w h < <(sed -n 2p "$work/$file.pfm")
  header=$(head -c 100 "$work/$file.pfm" | head -n 3 | wc -c)
  size=$(stat -c %s "$work/$file.pfm")
  if (( size != header + w * h * 12 )); then
    echo "FAIL: $file: the image has $size bytes, expected $header + $w x $h x 12" >&2
    status=1
  fi
  echo "$file: example and nbtf query agree ($got); image $w x $h"
done
# The Python package: installed into site-packages under the prefix.
python=$(sed -n 's/^NBTF_PYTHON_EXECUTABLE:INTERNAL=//p' "$build/CMakeCache.txt")
module=$(find "$work/prefix" -name '_nbtf.*.so' | head -n 1)
if [[ -n "$python" && -n "$module" ]]; then
  site=$(dirname "$(dirname "$module")")
  nbtf=$(cd "$src" && pwd)/tests/data/legacy_v1_0.nbtf  # absolute: python runs in $work (not beside a build tree)
  want=$("$build/bin/nbtf" query "$nbtf" --texel 5,3 --light 30,60 --view 45,180)
  got=$(cd "$work" && PYTHONPATH="$site" "$python" -c '
import sys, nbtf
print(nbtf.__file__)
print(" ".join("%.9g" % v for v in nbtf.open(sys.argv[1]).query(texel=(5, 3), light=(30, 60), view=(45, 180))))' "$nbtf")
  if [[ "$(sed -n 1p <<< "$got")" != "$site"/nbtf/__init__.py || "$(sed -n 2p <<< "$got")" != "$want" ]]; then
    echo "FAIL: the installed Python package printed '$got', nbtf query '$want' (expected from $site)" >&2
    status=1
  else
    echo "python: the installed package ($site) and nbtf query agree"
  fi
fi
exit $status
