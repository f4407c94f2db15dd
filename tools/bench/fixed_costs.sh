#!/usr/bin/env bash
# Fixed costs of a run, on one core (issue 24's figures): campaign runs per minute, the demo's wall time and its peak
# RSS, each the median of 3, with the load average at the time. Given two twin executables (e.g. a copy of main's
# and this tree's), measures them back to back, figure by figure, so that the ratio is taken at the same load.
#
#   tools/bench/fixed_costs.sh [TWIN_BEFORE] TWIN_AFTER     (from the source directory; default after: build/tools/twin)
set -euo pipefail

cd "$(dirname "$0")/../.."
if [[ $# -ge 2 ]]; then
  twins=("$1" "$2")
else
  twins=("${1:-build/tools/twin}")
fi
export MUJOCO_GL=osmesa
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

median() { sort -g | sed -n 2p; }
load() { cut -d' ' -f1 /proc/loadavg; }

# Wall seconds of one command (its output discarded).
wall() {
  local t0 t1
  t0=$(date +%s.%N)
  "$@" >/dev/null 2>&1
  t1=$(date +%s.%N)
  echo "$t1 - $t0" | bc -l
}

for twin in "${twins[@]}"; do
  [[ -x $twin ]] || { echo "$twin: not an executable" >&2; exit 2; }
done

echo "campaign: taskset -c 0 TWIN campaign scenes/exchange.yaml --runs 20 --seed 5 --jobs 1 (runs per minute)"
for twin in "${twins[@]}"; do
  l=$(load)
  m=$(for i in 1 2 3; do
        rm -rf "$work/c"
        s=$(wall taskset -c 0 "$twin" campaign scenes/exchange.yaml --runs 20 --seed 5 --jobs 1 -o "$work/c")
        echo "20 * 60 / $s" | bc -l
      done | median)
  printf '  %-40s %6.1f runs/min  (load %s)\n' "$twin" "$m" "$l"
done

echo "demo: taskset -c 0 TWIN run scenes/exchange.yaml -o DIR (wall seconds)"
for twin in "${twins[@]}"; do
  l=$(load)
  m=$(for i in 1 2 3; do
        rm -rf "$work/d"
        wall taskset -c 0 "$twin" run scenes/exchange.yaml --quiet -o "$work/d"
      done | median)
  printf '  %-40s %6.2f s  (load %s)\n' "$twin" "$m" "$l"
done

echo "peak RSS: /usr/bin/time -v TWIN run scenes/exchange.yaml -o DIR (Maximum resident set size)"
for twin in "${twins[@]}"; do
  l=$(load)
  m=$(for i in 1 2 3; do
        rm -rf "$work/r"
        /usr/bin/time -v taskset -c 0 "$twin" run scenes/exchange.yaml --quiet -o "$work/r" 2>&1 >/dev/null |
          awk '/Maximum resident/ {print $6}'
      done | median)
  printf '  %-40s %6d kB  (load %s)\n' "$twin" "$m" "$l"
done
