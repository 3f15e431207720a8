#!/usr/bin/env bash
# (Re-)apply patches/series to povray/ with quilt, keeping the timestamps of files whose
# content ends up unchanged, so editing one patch rebuilds only what that edit touches.
# Usage: mk/apply-patches.sh POVDIR
set -euo pipefail
top=$(cd "$(dirname "$0")/.." && pwd)
cd "$1"
export QUILT_PATCHES="$top/patches" QUILT_PC=.pc-brdf
state=$(mktemp)
trap 'rm -f "$state"' EXIT
# Files the currently applied series touches: remember their hash and mtime, then pop.
if [ -d .pc-brdf ] && quilt applied >/dev/null 2>&1; then
  for p in $(quilt applied 2>/dev/null); do quilt files "$p"; done | sort -u | while read -r f; do
    [ -f "$f" ] && printf '%s %s %s\n' "$(sha256sum < "$f" | cut -c1-64)" "$(stat -c %Y "$f")" "$f"
  done > "$state"
  quilt pop -a -q -f >/dev/null
fi
if grep -qvE '^\s*(#|$)' "$top/patches/series"; then
  quilt push -a -q --fuzz=0 >/dev/null
fi
# Same content as before the pop: put the old timestamp back.
while read -r sum mtime f; do
  [ -f "$f" ] && [ "$(sha256sum < "$f" | cut -c1-64)" = "$sum" ] && touch -d "@$mtime" "$f"
done < "$state"
echo "patches: $(quilt applied 2>/dev/null | wc -l) applied"
