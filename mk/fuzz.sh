#!/usr/bin/env bash
# Run each libFuzzer target for SECONDS, starting from the committed seeds, and summarise.
# Usage: mk/fuzz.sh FUZZ_BUILD SEED_DIR SECONDS TARGET...   (TARGET foo_fuzz or foo_header_fuzz reads SEED_DIR/foo)
# New inputs go to FUZZ_BUILD/corpus/foo (kept between runs), crash/leak/timeout/oom inputs
# to FUZZ_BUILD/artifacts/, logs to FUZZ_BUILD/logs/. Exit status 1 if any target failed.
set -uo pipefail
build=$1 seeds=$2 seconds=$3
shift 3
mkdir -p "$build/artifacts" "$build/logs"
status=0 total=0
printf '%-12s %12s %8s %8s %s\n' target executions crashes leaks result
for t in "$@"; do
  name=${t%_fuzz}; name=${name%_header}
  work=$build/corpus/$name log=$build/logs/$t.log
  mkdir -p "$work"
  rm -f "$build/artifacts/$t"-*
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 UBSAN_OPTIONS=print_stacktrace=1 \
    "$build/$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=16384 \
      -print_final_stats=1 -artifact_prefix="$build/artifacts/$t-" "$work" "$seeds/$name" >"$log" 2>&1
  rc=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  crashes=$(find "$build/artifacts" -name "$t-crash-*" -o -name "$t-timeout-*" -o -name "$t-oom-*" | wc -l)
  leaks=$(find "$build/artifacts" -name "$t-leak-*" | wc -l)
  result=ok
  if [ "$rc" != 0 ] || [ "$crashes" != 0 ] || [ "$leaks" != 0 ]; then
    result="FAILED (exit $rc; see $log)"
    status=1
    grep -m3 -E '^(==[0-9]+==ERROR|SUMMARY|.*runtime error)' "$log" || true
  fi
  printf '%-12s %12s %8s %8s %s\n' "$t" "${execs:-?}" "$crashes" "$leaks" "$result"
  total=$((total + ${execs:-0}))
done
echo "fuzz: $total executions in all"
exit $status
