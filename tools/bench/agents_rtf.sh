#!/usr/bin/env bash
# The lock-step real-time factor with every robot control in an agent process against every robot control in the run's
# process (issue 28's figure; docs/distributed.md, "Figures"): simulated seconds over the wall seconds of the `twin run`
# process (its start, the agents' discovery included, to its exit), the median of N runs each, the two set-ups taken
# alternately run by run so that their ratio is measured at the same load, in one invocation.
#
#   tools/bench/agents_rtf.sh [-n N] [-c CPUS] TWIN [SCENARIO.yaml...]   (from the source directory; default
#                                                                        scenarios: exchange and pipeline)
# Every process (the run and its agents) is pinned with `taskset -c CPUS` (default 0: all on one core). The agents of a
# run are started first and waited for ("waiting for task control"); each run uses DDS domain 150 + its number modulo
# 50. A run that does not end OK, or an agent that does not exit 0, stops the script (exit 1).
set -euo pipefail

cd "$(dirname "$0")/../.."
n=3
cpus=0
while [[ ${1:-} == -* ]]; do
  case $1 in
    -n) n=$2; shift 2 ;;
    -c) cpus=$2; shift 2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done
[[ $# -ge 1 ]] || { echo "usage: $0 [-n N] [-c CPUS] TWIN [SCENARIO.yaml...]" >&2; exit 2; }
twin=$1
shift
[[ -x $twin ]] || { echo "$twin: not an executable" >&2; exit 2; }
scenarios=("$@")
[[ ${#scenarios[@]} -gt 0 ]] || scenarios=(scenes/exchange.yaml scenes/pipeline.yaml)
export MUJOCO_GL=osmesa
work=$(mktemp -d)
agents=()
cleanup() {
  for p in "${agents[@]}"; do kill "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT

median() { sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
runs=0

# The cell robots of a scenario, from its `robots: {label: robot, ...}` line.
robots_of() {
  sed -n 's/^robots: *{\(.*\)}.*/\1/p' "$1" | tr ',' '\n' | sed 's/.*: *//; s/ *$//'
}

# One run: prints "simulated wall".
one() {
  local scenario=$1 mode=$2 sim domain
  local -a extra=()
  if [[ $mode == agents ]]; then
    runs=$((runs + 1))
    domain=$((150 + runs % 50))
    agents=()
    for robot in $(robots_of "$scenario"); do
      taskset -c "$cpus" "$twin" agent "$scenario" --robot "$robot" --domain "$domain" --wait 60 >"$work/agent-$robot" 2>&1 &
      agents+=($!)
    done
    for robot in $(robots_of "$scenario"); do
      for ((w = 0; w < 300; w++)); do
        grep -q "waiting for task control" "$work/agent-$robot" && break
        sleep 0.1
      done
    done
    extra=(--agents remote --domain "$domain")
  fi
  if ! /usr/bin/time -f '%e' -o "$work/time" taskset -c "$cpus" "$twin" run "$scenario" --quiet "${extra[@]}" \
      >"$work/out" 2>&1; then
    echo "$twin run $scenario ${extra[*]} failed:" >&2
    cat "$work/out" >&2
    exit 1
  fi
  for p in "${agents[@]}"; do
    if ! wait "$p"; then
      echo "an agent of $scenario did not exit 0:" >&2
      cat "$work"/agent-* >&2
      exit 1
    fi
  done
  agents=()
  sim=$(sed -n 's/^OK: .* at t = \([0-9.]*\) s.*/\1/p' "$work/out")
  echo "$sim $(cat "$work/time")"
}

printf '%-26s %-10s %9s %9s %8s\n' scenario robots simulated wall rtf
for scenario in "${scenarios[@]}"; do
  : >"$work/local"
  : >"$work/agents"
  for ((i = 0; i < n; i++)); do
    one "$scenario" local >>"$work/local"
    one "$scenario" agents >>"$work/agents"
  done
  for mode in local agents; do
    sim=$(cut -d' ' -f1 "$work/$mode" | median)
    wall=$(cut -d' ' -f2 "$work/$mode" | median)
    rtf=$(echo "$sim / $wall" | bc -l)
    printf '%-26s %-10s %8.2fs %8.2fs %7.1fx\n' "$scenario" "$mode" "$sim" "$wall" "$rtf"
    eval "rtf_$mode=$rtf"
  done
  printf '%-26s agents/local: %.3f; load %s\n' "$scenario" "$(echo "$rtf_agents / $rtf_local" | bc -l)" \
    "$(cut -d' ' -f1 /proc/loadavg)"
done
