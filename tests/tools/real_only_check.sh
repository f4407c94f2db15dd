#!/usr/bin/env bash
# Checks a `twin` built without the simulator (-DCW_SIM=OFF) as a user of a cell of real robots would run it: it links
# no MuJoCo, OSMesa or Assimp; it checks, compiles and analyses programs; the commands that need the twin are refused
# with exit 2 and an error that says why; and it runs the exchange on two controllers (its own `twin emulate`, over
# real pseudo-terminals, 4 times faster than real time) with no twin: the report names the robots and their drivers
# and says that the parts' places are the controller's model's; a controller that stops answering mid-run stops the
# cell (exit 1), the fault in the report. Run by .ci/run: bash tests/tools/real_only_check.sh BUILD_DIR
set -euo pipefail
build=${1:?usage: real_only_check.sh BUILD_DIR}
twin=$build/tools/twin
scratch=$(mktemp -d)
emulators=()  # the pids of the emulators this script started
stop_emulators() {
  local pid
  for pid in "${emulators[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${emulators[@]}"; do wait "$pid" 2>/dev/null || true; done
  emulators=()
}
trap 'stop_emulators; rm -rf "$scratch"' EXIT
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
expect 2 "give it one with --driver puma=movemaster:PORT" -- "$twin" run scenes/exchange.yaml
expect 2 "needs the simulator" -- "$twin" snapshot scenes/cell.yaml -o "$scratch/cell.png"
expect 2 "needs the simulator" -- "$twin" campaign scenes/exchange.yaml -o "$scratch/c"
expect 2 "needs the simulator" -- "$twin" emulate --scenario scenes/exchange.yaml --robot "melfa=movemaster:$scratch/m"
[[ ! -e $scratch/c && ! -e $scratch/cell.png ]] || fail "a refused command wrote something"
# Refused before anything connects (the ports do not exist): a feed, which nothing real sees arrive, and --speed above
# 1 with a real arm (a port that is not a pseudo-terminal).
expect 2 "the feed is the twin putting parts on conveyor 'input'" -- "$twin" run scenes/pipeline.yaml \
  --driver "puma=val2:$scratch/none" --driver "melfa=movemaster:$scratch/none"
expect 2 "robot 'puma' is a real arm" -- "$twin" run scenes/exchange.yaml --speed 4 \
  --driver "puma=val2:$scratch/none" --driver "melfa=movemaster:$scratch/none"

# emulate NAME LANGUAGE: a controller of the build's own on the pseudo-terminal $scratch/NAME, its arm 4 times faster
# than real time, its home the cell's (the bring-up cross-checks it); waits until it is published.
emulate() {
  local name=$1 language=$2 home
  home=$([[ $name == puma ]] && echo 0,84,-192,0,-72,90 || echo -90,30,60,0,60,0)
  rm -f "$scratch/$name.log"
  "$twin" emulate "$language" --link "$scratch/$name" --time-scale 0.25 --home "$home" >"$scratch/$name.log" 2>&1 &
  emulators+=($!)
  for _ in $(seq 100); do
    grep -q "Ctrl-C to stop" "$scratch/$name.log" 2>/dev/null && return 0
    sleep 0.1
  done
  fail "the $language emulator did not come up: $(cat "$scratch/$name.log")"
}
# The exchange with A already at the input conveyor's stop bar: a run without the twin has no part sensor (the stop's
# photo-eye is not read yet), so its controller cannot know when a part riding a belt arrives.
mkdir "$scratch/scene"
sed -e "s#\.\./models/#$PWD/models/#" \
    -e 's#^\(  - {name: A, .*\), on: input}#\1, pose: {xyz: [0.03, -0.55, 0.53], yaw: 0}}#' scenes/cell.yaml \
    >"$scratch/scene/cell.yaml"
grep -q "name: A, .*pose:" "$scratch/scene/cell.yaml" || fail "A was not put at the stop in the test's cell"
cp scenes/exchange.yaml scenes/exchange.task "$scratch/scene/"
real_run=(run "$scratch/scene/exchange.yaml" --quiet --speed 4 --driver "puma=val2:$scratch/puma"
          --driver "melfa=movemaster:$scratch/melfa")

# The exchange on the two controllers, no twin: A handed over and placed, by the controller's account.
emulate puma val2
emulate melfa movemaster
expect 0 "parts: where the controller's model (no twin" -- "$twin" "${real_run[@]}" -o "$scratch/real"
report=$scratch/real/report.json
for f in events.jsonl report.json gantt.png index.html; do [[ -s $scratch/real/$f ]] || fail "no $f in -o DIR"; done
[[ ! -e $scratch/real/final.png ]] || fail "a run without the twin wrote a final picture"
jq -e '.outcome == "finished" and .parts_from == "controller_model"' "$report" >/dev/null ||
  fail "the report does not say the run finished with the parts from the controller's model: $(cat "$report")"
jq -e '[.robots[].cell] == ["puma", "melfa"]' "$report" >/dev/null || fail "the report's robots: $(jq .robots "$report")"
jq -e '[.drivers[] | "\(.robot) \(.kind) \(.emulated)"] == ["puma val2 true", "melfa movemaster true"]' \
  "$report" >/dev/null || fail "the report's drivers: $(jq .drivers "$report")"
jq -e '[.account[] | select(.workpiece == "A")][0] | .status == "in_place" and .where == "output"' "$report" \
  >/dev/null || fail "A is not at the output by the controller's model: $(jq .account "$report")"
grep -qF "melfa emulated movemaster on $scratch/melfa" "$scratch/real/index.html" || fail "the page names no drivers"
grep -qF "where the controller&#39;s model" "$scratch/real/index.html" ||
  grep -qF "where the controller's model" "$scratch/real/index.html" || fail "the page does not say where parts come from"
stop_emulators

# A controller that stops answering mid-run: the MELFA's emulator is killed once the MELFA has begun (its first
# command ended, in the log streamed as the run goes), while the PUMA carries A to the hand-over.
emulate puma val2
emulate melfa movemaster
rc=0
"$twin" "${real_run[@]}" -o "$scratch/cut" >"$scratch/cut.out" 2>&1 &
run_pid=$!
for _ in $(seq 300); do
  grep -q '"type":"command_end","robot":"r2"' "$scratch/cut/events.jsonl.part" 2>/dev/null && break
  sleep 0.1
done
kill "${emulators[1]}"
wait "$run_pid" || rc=$?
[[ $rc == 1 ]] || fail "a run whose controller stopped answering exited $rc, not 1: $(cat "$scratch/cut.out")"
cut=$scratch/cut/report.json
jq -e '.outcome == "stopped" and .parts_from == "controller_model"' "$cut" >/dev/null ||
  fail "the cell was not stopped: $(cat "$scratch/cut.out")"
jq -e '.unexplained_faults[0] | .robot == "r2" and (.symptom | test("link_lost|driver_timeout|driver_fault"))' \
  "$cut" >/dev/null || fail "the report does not name the MELFA's driver fault: $(jq .unexplained_faults "$cut")"
jq -e '[.account[] | select(.workpiece == "A")][0].status != "in_place" and .parts_completed == 0' "$cut" \
  >/dev/null || fail "A is claimed done after the MELFA's controller went: $(jq .account "$cut")"
grep -qF "unexplained fault at t = " "$scratch/cut.out" || fail "the summary names no fault: $(cat "$scratch/cut.out")"
stop_emulators
echo "real_only_check: the twin without the simulator checks, compiles, refuses what needs the twin and runs real robots"
