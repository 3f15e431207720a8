#!/usr/bin/env bash
# Build a separate ASan+UBSan copy of the fork: the patched tree POVDIR is copied (without
# objects) to DEST/povray, configured there with CONFIGURE ARGS... (the Makefile passes the
# fork's own configure line with the sanitizer flags added and the sanitized libshading on
# LDFLAGS) and built; the binary is DEST/povray-brdf. povray/ itself is never touched.
# Usage: mk/asan-fork.sh POVDIR DEST JOBS CONFIGURE-ARG...
set -euo pipefail
src=$1 dest=$2 jobs=$3
shift 3
tree=$dest/povray
mkdir -p "$tree"

# Refresh the copy: sources whose content changed get a new mtime (cp -p keeps the
# original's, which is newer than the object when the patched tree changed).
# configure's outputs stay the copy's own.
tar -C "$src" --exclude='*.o' --exclude='*.a' --exclude='./unix/povray' --exclude='.pc*' \
    --exclude=Makefile --exclude=config.status --exclude=config.log --exclude=config.h \
    --exclude=stamp-h1 --exclude=.deps -cf - . |
  tar -C "$tree" --keep-newer-files -xf - 2>/dev/null || true

printf '%q ' "$@" > "$dest/configure-args.tmp"
if ! cmp -s "$dest/configure-args.tmp" "$dest/configure-args" || [ ! -f "$tree/config.status" ] ||
   ! grep -q "fsanitize=address" "$tree/config.status"; then
  echo "asan-fork: configuring $tree"
  (cd "$tree" && ./configure -q "$@" >/dev/null)
  mv "$dest/configure-args.tmp" "$dest/configure-args"
else
  rm -f "$dest/configure-args.tmp"
fi
# A newer sanitized libshading.a needs a relink (automake does not track it).
lib=$(printf '%s\n' "$@" | sed -n 's/^LDFLAGS=-L\([^ ]*\).*/\1/p')/libshading.a
if [ -e "$tree/unix/povray" ] && [ -e "$lib" ] && [ "$lib" -nt "$tree/unix/povray" ]; then rm -f "$tree/unix/povray"; fi
echo "asan-fork: building $tree (log: $dest/build.log)"
make -C "$tree" -j "$jobs" >"$dest/build.log" 2>&1 || { tail -40 "$dest/build.log"; exit 1; }
cp -p "$tree/unix/povray" "$dest/povray-brdf"
echo "asan-fork: $dest/povray-brdf"
