#!/usr/bin/env bash
# Generate the ready tables listed in brdf_data/materials.txt into OUTDIR with brdftool.
# A table is rebuilt when it is missing or older than the list or the tool.
# Usage: mk/brdf-data.sh BRDFTOOL LIST OUTDIR
set -euo pipefail
tool=$1 list=$2 out=$3
mkdir -p "$out"
lineno=0
while IFS= read -r line || [ -n "$line" ]; do
  lineno=$((lineno + 1))
  case "$line" in ''|'#'*) continue ;; esac
  name=${line%%$'\t'*}
  args=${line#*$'\t'}
  if [ "$name" = "$line" ] || [ -z "$name" ]; then
    echo "$list:$lineno: expected NAME<TAB>ARGUMENTS" >&2; exit 1
  fi
  dst="$out/$name.brdf"
  if [ -f "$dst" ] && [ "$dst" -nt "$list" ] && [ "$dst" -nt "$tool" ]; then continue; fi
  # The arguments are ours (a committed file), quoted for the shell.
  eval "set -- $args"
  "$tool" "$@" -o "$dst.tmp"
  mv "$dst.tmp" "$dst"
  echo "brdf-data: $dst"
done < "$list"
