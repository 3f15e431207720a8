#!/usr/bin/env bash
# Render the fast harness scenes with the ASan+UBSan build of the fork and summarise what the
# sanitizers reported. Usage: mk/sanitize-fork.sh ASAN_BIN PYTHON REPORT_DIR [PYTEST_ARGS...]
#
# The harness runs REPORT_DIR/povray-brdf, a wrapper that keeps a POV-Ray process's stderr as
# REPORT_DIR/stderr.PID when it holds a sanitizer report (the sanitizers' own log_path files
# lose UBSan's reports when ASan and UBSan run together). ASan errors and leaks fail the
# render, so the test that ran it fails too; UBSan reports in POV-Ray's own code are
# recoverable and only collected. Leaks at exit are checked (detect_leaks=1); mk/lsan-pov.supp
# suppresses upstream POV-Ray's own leaks and names only upstream functions. ASAN_EXTRA adds
# ASan options (e.g. ASAN_EXTRA=new_delete_type_mismatch=0).
# Exit status 1 on a failed test, an ASan error, a leak, or any report naming the shading library.
set -uo pipefail
bin=$1 py=$2 reports=$3
shift 3
top=$(pwd)
rm -rf "$reports"
mkdir -p "$reports"
tests=(tests/test_brdf_finish.py tests/test_analytic_finishes.py tests/test_determinism.py
       tests/test_scene_errors.py tests/test_io_restrictions.py)

cat > "$reports/povray-brdf" <<WRAPPER
#!/usr/bin/env bash
err=\$(mktemp)
"$top/$bin" "\$@" 2>"\$err"
rc=\$?
cat "\$err" >&2
if grep -qE 'Sanitizer|runtime error:' "\$err"; then mv "\$err" "$top/$reports/stderr.\$\$"; else rm -f "\$err"; fi
exit \$rc
WRAPPER
chmod +x "$reports/povray-brdf"

export POVRAY_BRDF=$top/$reports/povray-brdf
export ASAN_OPTIONS="detect_leaks=1:fast_unwind_on_malloc=0:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1${ASAN_EXTRA:+:$ASAN_EXTRA}"
export LSAN_OPTIONS="suppressions=$top/mk/lsan-pov.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1"
echo "sanitize-fork: $bin on ${tests[*]}"
"$py" -m pytest -q -p no:cacheprovider "${tests[@]}" "$@"
rc=$?

# Reports, by kind; a report whose stack names the shading library is ours.
shopt -s nullglob
files=("$reports"/stderr.*)
# POV-Ray's parser drops the object it was building when a parse error is thrown (the
# object, its textures, pigment and finish leak: stock syntax errors do the same), so a leak
# in a process that ended in a parse error is counted apart, as long as no stack in it runs
# through the shading library.
asan=0 leaks=0 parse_leaks=0 ubsan=0 ours=0
for f in "${files[@]}"; do
  grep -q 'ERROR: AddressSanitizer' "$f" && asan=$((asan + 1))
  if grep -q 'ERROR: LeakSanitizer' "$f"; then
    if grep -qE 'Parse Error|Fatal error in parser' "$f" && ! grep -qE 'shading::|/shading/src/' "$f"; then
      parse_leaks=$((parse_leaks + 1))
    else
      leaks=$((leaks + 1))
    fi
  fi
  n=$(grep -c 'runtime error:' "$f"); ubsan=$((ubsan + n))
  grep -qE 'shading::|/shading/src/' "$f" && ours=$((ours + 1))
done
echo "sanitize-fork: ${#files[@]} processes reported: $asan with ASan errors, $leaks with leaks," \
     "$parse_leaks with upstream parse-error leaks, $ubsan UBSan runtime errors;" \
     "$ours reports name the shading library (in $reports)"
if [ "$ubsan" -gt 0 ]; then
  echo "sanitize-fork: UBSan findings (count, where):"
  grep -h 'runtime error:' "${files[@]}" | sed -E 's/: runtime error: (.{0,60}).*/: \1/' | sort | uniq -c | sort -rn | head -20
fi
if [ "$rc" != 0 ] || [ "$asan" -gt 0 ] || [ "$leaks" -gt 0 ] || [ "$ours" -gt 0 ]; then
  exit 1
fi
