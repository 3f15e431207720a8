#!/usr/bin/env bash
# Build POV-Ray (make -C DIR -j JOBS) with its output in LOG, and say how far it is on the
# terminal: "compiling POV-Ray: 123/154 files, 4:05 elapsed (log: build/povray-build.log)",
# rewritten in place on a terminal, a line every STEP files (and at the end) otherwise. The
# total is what `make -n` would compile (the files out of date), counted before the build.
# On failure it prints the log's last 40 lines and exits with make's status.
# Usage: mk/povray-make.sh DIR JOBS LOG [STEP]
set -euo pipefail
dir=$1 jobs=$2 log=$3 step=${4:-20}

# A compile command: the compiler with -c and a source file. automake prints each in full, on a
# line of its own that ends in "&&\" (its dependency tracking continues the command):
#   g++ -DHAVE_CONFIG_H -I. ... -MT backend/parser/parse.o -MD -MP -MF $depbase.Tpo -c -o backend/parser/parse.o backend/parser/parse.cpp &&\
compile_re='^([^#]*[ /])?(g\+\+|gcc|c\+\+|cc|clang\+\+|clang) .* -c( .*)? [^ ]+\.(cpp|cc|cxx|c)( &&\\)?$'
total=$(make -C "$dir" -n 2>/dev/null | grep -cE "$compile_re" || true)

tty=0
[ -t 2 ] && tty=1
start=$(date +%s)
: > "$log"
set +e +o pipefail
make -C "$dir" -j "$jobs" 2>&1 | tee -a "$log" | COMPILE_RE=$compile_re LOGPATH=$log \
    awk -v total="$total" -v tty="$tty" -v step="$step" -v start="$start" '
  function show(final,   now, el, msg) {
    now = systime(); el = now - start
    msg = sprintf("compiling POV-Ray: %d/%d files, %d:%02d elapsed (log: %s)", n, total, int(el / 60), el % 60,
                  ENVIRON["LOGPATH"])
    if (tty) printf "\r%-100s%s", msg, (final ? "\n" : "") > "/dev/stderr"
    else print msg > "/dev/stderr"
    fflush("/dev/stderr")
  }
  BEGIN { n = 0; re = ENVIRON["COMPILE_RE"]; if (total > 0) show(0) }
  $0 ~ re { n++; if (n > total) total = n; if (tty || n % step == 0) show(0) }
  END { if (total > 0) show(1) }
'
status=${PIPESTATUS[0]}
set -e -o pipefail
if [ "$status" -ne 0 ]; then
  echo "compiling POV-Ray failed (make exit $status); the last 40 lines of $log:" >&2
  tail -40 "$log" >&2
  exit "$status"
fi
