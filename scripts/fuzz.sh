#!/usr/bin/env bash
# Builds the libFuzzer targets (the `fuzz` preset: clang, address + undefined sanitizers) and
# runs each for a bounded time, starting from its seed corpus in fuzz/corpus/<target>/.
#
# Usage: scripts/fuzz.sh [SECONDS] [TARGET ...]
#   SECONDS  fuzzing time per target (default 60); 0 only replays the seed corpus
#   TARGET   e.g. multipart zip (default: every fuzz/*_fuzzer.cc)
# Prints per target the executions, executions per second and whether it found anything.
# Inputs it generates go to build/fuzz/corpus/<target>/ (kept between runs, not in the repo);
# a finding is saved as build/fuzz/findings/<target>/crash-* (or leak-, timeout-, oom-) and
# makes the script exit 1. Reproduce one with: build/fuzz/fuzz/<target>_fuzzer FILE
# A fixed finding's input belongs in fuzz/corpus/<target>/ beside a regression unit test.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
shift || true
if [ $# -gt 0 ]; then
  targets=("$@")
else
  targets=()
  for f in fuzz/*_fuzzer.cc; do t=$(basename "$f" _fuzzer.cc); targets+=("$t"); done
fi

build_start=$(date +%s)
cmake --preset fuzz >/dev/null
cmake --build --preset fuzz
echo "fuzz: build took $(( $(date +%s) - build_start )) s"

status=0
summary=()
for t in "${targets[@]}"; do
  binary="build/fuzz/fuzz/${t}_fuzzer"
  work="build/fuzz/corpus/$t"
  findings="build/fuzz/findings/$t"
  log="build/fuzz/logs/$t.log"
  mkdir -p "$work" "$findings" "$(dirname "$log")"
  rm -f "$findings"/*
  # -max_total_time bounds the run; a single input over -timeout seconds or -rss_limit_mb is a
  # finding too (hangs and memory blow-ups on tiny inputs are what a client could exploit).
  rc=0
  "$binary" -max_total_time="$seconds" -runs=$([ "$seconds" = 0 ] && echo 0 || echo -1) \
    -timeout=10 -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="$findings/" "$work" "fuzz/corpus/$t" >"$log" 2>&1 || rc=$?
  runs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' || echo "?")
  rate=$(grep -oE 'exec/s: *[0-9]+' "$log" | tail -1 | grep -oE '[0-9]+$' || echo "?")
  found=$(ls "$findings" 2>/dev/null | head -5 | tr '\n' ' ')
  if [ $rc -ne 0 ] || [ -n "$found" ]; then
    result="FOUND: ${found:-exit status $rc} (log: $log)"
    status=1
    grep -m5 -E 'ERROR|fuzz check failed|runtime error|what\(\)' "$log" | sed 's/^/    /' || true
  else
    result="nothing found"
  fi
  line=$(printf '%-14s %10s runs %8s exec/s  %s' "$t" "$runs" "$rate" "$result")
  echo "fuzz: $line"
  summary+=("$line")
done
echo "fuzz: ${seconds} s per target:"
printf '  %s\n' "${summary[@]}"
exit $status
