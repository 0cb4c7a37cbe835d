#!/usr/bin/env bash
# Benchmark of the decoder as a fragment shader: `nbtf view`'s page in headless
# Chromium (WebGL2 on SwiftShader, the software rasterizer) renders the plane's default view at
# SIZE x SIZE (default 1024) a few times; the page reports the median frame time and the pixels
# the material covers. Beside it: the shader's work per pixel, counted from the decoder's
# description (`nbtf export-shader`'s manifest: multiply-adds, other operations, uniform loads,
# texture fetches), an estimate for a named GPU from its throughput (docs/shader.md), and the CPU
# cross-check: `nbtf render` of the same view (same camera, light, one sample per pixel, no
# environment term) with all cores.
# Material: a compressed 100 x 100 synthetic fabric (k = 500, 60 s training budget; cached),
# or --file F.nbtf. --quick: a 32 x 32 material trained for 2 epochs, 256 x 256, 1 frame.
# Options: --size N, --frames F (default 3), --file F.nbtf, --quick, --weights W (auto, texture,
# uniform-blocks: where the page keeps the decoder's weights).
# SwiftShader's frame times say nothing about a GPU; the operation count is the portable figure.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
size=1024
frames=3
file=
quick=
weights=auto
while [[ $# -gt 0 ]]; do
  case $1 in
    --size) size=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --file) file=$2; shift 2 ;;
    --quick) quick=1; size=256; frames=1; shift ;;
    --weights) weights=$2; shift 2 ;;
    *) echo "bench_shader.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
# NBTF_BIN_DIR: binaries to measure (default: build them into build/).
nbtf_build
nbtf=$bin/nbtf
chromium=$(command -v chromium || command -v chromium-browser || true)
if [[ -z "$chromium" ]]; then
  echo "bench_shader.sh: chromium is not on the PATH (scripts/setup.sh installs it)" >&2
  exit 1
fi
work=$bench_data/shader
mkdir -p "$work"
bench_banner "shader: ${size} x ${size}, $frames frames"
if [[ -z "$file" ]]; then
  if [[ -n "$quick" ]]; then
    data=$bench_data/fabric32_ubo2003
    synth_once "$data" --preset fabric --size 32x32 --layout ubo2003 --seed 1 --no-ground-truth -q
    file=$work/fabric32_quick.nbtf
    [[ -f "$file" ]] || "$nbtf" compress "$data" -o "$file" --clusters 32 --epochs 2 -q >/dev/null
  else
    data=$bench_data/fabric100_ubo2003
    synth_once "$data" --preset fabric --size 100x100 --layout ubo2003 --seed 1 --no-ground-truth -q
    file=$work/fabric100_k500_60s.nbtf
    if [[ ! -f "$file" ]]; then
      echo "== compressing $data (k = 500, 60 s training budget)"
      "$nbtf" compress "$data" -o "$file" --clusters 500 --time-budget 60 -q >/dev/null
    fi
  fi
fi
echo "== material $file"
"$nbtf" export-shader "$file" -o "$work/export" --weights "$weights" -q
"$nbtf" view "$file" -o "$work/viewer.html" --weights "$weights" -q
echo "== chromium (SwiftShader): #bench=$size,$frames"
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
"$chromium" --headless --no-sandbox --use-gl=angle --use-angle=swiftshader --enable-unsafe-swiftshader \
  --user-data-dir="$profile" --dump-dom "file://$work/viewer.html#bench=$size,$frames" 2>/dev/null >"$work/bench_dom.html"
python3 - "$work/bench_dom.html" "$work/bench_page.json" <<'PY'
import html, json, re, sys
dom = open(sys.argv[1]).read()
m = re.search(r'<pre id="nbtf-result">(.*?)</pre>', dom, re.S)
if not m or not m.group(1):
    sys.exit("bench_shader.sh: the page wrote no result")
r = json.loads(html.unescape(m.group(1)))
if r.get("status") != "ok":
    sys.exit("bench_shader.sh: the page failed: " + r.get("message", "?"))
json.dump(r, open(sys.argv[2], "w"))
PY
read -r camera light < <(python3 -c "
import json, sys; r = json.load(open('$work/bench_page.json'))
print(','.join('%.6f' % x for x in r['camera']), ','.join(str(x) for x in r['light']))")
echo "== CPU cross-check: nbtf render --scene plane --uniform 1 --env 0, the same view"
"$nbtf" render "$file" --scene plane --size "${size}x${size}" --uniform 1 --env 0 --camera "$camera" \
  --light "$light" -o "$work/render_cpu.png" --stats-json "$work/render_cpu.json" -q
python3 - "$work/bench_page.json" "$work/export/manifest.json" "$work/render_cpu.json" <<'PY'
import json, sys
page, manifest, cpu = (json.load(open(p)) for p in sys.argv[1:4])
cost = manifest["cost_per_pixel"]
n, ms, covered = page["size"], page["frame_ms"], page["material_pixels"]
print(f"shader per pixel: {cost['operations']:.0f} operations ({cost['multiply_adds']:.0f} multiply-adds, "
      f"{cost['other_ops']:.0f} other, {cost['transcendentals']:.0f} transcendental), "
      f"{cost['uniform_loads']:.0f} uniform loads (weights: {manifest['weights']}), "
      f"{cost['texture_fetches']:.0f} texture fetches")
print(f"SwiftShader: {ms:.1f} ms per {n} x {n} frame (median of {len(page['frames_ms'])}; "
      f"{covered} pixels of material, {1e6 * ms / max(covered, 1) / 1e3:.2f} us per decoded pixel)")
print(f"CPU nbtf render, same view: {cpu['seconds'] * 1e3:.1f} ms ({cpu['material_queries']} material queries: "
      f"light and environment per pixel, even at --env 0; {1e6 * cpu['seconds'] / max(cpu['material_queries'], 1):.3f} us each)")
# A named GPU from its throughput (docs/shader.md): NVIDIA GeForce RTX 4090, 82.6 TFLOP/s FP32
# (41.3 T FMA instructions/s), 1290 GTexel/s bilinear (RGBA32F texels at a quarter of that).
alu = covered * (cost["operations"] + cost["uniform_loads"]) / 41.3e12
tex = covered * cost["texture_fetches"] / (1290e9 / 4)
print(f"estimate, RTX 4090: {1e3 * max(alu, tex):.2f} ms per frame "
      f"(arithmetic and uniform loads {1e3 * alu:.2f} ms, RGBA32F fetches {1e3 * tex:.2f} ms; the larger bounds it)")
PY
