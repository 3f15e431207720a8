#!/usr/bin/env bash
# Remove what mk/install.sh put under PREFIX, as listed in its install-manifest.txt, then
# the directories it leaves empty. Usage: mk/uninstall.sh PREFIX [DESTDIR]
set -euo pipefail
prefix=$1
destdir=${2:-}
case $prefix in /*) ;; *) prefix=$(realpath -m "$prefix") ;; esac
prefix=${prefix%/}
manifest=$destdir$prefix/share/povray-brdf/install-manifest.txt
[ -f "$manifest" ] || { echo "uninstall: no $manifest (nothing installed there by make install)" >&2; exit 1; }
n=0
while IFS= read -r f; do
  case $f in "$prefix"/*) ;; *) echo "uninstall: skipping $f (outside $prefix)" >&2; continue ;; esac
  if [ -e "$destdir$f" ] || [ -L "$destdir$f" ]; then rm -f "$destdir$f"; n=$((n + 1)); fi
done < <(grep -v 'install-manifest.txt$' "$manifest")
rm -f "$manifest"
for d in share/povray-brdf etc/povray-brdf bin etc share; do
  [ -d "$destdir$prefix/$d" ] && find "$destdir$prefix/$d" -depth -type d -empty -delete
done
echo "uninstall: removed $n files from $destdir$prefix"
