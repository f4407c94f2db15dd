#!/bin/sh
# Runs one libFuzzer harness of tests/fuzz (docs/CONTRIBUTING.md, "Fuzzing the readers").
#   tests/fuzz/run.sh BUILD_DIR READER [SECONDS]      e.g. tests/fuzz/run.sh build-fuzz task 600
# The corpus grows in BUILD_DIR/tests/fuzz/READER_corpus (the seeds are read from READER_seeds); a crash, a hang
# (one input over 10 s) or a leak is written as BUILD_DIR/tests/fuzz/READER-crash-* (or -timeout-, -leak-, -oom-).
# Reproduce one with BUILD_DIR/tests/fuzz/READER_fuzz FILE. The log is BUILD_DIR/tests/fuzz/READER.log.
set -eu
build=$1 reader=$2 seconds=${3:-600}
dir=$build/tests/fuzz
mkdir -p "$dir/${reader}_corpus"
cd "$dir"
exec nice -n 10 "./${reader}_fuzz" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
  -artifact_prefix="${reader}-" "${reader}_corpus" "${reader}_seeds" >"${reader}.log" 2>&1
