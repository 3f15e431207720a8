# Installation: mk/install.sh relinks the fork with PREFIX/etc/povray-brdf as its compiled-in
# configuration directory and copies it, brdftool, the include files (POV-Ray's standard ones
# and scenes/include), the ready tables, the docs and a povray.conf/.ini for that layout
# (conf/installed/*.in) under PREFIX/{bin,share/povray-brdf,etc/povray-brdf}.
# DESTDIR=/stage puts the files under /stage/PREFIX (for packaging), PREFIX still compiled in.
PREFIX  ?= /usr/local
DESTDIR ?=
.PHONY: install uninstall

install: all brdf-data ## Install povray-brdf, brdftool, includes, tables, docs, man pages and conf under PREFIX (default /usr/local)
	bash mk/install.sh '$(TOP)' '$(PREFIX)' '$(DESTDIR)'

uninstall: ## Remove what `make install PREFIX=...` installed (its install-manifest.txt)
	bash mk/uninstall.sh '$(PREFIX)' '$(DESTDIR)'
