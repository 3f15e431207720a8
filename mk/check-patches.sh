#!/usr/bin/env bash
# Apply patches/series to a pristine unpack of the Debian source; fail on fuzz, offsets or rejects.
# Usage: mk/check-patches.sh path/to/povray_3.7.0.10-2.dsc
set -euo pipefail
top=$(cd "$(dirname "$0")/.." && pwd)
dsc=$(readlink -f "$1")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
dpkg-source --no-check --no-copy -x "$dsc" "$tmp/povray" >/dev/null
cd "$tmp/povray"
export QUILT_PATCHES="$top/patches" QUILT_PC=.pc-brdf
n=0; bad=0
while read -r p _; do
  case "$p" in ''|'#'*) continue ;; esac
  n=$((n + 1))
  if ! out=$(quilt push --fuzz=0 2>&1); then
    echo "FAIL $p: does not apply"; echo "$out" | sed 's/^/    /'; bad=$((bad + 1)); break
  fi
  if echo "$out" | grep -qiE 'offset|fuzz'; then
    echo "FAIL $p: applies only with offset/fuzz"; echo "$out" | grep -iE 'offset|fuzz' | sed 's/^/    /'; bad=$((bad + 1))
  else
    echo "ok   $p"
  fi
done < "$top/patches/series"
echo "check-patches: $n patches, $bad with fuzz, offset or reject"
[ "$bad" -eq 0 ]
