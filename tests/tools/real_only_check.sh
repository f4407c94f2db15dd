#!/usr/bin/env bash
# Checks a `twin` built without the simulator (-DCW_SIM=OFF) as a user of a cell of real robots would run it: it links
# no MuJoCo, OSMesa or Assimp; it checks, compiles and analyses programs; and the commands that need the twin are
# refused with exit 2 and an error that says why. Run by .ci/run: bash tests/tools/real_only_check.sh BUILD_DIR
set -euo pipefail
build=${1:?usage: real_only_check.sh BUILD_DIR}
twin=$build/tools/twin
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
fail() { echo "real_only_check: $*" >&2; exit 1; }

# expect CODE TEXT -- COMMAND...: runs COMMAND, fails unless it exits CODE and its output has TEXT.
expect() {
  local code=$1 text=$2
  shift 3
  local out rc=0
  out=$("$@" 2>&1) || rc=$?
  [[ $rc == "$code" ]] || fail "'$*' exited $rc, not $code: $out"
  grep -qF -- "$text" <<<"$out" || fail "'$*' did not say '$text': $out"
}

if ldd "$twin" | grep -E 'mujoco|OSMesa|assimp|libGL\.so'; then fail "$twin links the simulator's libraries"; fi
expect 0 "no simulator (CW_SIM=OFF)" -- "$twin" --version
expect 0 "no deadlock" -- "$twin" check scenes/exchange.task
expect 0 "collisions not swept" -- "$twin" compile scenes/exchange.task --scenario scenes/exchange.yaml \
  --robot-language -o "$scratch/programs" --driver puma=val2 --driver melfa=movemaster
[[ -n $(ls "$scratch/programs") ]] || fail "twin compile --robot-language wrote no robot program"
expect 2 "needs the simulator" -- "$twin" run scenes/exchange.yaml
expect 2 "needs the simulator" -- "$twin" snapshot scenes/cell.yaml -o "$scratch/cell.png"
expect 2 "needs the simulator" -- "$twin" campaign scenes/exchange.yaml -o "$scratch/c"
[[ ! -e $scratch/c && ! -e $scratch/cell.png ]] || fail "a refused command wrote something"
echo "real_only_check: the twin without the simulator checks, compiles and refuses what needs the twin"
