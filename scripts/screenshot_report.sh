#!/usr/bin/env bash
# Takes a screenshot of an evaluation report (report.html) with headless Chromium, to check
# by looking that it reads well. Usage: scripts/screenshot_report.sh <report.html> <out.png> [WIDTH,HEIGHT]
# Installs Debian's chromium through scripts/setup.sh when it is missing.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
if [[ $# -lt 2 ]]; then
  echo "usage: $0 <report.html> <out.png> [WIDTH,HEIGHT (default 1200,3000)]" >&2
  exit 2
fi
html=$1
out=$2
size=${3:-1200,3000}
[[ -f "$html" ]] || { echo "screenshot_report: '$html' does not exist" >&2; exit 1; }

browser=$(command -v chromium || command -v chromium-browser || true)
if [[ -z "$browser" ]]; then
  "$root/scripts/setup.sh" --with chromium
  browser=$(command -v chromium || true)
fi
[[ -n "$browser" ]] || { echo "screenshot_report: chromium is not installed and could not be installed" >&2; exit 1; }

html_abs=$(cd "$(dirname "$html")" && pwd)/$(basename "$html")
out_abs=$(cd "$(dirname "$out")" && pwd)/$(basename "$out")
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
# Write beside the target, then rename: no half-written screenshot under the final name.
tmp="$out_abs.tmp.png"
"$browser" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking \
  --disable-component-update --disable-sync --hide-scrollbars --user-data-dir="$profile" \
  --screenshot="$tmp" --window-size="$size" "file://$html_abs" >/dev/null 2>&1 || true
if [[ ! -s "$tmp" ]]; then
  rm -f "$tmp"
  echo "screenshot_report: chromium wrote no screenshot for '$html'" >&2
  exit 1
fi
mv "$tmp" "$out_abs"
echo "screenshot_report: wrote $out ($size)"
