#!/usr/bin/env bash
# Build an exact-profile table file (`sstool build --if-stale`) through a cache that this
# machine's clones share, so a fresh clone does not rerun minutes of Monte Carlo that an
# identical generator already ran.
#
# Usage: mk/ss-tables.sh SSTOOL CACHE_DIR OUT [sstool build options...]
#   CACHE_DIR empty: no cache (plain `sstool build --if-stale`).
#
# The key is the sha256 of the sstool program (code and data) and of the options. The build is
# deterministic (fixed Monte Carlo chunks and seeds, independent of --threads, which is left out
# of the key) and the code and data do not depend on the clone's path (-ffile-prefix-map), so
# one key means one file. A cached
# file is copied in (temporary name, then rename) and then checked whole by `sstool build
# --if-stale` itself: the loader verifies the checksum over every byte and the structure, and
# the generator version and settings must match, or it is rebuilt. Only a file this run built
# is stored, whole (temporary name, then rename); the newest 8 entries are kept.
set -euo pipefail
sstool=$1 cache=$2 out=$3
shift 3
args=("$@")

stamp() { stat -c '%i %s %Y' "$1" 2>/dev/null || echo none; }

mkdir -p "$(dirname "$out")"
key=
if [ -n "$cache" ]; then
  key_args=()
  skip=0
  for a in "${args[@]}"; do
    if [ "$skip" = 1 ]; then skip=0; continue; fi
    if [ "$a" = --threads ]; then skip=1; continue; fi
    key_args+=("$a")
  done
  # The program without its debug sections and build id: GCC records its switches in the debug
  # information (-ffile-prefix-map names the tree), and the build id hashes that in; the code
  # and data, which alone decide the tables, are the same from any clone.
  prog=$(mktemp)
  trap 'rm -f "$prog"' EXIT
  objcopy --strip-debug --remove-section=.note.gnu.build-id "$sstool" "$prog"
  key=$( { sha256sum < "$prog"; printf '%s\n' "${key_args[@]}"; } | sha256sum | cut -c1-32)
  entry=$cache/$(basename "$out" .ssp)-$key.ssp
  if [ -f "$entry" ] && ! cmp -s "$entry" "$out"; then
    cp "$entry" "$out.cache.$$" && mv -f "$out.cache.$$" "$out"
    echo "ss-tables: $out from the cache ($entry); checking it" >&2
  fi
fi

before=$(stamp "$out")
"$sstool" build --if-stale "${args[@]}" -o "$out"
after=$(stamp "$out")

# Storing is best effort: a cache that cannot be written costs the next clone a rebuild, no more.
if [ -n "$key" ] && [ "$after" != "$before" ]; then
  if mkdir -p "$cache" 2>/dev/null && cp "$out" "$entry.tmp.$$" 2>/dev/null && mv -f "$entry.tmp.$$" "$entry"; then
    # Keep the newest 8 entries (each a few MB).
    ls -1t "$cache"/*.ssp 2>/dev/null | tail -n +9 | xargs -r rm -f
  else
    rm -f "$entry.tmp.$$"
    echo "ss-tables: warning: could not store $out in the cache $cache (the build is not affected)" >&2
  fi
fi
