#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine (run as root): install what is missing, build, then run the demo or
# the test suite. The README's two set-up commands call this script; so does .ci/run.
#
#   bash tools/bootstrap.sh demo   # install, build, run scenes/exchange.yaml headless (outputs in out/exchange)
#   bash tools/bootstrap.sh test   # install, build, run every test (ctest)
#
# Environment: BUILD_DIR (default build), CW_SANITIZE ('' | 'address,undefined' | 'thread'), JOBS (default nproc).
set -euo pipefail
cd "$(dirname "$0")/.."

mode=${1:-}
case "$mode" in demo|test|build) ;; *) echo "usage: $0 demo|test|build" >&2; exit 2 ;; esac

# lld: the linker CMakeLists.txt picks when it is there (links in a quarter of GNU ld's time).
# ccache: several build directories (CI's sanitizer legs and the build without the simulator, people working side by
# side) compile the same files; CMake uses it when it is there.
# libqhull-dev: MuJoCo's CMake config names /usr/include/libqhull_r, and CMake refuses to generate without it.
# libfastrtps-dev, libfastcdr-dev: Fast DDS 2.9 for robot agents in other processes (distributed/, docs/distributed.md);
# 3.1 MB to download, 18 MB installed. Its code generator (fastddsgen) is not needed: the messages are encoded by hand.
# libwebsocketpp-dev, libasio-dev: the live view's HTTP + WebSocket server (serve/, docs/live-view.md), header-only.
# nodejs, npm: the build fetches the live view's 3D page's three.js and urdf-loader with `npm ci` (serve/page/), in
# both modes (the page is part of the build). A machine whose node already brings npm (NodeSource's) keeps it.
packages=(
  build-essential cmake ninja-build pkg-config git ccache lld
  libmujoco-dev libqhull-dev libeigen3-dev libopencv-dev libosmesa6-dev liburdfdom-dev libyaml-cpp-dev libtinyxml2-dev libpng-dev
  libgtest-dev libgmock-dev libbenchmark-dev libfmt-dev libcli11-dev nlohmann-json3-dev graphviz libglpk-dev
  libassimp-dev ffmpeg libavcodec-dev libavformat-dev libswscale-dev libavutil-dev libmodbus-dev
  libfastrtps-dev libfastcdr-dev libwebsocketpp-dev libasio-dev
)
# chromium: the report page opened in a browser (tests/tools), and the live view's page driven in one
# (tests/browser). python3-pymodbus (and the serial modules its server imports, which Debian lists only as
# recommended): a Modbus TCP server and client the team did not write, which the I/O driver and the twin's I/O server
# are tested against over loopback.
command -v npm >/dev/null || packages+=(nodejs npm)
if [[ $mode == test ]]; then packages+=(chromium python3-pymodbus python3-serial python3-serial-asyncio); fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "installing: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

build=${BUILD_DIR:-build}
jobs=${JOBS:-$(nproc)}
# Ninja schedules the whole build as one graph (Make waits at each library's boundary). CMake reads CMAKE_GENERATOR
# only for a new build directory, so a directory configured with Make before keeps working.
export CMAKE_GENERATOR=${CMAKE_GENERATOR:-Ninja}
# Optimised, with line tables only (-g1): backtraces, sanitizer reports and gdb's `bt` keep their file:line, and the
# build takes about a quarter less time than with -g (one core: cell/sim/src/run.cpp 15.3 s against 19.1 s,
# tests/twin/sim/world_test.cpp 9.5 s against 13.8 s). For a debugger that shows variables, configure a build of your
# own with -DCMAKE_BUILD_TYPE=RelWithDebInfo or Debug (docs/CONTRIBUTING.md).
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
  -DCW_SANITIZE="${CW_SANITIZE:-}"
cmake --build "$build" -j "$jobs"

# Rendering is headless everywhere: MuJoCo and our renderer use OSMesa, never a display.
export MUJOCO_GL=osmesa

case "$mode" in
  build) ;;
  demo)
    # The paper's Table 1: check the program, draw the cell headless, then run it on the simulated cell; the demo
    # fails unless the workpiece ends where the scenario expects it (twin run's exit status).
    mkdir -p out
    "$build"/tools/twin check scenes/exchange.task
    "$build"/tools/twin snapshot scenes/cell.yaml -o out/cell.png
    "$build"/tools/twin run scenes/exchange.yaml -o out/exchange
    ;;
  test)
    ctest --test-dir "$build" --output-on-failure -j "$jobs"
    ;;
esac
