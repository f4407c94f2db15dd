#!/usr/bin/env bash
# The pictures of docs/live-view.md: `twin serve` of a scenario, played to its end, photographed by headless Chromium
# (software WebGL) as a person would see the page, and from the cell camera's view.
#   tools/live_view_screenshots.sh [SCENARIO] [OUT_DIR]   (defaults: scenes/exchange.yaml docs/images)
# Needs a build (build/tools/twin, BUILD_DIR to change it) and chromium.
set -euo pipefail
cd "$(dirname "$0")/.."
scenario=${1:-scenes/exchange.yaml}
out=${2:-docs/images}
twin=${BUILD_DIR:-build}/tools/twin
mkdir -p "$out"
log=$(mktemp)
MUJOCO_GL=osmesa "$twin" serve "$scenario" --port 0 --play >"$log" 2>&1 &
pid=$!
trap 'kill $pid 2>/dev/null; wait $pid 2>/dev/null || true; rm -f "$log"' EXIT
for _ in $(seq 100); do grep -q "Ctrl-C stops" "$log" && break; sleep 0.2; done
port=$(sed -n 's|.*http://127.0.0.1:\([0-9]*\)/.*|\1|p' "$log")
[[ -n $port ]] || { echo "twin serve did not start:" >&2; cat "$log" >&2; exit 1; }
shot() {  # shot FILE WIDTH HEIGHT URL
  chromium --headless=new --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader --hide-scrollbars \
    --window-size="$2,$3" --virtual-time-budget=8000 --screenshot="$1" "$4" 2>/dev/null
}
shot "$out/live-view-3d.png" 1400 800 "http://127.0.0.1:$port/"
shot "$out/live-view-camera.png" 640 480 "http://127.0.0.1:$port/?view=camera:overhead"
ls -l "$out"/live-view-*.png
