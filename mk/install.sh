#!/usr/bin/env bash
# Install the built fork into PREFIX: `make install PREFIX=/opt/povray-brdf [DESTDIR=/stage]`.
# Usage: mk/install.sh TOP PREFIX [DESTDIR]
#
#   PREFIX/bin/povray-brdf                the fork (never named `povray`: stock stays stock)
#   PREFIX/bin/brdftool                   tabulate, convert, fit, plot ... BRDF tables
#   PREFIX/bin/sstool                     build, inspect, evaluate the exact subsurface profile tables
#   PREFIX/etc/povray-brdf/povray.conf    I/O restrictions for the installed layout
#   PREFIX/etc/povray-brdf/povray.ini     library paths: the two directories below
#   PREFIX/share/povray-brdf/include      POV-Ray 3.7.0.10's standard include files and ours
#   PREFIX/share/povray-brdf/brdf_data    the ready tables of `make brdf-data` (.brdf, and the exact
#                                         subsurface profiles subsurface_profiles.ssp and the slab
#                                         tables of thin geometry subsurface_slabs.ssp and of
#                                         forward-scattering media subsurface_slabs_forward.ssp)
#   PREFIX/share/povray-brdf/doc          README, docs/, shading/MODELS.md, DIPOLE.md, brdf_data/README.md
#   PREFIX/share/man/man1                 povray-brdf.1.gz, brdftool.1.gz, sstool.1.gz (from docs/man/)
#   PREFIX/share/povray-brdf/install-manifest.txt   every installed file (`make uninstall`)
#
# POV-Ray compiles its configuration directory into the binary (POVCONFDIR, from configure's
# --sysconfdir: build/conf/povray/3.7 for the in-tree fork). So that the installed binary
# reads PREFIX/etc/povray-brdf and not the build tree, this script recompiles the one file
# that uses it (vfe/unix/unixoptions.cpp, with the build's own flags and POVCONFDIR changed)
# and relinks the fork from the build's objects in a temporary directory; povray/ and build/
# are not modified. DESTDIR stages the files elsewhere (packaging) with PREFIX compiled in.
set -euo pipefail

top=$(cd "$1" && pwd)
prefix=$2
destdir=${3:-}
die() { echo "install: $*" >&2; exit 1; }

[ -n "$prefix" ] || die "PREFIX is empty"
case $prefix in /*) ;; *) prefix=$(realpath -m "$prefix") ;; esac
prefix=${prefix%/}
# The path is compiled into a C string and a shell command line: keep it plain.
[[ $prefix =~ ^/[A-Za-z0-9_./+-]*$ ]] || die "PREFIX '$prefix': use letters, digits and _ . / + - only"

povdir=$top/povray
bin_src=$top/build/bin/povray-brdf
tool_src=$top/build/shading/brdftool
for f in "$bin_src" "$tool_src" "$povdir/vfe/libvfe.a" "$povdir/source/libpovray.a" \
         "$povdir/vfe/Makefile" "$povdir/unix/Makefile" "$top/build/shading/libshading.a"; do
  [ -e "$f" ] || die "$f is missing: build the fork first (make)"
done
# The relink below compiles today's unixoptions.cpp against the objects of the last build:
# they must be of the same tree (what `make install` ensures by building `all` first).
for f in "$povdir/vfe/unix/unixoptions.cpp" "$povdir/vfe/libvfe.a" "$povdir/source/libpovray.a" \
         "$top/build/shading/libshading.a"; do
  if [ "$f" -nt "$bin_src" ]; then die "the fork's build is out of date ($f is newer than build/bin/povray-brdf): run make"; fi
done
shopt -s nullglob
tables=("$top"/build/brdf_data/*.brdf "$top"/build/brdf_data/*.ssp)
[ ${#tables[@]} -gt 0 ] || die "no tables in build/brdf_data: run make brdf-data"

etc=$prefix/etc/povray-brdf
share=$prefix/share/povray-brdf
bindir=$prefix/bin
D=$destdir

tmp=$(mktemp -d)
trap '[ -n "${KEEP_TMP:-}" ] || rm -rf "$tmp"' EXIT

# ---------------------------------------------------------------- relink with PREFIX's conf dir
# The compile and link lines come from POV's own automake Makefiles (print the variables).
printvar() {  # DIR EXPR: the expansion of a make expression in POV's Makefile of DIR
  printf 'print-it:\n\t@echo '"'"'%s'"'"'\n' "$2" | make -s --no-print-directory -C "$1" -f Makefile -f - print-it
}
compile=$(printvar "$povdir/vfe" '$(CXXCOMPILE)')
for var in POVCONFDIR POVCONFDIR_BACKWARD POVLIBDIR; do
  grep -q -- "-D$var=" <<<"$compile" || die "no -D$var in POV's compile line (vfe/Makefile changed?)"
done
compile=$(sed -e "s|-DPOVCONFDIR=\\\\\"[^\"]*\\\\\"|-DPOVCONFDIR=\\\\\"$etc\\\\\"|" \
              -e "s|-DPOVCONFDIR_BACKWARD=\\\\\"[^\"]*\\\\\"|-DPOVCONFDIR_BACKWARD=\\\\\"$etc\\\\\"|" \
              -e "s|-DPOVLIBDIR=\\\\\"[^\"]*\\\\\"|-DPOVLIBDIR=\\\\\"$share\\\\\"|" <<<"$compile")
grep -q -- "-DPOVCONFDIR=\\\\\"$etc\\\\\"" <<<"$compile" || die "could not set POVCONFDIR in: $compile"
echo "install: compiling vfe/unix/unixoptions.cpp with POVCONFDIR=$etc"
(cd "$povdir/vfe" && eval "$compile -c unix/unixoptions.cpp -o $tmp/unixoptions.o") >"$tmp/compile.log" 2>&1 \
  || { cat "$tmp/compile.log" >&2; die "compiling unixoptions.cpp failed"; }

cp "$povdir/vfe/libvfe.a" "$tmp/libvfe.a"
ar t "$tmp/libvfe.a" | grep -x unixoptions.o >/dev/null || die "libvfe.a has no unixoptions.o member"
ar r "$tmp/libvfe.a" "$tmp/unixoptions.o" 2>/dev/null

linkpre=$(printvar "$povdir/unix" '$(CXXLD) $(AM_CXXFLAGS) $(CXXFLAGS) $(AM_LDFLAGS) $(LDFLAGS)')
objects=$(printvar "$povdir/unix" '$(povray_OBJECTS)')
ldadd=$(printvar "$povdir/unix" '$(povray_LDADD)')
libs=$(printvar "$povdir/unix" '$(LIBS)')
ldadd=$(sed "s|[^ ]*/vfe/libvfe\.a|$tmp/libvfe.a|" <<<"$ldadd")
grep -q "$tmp/libvfe.a" <<<"$ldadd" || die "no libvfe.a in POV's link line: $ldadd"
echo "install: linking povray-brdf"
(cd "$povdir/unix" && eval "$linkpre -o $tmp/povray-brdf $objects $ldadd $libs") >"$tmp/link.log" 2>&1 \
  || { cat "$tmp/link.log" >&2; die "linking povray-brdf failed"; }
strings "$tmp/povray-brdf" | grep -x "$etc/povray.conf" >/dev/null || die "the relinked binary does not name $etc/povray.conf"

# ---------------------------------------------------------------- files
manifest=()
put() {  # MODE SRC DST: install one file (a rename, so a running povray-brdf is not disturbed)
  install -D -m "$1" "$2" "$D$3.tmp.$$"
  mv -f "$D$3.tmp.$$" "$D$3"
  manifest+=("$3")
}
put 755 "$tmp/povray-brdf" "$bindir/povray-brdf"
put 755 "$tool_src" "$bindir/brdftool"
put 755 "$top/build/shading/sstool" "$bindir/sstool"
for f in "$povdir"/distribution/include/*; do
  [ -f "$f" ] && put 644 "$f" "$share/include/$(basename "$f")"
done
for f in "$top"/scenes/include/*.inc; do put 644 "$f" "$share/include/$(basename "$f")"; done
for f in "${tables[@]}"; do put 644 "$f" "$share/brdf_data/$(basename "$f")"; done
for f in README.md shading/MODELS.md shading/DIPOLE.md brdf_data/README.md docs/*.md; do
  [ -f "$top/$f" ] && put 644 "$top/$f" "$share/doc/$f"   # relative links between them keep working
done
for f in "$top"/docs/man/*.1; do
  gzip -9nc "$f" > "$tmp/$(basename "$f").gz"
  put 644 "$tmp/$(basename "$f").gz" "$prefix/share/man/man1/$(basename "$f").gz"
done
for f in povray.conf povray.ini; do
  sed -e "s|@ETCDIR@|$etc|g" -e "s|@SHAREDIR@|$share|g" -e "s|@PREFIX@|$prefix|g" \
      "$top/conf/installed/$f.in" > "$tmp/$f"
  put 644 "$tmp/$f" "$etc/$f"
done
manifest+=("$share/install-manifest.txt")
printf '%s\n' "${manifest[@]}" > "$tmp/manifest"
install -D -m 644 "$tmp/manifest" "$D$share/install-manifest.txt"

echo "install: ${#manifest[@]} files under $D$prefix"
echo "install: $D$bindir/povray-brdf reads $etc/povray.{conf,ini}; tables in $share/brdf_data, includes in $share/include"
echo "install: man povray-brdf, man brdftool, man sstool (in $prefix/share/man/man1; add $prefix/share/man to MANPATH if man does not find them)"
