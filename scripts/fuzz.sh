#!/usr/bin/env bash
# Builds the libFuzzer targets (the `fuzz` preset: clang, address + undefined sanitizers) and
# runs each for a bounded time, starting from its seed corpus in fuzz/corpus/<target>/.
#
# Usage: scripts/fuzz.sh [SECONDS] [TARGET ...]
#   SECONDS  fuzzing time per target (default 60); 0 only replays the seed corpus
#   TARGET   e.g. multipart zip (default: every fuzz/*_fuzzer.cc)
# Prints per target the executions, executions per second and whether it found anything.
# Runs two targets at a time (RECONDUIT_FUZZ_JOBS=N for another number).
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

# The zip and config targets write each input to a file: in a folder of their own, in memory.
RECONDUIT_FUZZ_SCRATCH=$(mktemp -d /dev/shm/reconduit-fuzz.XXXXXX 2>/dev/null || mktemp -d)
export RECONDUIT_FUZZ_SCRATCH
trap 'rm -rf "$RECONDUIT_FUZZ_SCRATCH"' EXIT

# run_one TARGET: fuzzes one target, writes its summary line to build/fuzz/logs/TARGET.result.
run_one() {
  local t="$1" rc=0
  local binary="build/fuzz/fuzz/${t}_fuzzer" work="build/fuzz/corpus/$t"
  local findings="build/fuzz/findings/$t" log="build/fuzz/logs/$t.log"
  mkdir -p "$work" "$findings" build/fuzz/logs
  rm -f "$findings"/*
  # -max_total_time bounds the run; a single input over -timeout seconds or -rss_limit_mb is a
  # finding too (hangs and memory blow-ups on tiny inputs are what a client could exploit).
  "$binary" -max_total_time="$seconds" -runs=$([ "$seconds" = 0 ] && echo 0 || echo -1) \
    -timeout=10 -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="$findings/" "$work" "fuzz/corpus/$t" >"$log" 2>&1 || rc=$?
  local runs rate found result
  runs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' || echo "?")
  rate=$(grep -oE 'exec/s: *[0-9]+' "$log" | tail -1 | grep -oE '[0-9]+$' || echo "?")
  found=$(ls "$findings" 2>/dev/null | head -5 | tr '\n' ' ')
  if [ $rc -ne 0 ] || [ -n "$found" ]; then
    result="FOUND: ${found:-exit status $rc} (log: $log)"
  else
    result="nothing found"
  fi
  printf '%-14s %10s runs %8s exec/s  %s\n' "$t" "$runs" "$rate" "$result" \
    >"build/fuzz/logs/$t.result"
}

# Two targets at a time (RECONDUIT_FUZZ_JOBS): each libFuzzer process uses one core.
jobs="${RECONDUIT_FUZZ_JOBS:-2}"
run_start=$(date +%s)
running=0
for t in "${targets[@]}"; do
  run_one "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$jobs" ]; then wait -n; running=$((running - 1)); fi
done
wait

status=0
echo "fuzz: ${seconds} s per target, $jobs at a time, $(( $(date +%s) - run_start )) s:"
for t in "${targets[@]}"; do
  line=$(cat "build/fuzz/logs/$t.result")
  echo "  $line"
  if [[ "$line" == *FOUND* ]]; then
    status=1
    grep -m5 -E 'ERROR|fuzz check failed|runtime error|what\(\)' "build/fuzz/logs/$t.log" |
      sed 's/^/      /' || true
  fi
done
exit $status
