#!/usr/bin/env bash
# The real-time factor of a whole `twin run` (issue 26's figure): simulated seconds over wall seconds of the process,
# and over its CPU seconds (user + system: less disturbed on a loaded machine), each the median of N runs pinned to
# one core. Given two twin executables (e.g. one built from the tree before a change and this tree's), measures them
# alternately, run by run, so that the ratio after / before is taken at the same load, in one invocation.
#
#   tools/bench/rtf.sh [-n N] TWIN_BEFORE TWIN_AFTER [SCENARIO.yaml...]   (from the source directory;
#                                                                         default scenarios: exchange and pipeline)
# Each run is `taskset -c 0 TWIN run SCENARIO --quiet`; its simulated time is the `t = X s` of the summary line. A
# run that does not end OK is reported and stops the script (exit 1): the figures of a failed run do not compare.
set -euo pipefail

cd "$(dirname "$0")/../.."
n=3
if [[ ${1:-} == -n ]]; then n=$2; shift 2; fi
[[ $# -ge 2 ]] || { echo "usage: $0 [-n N] TWIN_BEFORE TWIN_AFTER [SCENARIO.yaml...]" >&2; exit 2; }
before=$1 after=$2
shift 2
scenarios=("$@")
[[ ${#scenarios[@]} -gt 0 ]] || scenarios=(scenes/exchange.yaml scenes/pipeline.yaml)
for twin in "$before" "$after"; do
  [[ -x $twin ]] || { echo "$twin: not an executable" >&2; exit 2; }
done
export MUJOCO_GL=osmesa
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

median() { sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }

# One run: prints "simulated wall cpu".
one() {
  local twin=$1 scenario=$2 sim
  if ! /usr/bin/time -f '%e %U %S' -o "$work/time" taskset -c 0 "$twin" run "$scenario" --quiet >"$work/out" 2>&1; then
    echo "$twin run $scenario failed:" >&2
    cat "$work/out" >&2
    exit 1
  fi
  sim=$(sed -n 's/^OK: .* at t = \([0-9.]*\) s.*/\1/p' "$work/out")
  read -r wall user sys <"$work/time"
  echo "$sim $wall $(echo "$user + $sys" | bc -l)"
}

printf '%-26s %-7s %9s %9s %8s %9s %8s\n' scenario twin simulated wall rtf cpu rtf_cpu
for scenario in "${scenarios[@]}"; do
  for twin in before after; do : >"$work/$twin"; done
  for ((i = 0; i < n; i++)); do
    one "$before" "$scenario" >>"$work/before"
    one "$after" "$scenario" >>"$work/after"
  done
  for twin in before after; do
    sim=$(cut -d' ' -f1 "$work/$twin" | median)
    wall=$(cut -d' ' -f2 "$work/$twin" | median)
    cpu=$(cut -d' ' -f3 "$work/$twin" | median)
    rtf=$(echo "$sim / $wall" | bc -l)
    rtf_cpu=$(echo "$sim / $cpu" | bc -l)
    printf '%-26s %-7s %8.2fs %8.2fs %7.1fx %8.2fs %7.1fx\n' "$scenario" "$twin" "$sim" "$wall" "$rtf" "$cpu" "$rtf_cpu"
    eval "rtf_$twin=$rtf; cpu_$twin=$rtf_cpu"
  done
  printf '%-26s after/before: %.2f (wall), %.2f (cpu); load %s\n' "$scenario" "$(echo "$rtf_after / $rtf_before" | bc -l)" \
    "$(echo "$cpu_after / $cpu_before" | bc -l)" "$(cut -d' ' -f1 /proc/loadavg)"
done
