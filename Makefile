# povray-brdf: POV-Ray 3.7.0.10 with measured-BRDF and dipole subsurface shading.
#
# `make` fetches Debian's povray source package through apt, verifies it, unpacks it
# into povray/ (Debian's patches applied), applies our series from patches/ with
# quilt, builds the POV-free shading library (shading/, CMake) and links it into a
# build of POV-Ray with Debian's own flags (-O3, hardening; never fast-math). Everything it downloads or builds stays
# inside this tree (.cache/, povray/, build/, .venv/), so a second `make` does nothing.
#
# `make help` lists the targets.

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := all
MAKEFLAGS += --no-builtin-rules

TOP        := $(CURDIR)
JOBS       ?= $(shell nproc)
UPSTREAM_VERSION := 1:3.7.0.10-2
FORK_VERSION     := $(shell cat VERSION)

CACHE      := .cache/upstream
POVDIR     := povray
BUILD      := build
STAMPS     := $(BUILD)/stamps
SHADING_BUILD := $(BUILD)/shading
LIBSHADING := $(SHADING_BUILD)/libshading.a
CONFDIR    := $(BUILD)/conf
POVCONF    := $(CONFDIR)/povray/3.7
FORK_BIN   := $(BUILD)/bin/povray-brdf
STOCK_BIN  := /usr/bin/povray
VENV       := .venv
PY         := $(VENV)/bin/python

DSC        := povray_3.7.0.10-2.dsc
UPSTREAM_FILES := $(CACHE)/povray_3.7.0.10.orig.tar.gz $(CACHE)/povray_3.7.0.10-2.debian.tar.xz $(CACHE)/$(DSC)

# Debian packages the project needs besides POV-Ray's own build dependencies
# (those come from `apt-get build-dep povray`). `povray` is the stock reference; `time`
# (GNU time -v) checks the harness's memory measurement; groff-base renders and checks
# the man pages (tests/test_man_pages.py); strace shows that images are written whole
# (tests/test_write_failures.py).
# ccache serves a fresh clone's compiles from this machine's earlier ones (below).
APT_PACKAGES := build-essential dpkg-dev devscripts quilt cmake ninja-build libgtest-dev \
                python3 python3-venv povray povray-includes time groff-base strace ccache

# Compiles go through ccache where it is installed (it is in APT_PACKAGES; POV-Ray's CXX is
# mk/ccache/g++, which looks for it at each compile, so installing it later changes nothing
# else). The objects do not depend on where the tree lies (-ffile-prefix-map, as dpkg-buildflags'
# fixfilepath does for Debian's own builds), so ccache may share them between clones: paths
# under TOP are hashed relative to it and the working directory is left out of the hash.
# ccache's output is the compiler's, byte for byte.
export CCACHE_BASEDIR := $(TOP)
export CCACHE_NOHASHDIR := 1

# POV-Ray's configure: --disable-optimiz stops it adding fast-math and -march=native flags.
# The flags are Debian's for this package (debian/rules: `dpkg-buildflags` with
# hardening=+all on bookworm, plus -O3; `/usr/bin/povray --version` shows the same CXXFLAGS),
# so the fork and the stock binary are compiled alike: same speed, same rounding (the stock
# guard compares them to the bit). -fno-fast-math only states what Debian's rules say.
# The shading library reaches the fork through CPPFLAGS/LDFLAGS/LIBS, not by copying sources.
POV_CXXFLAGS := -g -O2 -ffile-prefix-map=$(TOP)=. -fstack-protector-strong -Wformat -Werror=format-security -O3 -fno-fast-math
POV_CPPFLAGS := -Wdate-time -D_FORTIFY_SOURCE=2
POV_LDFLAGS  := -Wl,-z,relro -Wl,-z,now
POV_CONFIGURE_ARGS := --disable-optimiz --disable-strip --with-boost-thread=boost_thread \
	CXX="$(TOP)/mk/ccache/g++" \
	--sysconfdir=$(TOP)/$(CONFDIR) \
	COMPILED_BY="povray-brdf $(FORK_VERSION) (measured-BRDF and dipole subsurface fork)" \
	CXXFLAGS="$(POV_CXXFLAGS)" \
	CPPFLAGS="$(POV_CPPFLAGS) -I$(TOP)/shading/include" \
	LDFLAGS="$(POV_LDFLAGS) -L$(TOP)/$(SHADING_BUILD)" \
	LIBS="-lshading -lpthread"

# Stable quilt settings: the same patch text whoever refreshes it.
QUILT_ENV := QUILT_PATCHES=$(TOP)/patches QUILT_PC=.pc-brdf QUILT_NO_DIFF_TIMESTAMPS=1 QUILT_NO_DIFF_INDEX=1
QUILT_REFRESH_ARGS := -p ab --no-timestamps --no-index --sort
PATCHES := $(shell sed -e 's/[[:space:]].*//' -e '/^\#/d' -e '/^$$/d' patches/series 2>/dev/null | sed 's|^|patches/|')

.PHONY: all help deps fetch shading fork brdf-data venv demo test test-security test-pages test-all test-unit test-py bench dg-compare \
        check-patches refresh-patches clean distclean \
        fuzz sanitize sanitize-unit sanitize-tsan sanitize-fork

all: $(FORK_BIN) $(POVCONF)/povray.conf $(POVCONF)/povray.ini ## Build the fork (fetch, verify, patch, configure, build)
	@echo "fork: $(FORK_BIN)"

help: ## List the targets
	@grep -hE '^[a-zA-Z_-]+:.*## ' $(MAKEFILE_LIST) | sed -E 's/:.*## /\t/' | expand -t 18

# ---------------------------------------------------------------- dependencies
# Installs what is missing through apt (needs root once); does nothing when all is there.
deps: $(STAMPS)/deps ## Install build dependencies through apt (as root), once
# The package list, in a file that changes only when the list does: adding a package runs
# mk/deps.sh again (and only then).
APT_LIST_FILE := $(BUILD)/apt-packages
$(APT_LIST_FILE): FORCE
	@mkdir -p $(@D)
	@printf '%s\n' $(APT_PACKAGES) > $@.tmp
	@if cmp -s $@.tmp $@; then rm $@.tmp; else mv $@.tmp $@; fi
$(STAMPS)/deps: mk/deps.sh $(APT_LIST_FILE)
	@mkdir -p $(@D)
	bash mk/deps.sh $(APT_PACKAGES)
	@touch $@

# ---------------------------------------------------------------- upstream source
fetch: $(UPSTREAM_FILES) ## Download Debian's povray source package and verify sha256
$(UPSTREAM_FILES) &: upstream.sha256 | $(STAMPS)/deps
	@mkdir -p $(CACHE)
	cd $(CACHE) && for f in $(notdir $(UPSTREAM_FILES)); do \
	  if ! grep " $$f\$$" $(TOP)/upstream.sha256 | sha256sum -c --status 2>/dev/null; then rm -f $$f; fi; done
	cd $(CACHE) && if ! sha256sum -c --status $(TOP)/upstream.sha256 2>/dev/null; then \
	  apt-get source --download-only povray=$(UPSTREAM_VERSION) 2>&1 | grep -v '^W: Download is performed unsandboxed' ; fi
	cd $(CACHE) && sha256sum -c $(TOP)/upstream.sha256
	@touch $(UPSTREAM_FILES)

# Pristine tree: Debian's source with Debian's 19 patches applied (dpkg-source -x).
$(POVDIR)/.unpacked: $(UPSTREAM_FILES)
	rm -rf $(POVDIR) $(POVDIR).tmp
	dpkg-source --no-check --no-copy -x $(CACHE)/$(DSC) $(POVDIR).tmp >/dev/null
	mv $(POVDIR).tmp $(POVDIR)
	@touch $@

# Our series on top, with its own quilt state (.pc-brdf) so Debian's .pc stays untouched.
# A changed patch re-applies the series; files whose content did not change keep their
# timestamps (mk/apply-patches.sh), so only what the edit touches is rebuilt.
$(POVDIR)/.patched: $(POVDIR)/.unpacked patches/series $(PATCHES) mk/apply-patches.sh
	bash mk/apply-patches.sh $(POVDIR)
	@touch $@

# ---------------------------------------------------------------- shading library
shading: $(LIBSHADING) ## Build the POV-free shading library and its tests
$(SHADING_BUILD)/build.ninja: shading/CMakeLists.txt | $(STAMPS)/deps
	cmake -S shading -B $(SHADING_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null

# cmake/ninja knows the library's own dependencies: always ask it (a no-op is instant).
$(LIBSHADING): $(SHADING_BUILD)/build.ninja FORCE
	cmake --build $(SHADING_BUILD) -j $(JOBS) | { grep -vE '^(ninja: no work to do|\[0/2\] Re-checking globbed)' || true; }

# ---------------------------------------------------------------- the fork
# The configure command line, kept in a file that changes only when the flags change, so
# editing an unrelated part of this Makefile does not reconfigure (and rebuild) POV-Ray.
CONFIGURE_ARGS_FILE := $(BUILD)/configure-args
$(CONFIGURE_ARGS_FILE): FORCE
	@mkdir -p $(@D)
	@printf '%s\n' '$(subst ','\'',$(POV_CONFIGURE_ARGS))' > $@.tmp
	@if cmp -s $@.tmp $@; then rm $@.tmp; else mv $@.tmp $@; fi

# Configure once per unpack or change of flags (our patches touch no build files).
$(POVDIR)/.configured: $(POVDIR)/.unpacked $(CONFIGURE_ARGS_FILE) | $(POVDIR)/.patched $(LIBSHADING)
	cd $(POVDIR)/unix/config && for ax in *.m4; do \
	  if [ ! -h "$$ax" ] && [ -f "/usr/share/aclocal/$$ax" ]; then mv "$$ax" "$$ax.dist"; ln -s "/usr/share/aclocal/$$ax"; fi; done
	if [ -d $(POVDIR)/libraries ]; then mv $(POVDIR)/libraries $(POVDIR)/libraries.donotuse; fi
	cd $(POVDIR)/unix && ./prebuild.sh >/dev/null
	cd $(POVDIR) && ./configure -q $(POV_CONFIGURE_ARGS) >/dev/null
	@touch $@

# POV's automake tree tracks its own header dependencies (ours included, via -I);
# a newer libshading.a only needs a relink, which automake does not know about.
$(FORK_BIN): $(POVDIR)/.configured $(POVDIR)/.patched $(LIBSHADING)
	if [ -e $(POVDIR)/unix/povray ] && [ $(LIBSHADING) -nt $(POVDIR)/unix/povray ]; then rm -f $(POVDIR)/unix/povray; fi
	@# The compiler's lines go to the log; the terminal gets a file counter (mk/povray-make.sh).
	@MAKEFLAGS= bash mk/povray-make.sh $(POVDIR) $(JOBS) $(BUILD)/povray-build.log
	@mkdir -p $(@D)
	cp -p $(POVDIR)/unix/povray $@.tmp && mv -f $@.tmp $@  # a rename: works while renders run the old one

# The fork's own povray.conf/.ini (I/O restrictions on, library paths inside this tree).
$(POVCONF)/%: conf/%.in Makefile
	@mkdir -p $(@D)
	sed -e 's|@TOP@|$(TOP)|g' -e 's|@POVDIR@|$(TOP)/$(POVDIR)|g' $< > $@

fork: all

# ---------------------------------------------------------------- ready BRDF tables
BRDFTOOL   := $(SHADING_BUILD)/brdftool
SSTOOL     := $(SHADING_BUILD)/sstool
BRDF_DATA  := $(BUILD)/brdf_data
# The exact subsurface profiles (shading/DIPOLE.md "Profile tables"): rebuilt only when missing or
# made by another generator version or settings (sstool build --if-stale), a few minutes once.
SS_PROFILES := $(BRDF_DATA)/subsurface_profiles.ssp
# The exact slab tables of thin geometry (DIPOLE.md 6a): g 0 (every Jensen preset), the half-space
# file's etas, 31 thicknesses 2^(k/3), 1/16 .. 64 mean free paths (ln-d interpolation within
# ~0.5 % in the totals), half the default photons (totals still within 2.4 % of the harness Monte
# Carlo); about 3.3 minutes on 2 cores.
SS_SLABS := $(BRDF_DATA)/subsurface_slabs.ssp
SS_SLAB_D := 0.0625,0.0787451,0.0992126,0.125,0.15749,0.198425,0.25,0.31498,0.39685,0.5,0.629961,0.793701,1
SS_SLAB_D := $(SS_SLAB_D),1.25992,1.5874,2,2.51984,3.1748,4,5.03968,6.3496,8,10.0794,12.6992,16,20.1587,25.3984
SS_SLAB_D := $(SS_SLAB_D),32,40.3175,50.7968,64
SS_SLAB_ARGS := --g 0 --eta 1,1.1,1.2,1.3,1.33,1.4,1.5,1.6,1.8,2 --photons 40000 --short-photons 400000 --thickness $(SS_SLAB_D)
# The slab tables of forward-scattering media (DIPOLE.md 6a): g 0 to 0.95, the iors most scenes
# use, thicknesses 2^(k/2) mean free paths (not transport ones: 1/16 .. 64 mfp is 1/160 .. 6.4
# mfp' at g 0.9; thicker channels take a smaller g), 24 exit-angle samples for the narrow
# forward lobe seen through a sheet, half the isotropic file's photons (up to 8 times in thick slabs,
# DIPOLE.md 10.3); 7.8 minutes on 2 cores, 18.8 MB.
SS_FORWARD := $(BRDF_DATA)/subsurface_slabs_forward.ssp
SS_FORWARD_D := 0.0625,0.0883883,0.125,0.176777,0.25,0.353553,0.5,0.707107,1,1.41421,2,2.82843,4,5.65685,8
SS_FORWARD_D := $(SS_FORWARD_D),11.3137,16,22.6274,32,45.2548,64
SS_FORWARD_ARGS := --g 0,0.5,0.7,0.8,0.9,0.95 --eta 1,1.2,1.33,1.5 --photons 20000 --short-photons 200000 --angle-nodes 24 --thickness $(SS_FORWARD_D)
# Both go through a cache this machine's clones share (mk/ss-tables.sh: keyed by the sha256 of
# sstool's code and data and of the options, checked whole before use); SS_CACHE= turns it off.
SS_CACHE ?= $(or $(XDG_CACHE_HOME),$(HOME)/.cache)/povray-brdf/ss-tables
brdf-data: $(LIBSHADING) ## Generate the ready tables of brdf_data/materials.txt and the exact subsurface profiles (half-space, slabs, forward-scattering slabs) into build/brdf_data
	bash mk/brdf-data.sh $(BRDFTOOL) brdf_data/materials.txt $(BRDF_DATA)
	bash mk/ss-tables.sh $(SSTOOL) '$(SS_CACHE)' $(SS_PROFILES) --threads $(JOBS)
	bash mk/ss-tables.sh $(SSTOOL) '$(SS_CACHE)' $(SS_SLABS) --threads $(JOBS) $(SS_SLAB_ARGS)
	bash mk/ss-tables.sh $(SSTOOL) '$(SS_CACHE)' $(SS_FORWARD) --threads $(JOBS) $(SS_FORWARD_ARGS)

# ---------------------------------------------------------------- python harness
# The harness is a package (pyproject.toml: pinned dependencies, console scripts); the venv
# holds it editable, with its test and study extras.
venv: $(VENV)/.installed ## Create the project venv: the harness package (editable) and its pinned dependencies
$(VENV)/.installed: pyproject.toml | $(STAMPS)/deps
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -e '.[test,study]'
	@touch $@

# ---------------------------------------------------------------- use
demo: all brdf-data venv ## Build the fork, the tables and the harness venv (the tutorial's), render scenes/demo.pov, print where the image is
	@mkdir -p out
	cd scenes && $(TOP)/$(FORK_BIN) +Idemo.pov +O$(TOP)/out/demo.png +W640 +H360 +A0.1 -D +WT$(JOBS) 2>$(TOP)/out/demo.log || { tail -20 $(TOP)/out/demo.log; exit 1; }
	@grep -E 'Trace Time' out/demo.log | head -1 || true
	@echo "demo image: $(TOP)/out/demo.png"

test: all venv brdf-data ## Build if needed, run the unit (ctest) and fast Python (pytest) suites
	cd $(SHADING_BUILD) && ctest --output-on-failure -j $(JOBS)
	$(PY) -m pytest -q -m "not slow" -n $(JOBS)

# The security and data-safety checks too slow for `make test` (.ci/run runs both): every
# entry point x path form against the fork and Debian's stock binary (the matrix is printed),
# then the slow security tests: study fault runs, the whole parameter sweep, every .ssp damage
# class; and the pages in a browser (PAGE_TESTS, below).
SECURITY_SLOW_TESTS := tests/test_study_faults.py tests/test_param_sweep.py tests/test_ssp_cache.py
test-security: all venv brdf-data $(STAMPS)/deps-browser ## The slow security checks: the whole path matrix (fork beside stock), study fault runs, the parameter sweep, .ssp damage; the pages in a browser
	$(PY) -m harness.reports.path_matrix --jobs $(JOBS)
	$(PY) -m pytest -q -m slow $(SECURITY_SLOW_TESTS) $(PAGE_TESTS)

# The study, regress and report pages in headless Chromium (Debian's, driven by Playwright from
# the venv's test extra): no sideways scrolling at 1366/1400/1920 px, images loaded, text and
# plot labels >= 10 px on screen; screenshots in build/screens/ (tests/test_pages_browser.py).
BROWSER_APT_PACKAGES := chromium
PAGE_TESTS := tests/test_pages_browser.py
$(STAMPS)/deps-browser: mk/deps.sh | $(STAMPS)/deps
	bash mk/deps.sh $(BROWSER_APT_PACKAGES)
	@touch $@

test-pages: all venv brdf-data $(STAMPS)/deps-browser ## The study, regress and report pages in headless Chromium at 1366/1400/1920 px (screenshots: build/screens/)
	$(PY) -m pytest -q -m slow $(PAGE_TESTS)

test-all: all venv brdf-data ## Everything in `test` plus the slow renders
	cd $(SHADING_BUILD) && ctest --output-on-failure -j $(JOBS)
	$(PY) -m pytest -q

bench: all venv brdf-data ## Trace-time ratios (fork/stock, table/phong, the 25-sphere grid, every model, dipole/stock subsurface, exact/dipole profile), glossy noise, profile table build times, image errors, thin geometry (slab totals vs Monte Carlo, back-lit sheets, cost), subsurface in real geometry (profile and random walk vs the volumetric reference)
	$(PY) -m harness.reports.bench
	$(PY) -m harness.reports.glossy_noise
	$(PY) -m harness.reports.table_error
	$(PY) -m harness.reports.model_bench
	$(PY) -m harness.reports.dipole_bench
	$(PY) -m harness.reports.ss_bench
	$(PY) -m harness.reports.thin_bench
	$(PY) -m harness.reports.walk_bench

dg-compare: all venv ## The four D and two G terms at equal roughness: out/dg/dg.png and an error table
	$(PY) -m harness.reports.dg_compare

# ---------------------------------------------------------------- robustness
# Fuzzers (clang libFuzzer) for the .brdf and MERL readers, and sanitizer builds of the
# library, its tests and the fork. Each build has its own directory; nothing here touches
# build/shading, povray/ or build/bin.
FUZZ_APT_PACKAGES := clang libclang-rt-dev
FUZZ_BUILD     := $(BUILD)/fuzz
FUZZ_SECONDS   ?= 60
FUZZ_TARGETS   := table_header_fuzz table_fuzz merl_fuzz ssp_fuzz costs_fuzz
# Examples per Python reader in `make fuzz` (tests/test_reader_fuzz.py; the fast suite runs 250).
READER_FUZZ_EXAMPLES ?= 5000
SAN_FLAGS      := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer -g
SANITIZE_BUILD := $(BUILD)/sanitize
TSAN_BUILD     := $(BUILD)/tsan
ASAN_DIR       := $(BUILD)/asan
ASAN_BIN       := $(ASAN_DIR)/povray-brdf
# The fork's own configure line, with the sanitizers added and the sanitized library linked.
# POV-Ray's own code keeps UBSan recoverable (reports are collected, the render goes on).
# (_FORTIFY_SOURCE's checked string functions and ASan's interceptors do not mix: off here.)
POV_SAN_FLAGS  := -fsanitize=address,undefined -fno-omit-frame-pointer -g -U_FORTIFY_SOURCE
POV_ASAN_CONFIGURE_ARGS := $(subst LDFLAGS="$(POV_LDFLAGS) -L$(TOP)/$(SHADING_BUILD)",LDFLAGS="$(POV_LDFLAGS) -L$(TOP)/$(SANITIZE_BUILD) $(POV_SAN_FLAGS)",$(subst CXXFLAGS="$(POV_CXXFLAGS)",CXXFLAGS="$(POV_CXXFLAGS) $(POV_SAN_FLAGS)",$(POV_CONFIGURE_ARGS)))

$(STAMPS)/deps-fuzz: mk/deps.sh | $(STAMPS)/deps
	bash mk/deps.sh $(FUZZ_APT_PACKAGES)
	@touch $@

fuzz: $(STAMPS)/deps-fuzz venv ## libFuzzer on the C++ readers (FUZZ_SECONDS, 60, per target), then Hypothesis on the Python readers
	@test -f $(FUZZ_BUILD)/build.ninja || CXX=clang++ cmake -S shading -B $(FUZZ_BUILD) -G Ninja \
	  -DCMAKE_BUILD_TYPE=Release -DSHADING_TESTS=OFF -DSHADING_FUZZ=ON >/dev/null
	cmake --build $(FUZZ_BUILD) -j $(JOBS) --target $(FUZZ_TARGETS)
	status=0; bash mk/fuzz.sh $(FUZZ_BUILD) shading/fuzz/corpus $(FUZZ_SECONDS) $(FUZZ_TARGETS) || status=1; \
	READER_FUZZ_EXAMPLES=$(READER_FUZZ_EXAMPLES) $(PY) -m pytest -q -p no:cacheprovider tests/test_reader_fuzz.py \
	  -k refuses_or_reads || status=1; exit $$status

sanitize: sanitize-unit sanitize-tsan sanitize-fork ## ASan+UBSan unit tests, TSan registry tests, ASan+UBSan fork on the harness scenes

$(SANITIZE_BUILD)/libshading.a: FORCE | $(STAMPS)/deps
	@test -f $(SANITIZE_BUILD)/build.ninja || cmake -S shading -B $(SANITIZE_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release \
	  -DCMAKE_CXX_FLAGS="$(SAN_FLAGS)" -DCMAKE_EXE_LINKER_FLAGS="$(SAN_FLAGS)" >/dev/null
	cmake --build $(SANITIZE_BUILD) -j $(JOBS) | { grep -vE '^(ninja: no work to do|\[0/2\] Re-checking globbed)' || true; }

sanitize-unit: $(SANITIZE_BUILD)/libshading.a
	cd $(SANITIZE_BUILD) && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
	  ctest --output-on-failure -j $(JOBS)

sanitize-tsan: $(STAMPS)/deps
	@test -f $(TSAN_BUILD)/build.ninja || cmake -S shading -B $(TSAN_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release \
	  -DCMAKE_CXX_FLAGS="-fsanitize=thread -g" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread" >/dev/null
	cmake --build $(TSAN_BUILD) -j $(JOBS) --target shading_tests
	TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1 $(TSAN_BUILD)/shading_tests \
	  --gtest_filter='Threads.*:SharedTable.*:FinishRegistry.*:*Concurrent*:SubsurfaceSampling.CloudIsBuiltOnce*:SubsurfaceSampling.AnErrorWhileSampling*'

$(ASAN_BIN): $(FORK_BIN) $(SANITIZE_BUILD)/libshading.a mk/asan-fork.sh FORCE
	bash mk/asan-fork.sh $(POVDIR) $(ASAN_DIR) $(JOBS) $(POV_ASAN_CONFIGURE_ARGS)

sanitize-fork: $(ASAN_BIN) all venv brdf-data
	bash mk/sanitize-fork.sh $(ASAN_BIN) $(PY) $(ASAN_DIR)/reports

# ---------------------------------------------------------------- patch tooling
check-patches: $(UPSTREAM_FILES) ## Apply the series to a pristine tree; fail on fuzz or offset
	bash mk/check-patches.sh $(CACHE)/$(DSC)

refresh-patches: $(POVDIR)/.patched ## Refresh every patch with stable quilt settings
	cd $(POVDIR) && $(QUILT_ENV) quilt pop -a -q >/dev/null 2>&1 || true
	cd $(POVDIR) && while $(QUILT_ENV) quilt push -q >/dev/null 2>&1; do \
	  $(QUILT_ENV) quilt refresh $(QUILT_REFRESH_ARGS); done
	@touch $(POVDIR)/.patched

clean: ## Remove build outputs (keeps the download cache and the venv)
	rm -rf $(BUILD) $(POVDIR) out

distclean: clean ## Also remove the download cache and the venv
	rm -rf .cache $(VENV)

$(STAMPS):
	mkdir -p $@

.PHONY: FORCE
FORCE:

# Workflow targets that live in their own fragments (mk/targets/*.mk: report, regress, study,
# install, ...), each with `## ` help text like the targets above.
include $(sort $(wildcard mk/targets/*.mk))
