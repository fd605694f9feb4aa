#!/usr/bin/env bash
# Render a qualification report in headless Chromium and save a PNG of it.
#
#   scripts/screenshot_report.sh QUAL_DIR [OUT.png]
#
# Writes QUAL_DIR/report.html first (hil report) when it is not there yet. OUT defaults to
# QUAL_DIR/report.png; the window is 1280 px wide and SCREENSHOT_HEIGHT (default 4000) tall.
# Exit status: 0 written, 2 usage error or no report, 3 no Chromium, 1 Chromium failed.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 || "$1" == -h || "$1" == --help ]]; then
    sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'
    [[ $# -ge 1 && ("$1" == -h || "$1" == --help) ]] && exit 0
    exit 2
fi
qual_dir=$1
out=${2:-$qual_dir/report.png}
height=${SCREENSHOT_HEIGHT:-4000}

browser=""
for name in chromium chromium-browser google-chrome; do
    if command -v "$name" >/dev/null 2>&1; then browser=$name; break; fi
done
if [[ -z "$browser" ]]; then
    echo "screenshot_report.sh: chromium not installed (Debian: apt-get install chromium)" >&2
    exit 3
fi

if [[ ! -f "$qual_dir/report.html" ]]; then
    python -m hil report "$qual_dir" || exit 2
fi
report=$(cd "$qual_dir" && pwd)/report.html
mkdir -p "$(dirname "$out")"
out_abs=$(cd "$(dirname "$out")" && pwd)/$(basename "$out")

profile=$(mktemp -d)
log=$(mktemp)
trap 'rm -rf "$profile" "$log"' EXIT
flags=(--headless --disable-gpu --hide-scrollbars --no-first-run --mute-audio
       --user-data-dir="$profile" --window-size="1280,$height" --screenshot="$out_abs")
# Chromium refuses to run as root inside its sandbox
if [[ $(id -u) -eq 0 ]]; then flags+=(--no-sandbox); fi
rm -f "$out_abs"
if ! timeout 120 "$browser" "${flags[@]}" "file://$report" >"$log" 2>&1 || [[ ! -s "$out_abs" ]]; then
    echo "screenshot_report.sh: $browser did not write $out_abs; its output:" >&2
    tail -20 "$log" >&2
    exit 1
fi
echo "$out_abs"
