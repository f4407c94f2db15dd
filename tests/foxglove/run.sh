#!/usr/bin/env bash
# ctest foxglove_client (tests/CMakeLists.txt): starts `twin serve SCENARIO --port 0 --realtime --speed 4 --play`,
# reads the port from its banner, runs Foxglove's client against it (client.mjs, with the node_modules of this directory's
# package-lock.json installed in NODE_DIR by the build), then stops the server with Ctrl-C's signal.
#   run.sh TWIN SCENARIO NODE_DIR NODE
set -euo pipefail
twin=$1 scenario=$2 node_dir=$3 node=$4
here=$(cd "$(dirname "$0")" && pwd)
out=$(mktemp)
trap 'kill -INT $pid 2>/dev/null || true; wait $pid 2>/dev/null || true; rm -f "$out"' EXIT
MUJOCO_GL=${MUJOCO_GL:-osmesa} "$twin" serve "$scenario" --port 0 --realtime --speed 4 --play >"$out" 2>&1 &
pid=$!
port=
for _ in $(seq 300); do
  port=$(sed -n 's|.*serving the live view on http://127\.0\.0\.1:\([0-9]*\)/.*|\1|p' "$out")
  [[ -n $port ]] && break
  kill -0 $pid 2>/dev/null || { echo "twin serve stopped:"; cat "$out"; exit 1; }
  sleep 0.1
done
[[ -n $port ]] || { echo "twin serve printed no port in 30 s:"; cat "$out"; exit 1; }
cp "$here/client.mjs" "$node_dir/client.mjs"  # next to its node_modules, where node resolves its imports
"$node" "$node_dir/client.mjs" "$port" 60
