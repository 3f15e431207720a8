#!/usr/bin/env bash
# Render the fast harness scenes with the ASan+UBSan build of the fork and summarise what the
# sanitizers reported. Usage: mk/sanitize-fork.sh ASAN_BIN PYTHON REPORT_DIR [PYTEST_ARGS...]
#
# Every POV-Ray process writes its reports to REPORT_DIR/{asan,ubsan}.PID (ASan errors and
# leaks abort the render, so the test that ran it fails too; UBSan reports in POV-Ray's own
# code are recoverable and only collected). Leaks at exit are checked (detect_leaks=1);
# mk/lsan-pov.supp suppresses upstream POV-Ray's own exit-time leaks and names only upstream
# functions. Exit status 1 on a failed test or on any report that is not suppressed.
set -uo pipefail
bin=$1 py=$2 reports=$3
shift 3
top=$(pwd)
rm -rf "$reports"
mkdir -p "$reports"
tests=(tests/test_brdf_finish.py tests/test_analytic_finishes.py tests/test_determinism.py
       tests/test_scene_errors.py tests/test_io_restrictions.py)

export POVRAY_BRDF=$top/$bin
export ASAN_OPTIONS="detect_leaks=1:log_path=$top/$reports/asan:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1"
export LSAN_OPTIONS="suppressions=$top/mk/lsan-pov.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:log_path=$top/$reports/ubsan"
echo "sanitize-fork: $bin on ${tests[*]}"
"$py" -m pytest -q -p no:cacheprovider "${tests[@]}" "$@"
rc=$?

# Reports, by kind; a report whose stack names the shading library is ours.
shopt -s nullglob
files=("$reports"/asan.* "$reports"/ubsan.*)
asan=0 leaks=0 ubsan=0 ours=0
for f in "${files[@]}"; do
  grep -q 'ERROR: AddressSanitizer' "$f" && asan=$((asan + 1))
  grep -q 'ERROR: LeakSanitizer' "$f" && leaks=$((leaks + 1))
  n=$(grep -c 'runtime error:' "$f"); ubsan=$((ubsan + n))
  grep -qE 'shading::|/shading/src/' "$f" && ours=$((ours + 1))
done
echo "sanitize-fork: ${#files[@]} report files: $asan ASan errors, $leaks leak reports, $ubsan UBSan runtime errors, $ours naming the shading library (in $reports)"
if [ "$ubsan" -gt 0 ]; then
  echo "sanitize-fork: UBSan findings (unique):"
  grep -h 'runtime error:' "${files[@]}" | sed -E 's/^[^ ]*\/povray\///' | sort | uniq -c | sort -rn | head -20
fi
if [ "$rc" != 0 ] || [ "$asan" -gt 0 ] || [ "$leaks" -gt 0 ] || [ "$ours" -gt 0 ]; then
  exit 1
fi
