#!/usr/bin/env bash
# Install, through apt, what building and testing the fork needs; do nothing if it is all there.
# Usage: mk/deps.sh PACKAGE... (POV-Ray's own build dependencies come from `apt-get build-dep povray`).
# Needs root only when something is missing. Never touches anything outside apt's own state.
set -euo pipefail

have_deb_src() { grep -rqsE '^(Types:.*deb-src|deb-src )' /etc/apt/sources.list /etc/apt/sources.list.d/; }
as_root() {
  if [ "$(id -u)" != 0 ]; then
    echo "deps: missing: $*; run 'make deps' as root once (it uses apt-get)" >&2
    exit 1
  fi
}

missing=()
for p in "$@"; do
  dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q '^install ok installed' || missing+=("$p")
done

if ! have_deb_src; then
  as_root "a deb-src entry for apt"
  # Derive a source entry from the machine's own binary entry: same hosts, same suites.
  if [ -f /etc/apt/sources.list.d/debian.sources ]; then
    sed 's/^Types: deb$/Types: deb-src/' /etc/apt/sources.list.d/debian.sources > /etc/apt/sources.list.d/povray-brdf-src.sources
  elif [ -f /etc/apt/sources.list ]; then
    sed -n 's/^deb /deb-src /p' /etc/apt/sources.list > /etc/apt/sources.list.d/povray-brdf-src.list
  else
    echo "deps: no apt source list found to derive a deb-src entry from" >&2; exit 1
  fi
  apt-get update -q
elif ! apt-get source --print-uris povray=1:3.7.0.10-2 >/dev/null 2>&1; then
  as_root "apt source lists (apt-get update)"
  apt-get update -q
fi

builddep=$(apt-get -s build-dep povray 2>/dev/null | grep -c '^Inst ' || true)
if [ "${#missing[@]}" -gt 0 ] || [ "$builddep" -gt 0 ]; then
  as_root "${missing[*]} ${builddep} build dependencies of povray"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -q
  apt-get build-dep -y -q povray
  [ "${#missing[@]}" -eq 0 ] || apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
echo "deps: all present"
