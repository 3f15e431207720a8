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

# Files configure writes, build outputs and quilt state stay the copy's own.
prune=( \( -name '*.o' -o -name '*.a' -o -name .deps -o -name '.pc*' -o -name Makefile -o -name config.status
        -o -name config.log -o -name config.h -o -name stamp-h1 -o -path ./unix/povray \) -prune -o )
if [ ! -f "$tree/configure" ]; then
  # First copy: everything else, times kept (nothing is built yet).
  (cd "$src" && find . "${prune[@]}" \( -type f -o -type l \) -print0) |
    tar -C "$src" --null -T - -cf - | tar -C "$tree" -xf -
else
  # Later: only what changed, by content, with a fresh time, so make rebuilds whatever
  # depends on it (a copied time can be older than objects built from the previous copy).
  (cd "$src" && find . "${prune[@]}" \( -type f -o -type l \) -print0) |
    while IFS= read -r -d '' f; do
      if [ -L "$src/$f" ]; then
        [ "$(readlink "$src/$f")" = "$(readlink "$tree/$f" 2>/dev/null)" ] || { mkdir -p "$(dirname "$tree/$f")"; cp -Pf "$src/$f" "$tree/$f"; }
      elif ! cmp -s "$src/$f" "$tree/$f"; then
        mkdir -p "$(dirname "$tree/$f")"
        rm -f "$tree/$f"
        cp "$src/$f" "$tree/$f"
      fi
    done
fi

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
